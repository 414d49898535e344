//! Image files: linear EXR frames (R, G, B, A, Z), sRGB PNG previews, brush
//! footprints.
//!
//! - EXR: 32-bit float channels `R`, `G`, `B` (linear, premultiplied by
//!   `A`), `A`, and `Z` (camera depth in scene units, +∞ where nothing was
//!   drawn), ZIP-compressed scan lines.
//! - PNG: 8-bit sRGB. Without a background colour, RGBA with straight
//!   (unpremultiplied) alpha: `rgb = srgb(RGB / A)`, `a = A`. With one, RGB
//!   flattened over it: `rgb = srgb(RGB + (1 − A)·background)`.
//!
//! Every file is written to a temporary sibling and renamed into place.

use std::io::{Cursor, Read};
use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, WritableImage,
};
use glam::Vec3;

use super::composite::{Brush, Frame};
use crate::error::{Error, Result};
use crate::usd_io::atomic::write_atomic;

/// Linear → sRGB transfer function (IEC 61966-2-1), input clamped to [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB → linear.
pub fn srgb_decode(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// A float in [0, 1] to 8 bits, rounded.
#[inline]
pub fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// The sRGB curve tabulated at 4096 points (within one 8-bit step of the
/// exact value; the exact function is used below 0.01, where it is steep).
struct SrgbTable(Vec<u8>);

impl SrgbTable {
    const N: usize = 4096;

    fn new() -> Self {
        SrgbTable(
            (0..=Self::N)
                .map(|i| to_u8(srgb_encode(i as f32 / Self::N as f32)))
                .collect(),
        )
    }

    #[inline]
    fn get(&self, x: f32) -> u8 {
        let x = x.clamp(0.0, 1.0);
        if x.is_nan() || x <= 0.0 {
            return 0;
        }
        // The curve is steep near 0: use the exact function there.
        if x < 0.01 {
            return to_u8(srgb_encode(x));
        }
        self.0[(x * Self::N as f32 + 0.5) as usize]
    }
}

/// Writes a frame as a linear float EXR with R, G, B, A and Z.
pub fn write_exr(path: &Path, frame: &Frame) -> Result<()> {
    let n = frame.width * frame.height;
    let mut chans: [Vec<f32>; 4] = std::array::from_fn(|_| Vec::with_capacity(n));
    for p in &frame.rgba {
        for (c, v) in chans.iter_mut().zip(p) {
            c.push(*v);
        }
    }
    let [r, g, b, a] = chans;
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::from_vec(vec![
        AnyChannel::new("R", FlatSamples::F32(r)),
        AnyChannel::new("G", FlatSamples::F32(g)),
        AnyChannel::new("B", FlatSamples::F32(b)),
        AnyChannel::new("A", FlatSamples::F32(a)),
        AnyChannel::new("Z", FlatSamples::F32(frame.z.clone())),
    ]);
    let layer = Layer::new(
        (frame.width, frame.height),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    let mut bytes = Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| Error::msg(format!("cannot encode EXR: {e}")).in_file(path))?;
    write_atomic(path, bytes.get_ref())
}

/// 8-bit sRGB pixels of a frame: RGBA straight alpha, or RGB over `background`.
pub fn frame_to_srgb8(frame: &Frame, background: Option<Vec3>) -> Vec<u8> {
    let lut = SrgbTable::new();
    match background {
        Some(bg) => {
            let mut out = Vec::with_capacity(frame.rgba.len() * 3);
            for p in &frame.rgba {
                let k = 1.0 - p[3];
                out.push(lut.get(p[0] + k * bg.x));
                out.push(lut.get(p[1] + k * bg.y));
                out.push(lut.get(p[2] + k * bg.z));
            }
            out
        }
        None => {
            let mut out = Vec::with_capacity(frame.rgba.len() * 4);
            for p in &frame.rgba {
                let a = p[3];
                if a > 0.0 {
                    out.push(lut.get(p[0] / a));
                    out.push(lut.get(p[1] / a));
                    out.push(lut.get(p[2] / a));
                } else {
                    out.extend_from_slice(&[0, 0, 0]);
                }
                out.push(to_u8(a));
            }
            out
        }
    }
}

/// Writes 8-bit pixels (3 or 4 channels per pixel) as a PNG tagged sRGB.
pub fn write_png8(path: &Path, width: usize, height: usize, channels: usize, data: &[u8], small: bool) -> Result<()> {
    let bytes = encode_png8(width, height, channels, data, small).map_err(|e| e.in_file(path))?;
    write_atomic(path, &bytes)
}

/// Encodes 8-bit pixels (3 or 4 channels per pixel) as PNG bytes tagged sRGB.
pub fn encode_png8(width: usize, height: usize, channels: usize, data: &[u8], small: bool) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let result = (|| -> std::result::Result<(), png::EncodingError> {
        let mut enc = png::Encoder::new(&mut bytes, width as u32, height as u32);
        enc.set_color(if channels == 4 {
            png::ColorType::Rgba
        } else {
            png::ColorType::Rgb
        });
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        enc.set_compression(if small {
            png::Compression::High
        } else {
            png::Compression::Fast
        });
        let mut w = enc.write_header()?;
        w.write_image_data(data)?;
        w.finish()
    })();
    result.map_err(|e| Error::msg(format!("cannot encode PNG: {e}")))?;
    Ok(bytes)
}

/// Writes a frame as an sRGB PNG preview.
pub fn write_png(path: &Path, frame: &Frame, background: Option<Vec3>) -> Result<()> {
    let data = frame_to_srgb8(frame, background);
    let channels = if background.is_some() { 3 } else { 4 };
    write_png8(path, frame.width, frame.height, channels, &data, false)
}

/// The largest brush PNG, on either side: a footprint is sampled across a
/// ribbon a few hundred pixels wide at most, and a PNG's header can claim
/// far more than its file holds (a 150 KB 1-bit PNG can say 30000 × 30000,
/// 3.6 GB once read as floats).
pub const MAX_BRUSH_SIDE: u32 = 4096;

/// Width and height from a PNG's IHDR chunk (which must come first, right
/// after the 8-byte signature), or None when the bytes do not start so.
fn png_header_size(bytes: &[u8]) -> Option<(u32, u32)> {
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    if bytes.len() < 24 || bytes[..8] != SIGNATURE || &bytes[12..16] != b"IHDR" {
        return None;
    }
    let word = |at: usize| u32::from_be_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    Some((word(16), word(20)))
}

/// Reads a PNG as a grayscale footprint in [0, 1]: gray (times alpha when
/// present), or for colour images their Rec. 709 luma times alpha. Values
/// are used as stored (no sRGB decoding): a footprint is a mask. A PNG
/// whose header says it is wider or taller than [`MAX_BRUSH_SIDE`] is
/// refused before any pixel is decoded.
pub fn read_brush(path: &Path) -> Result<Brush> {
    let err = |m: String| Error::msg(m).in_file(path);
    // A FIFO would block a plain open until a writer came.
    let open = || crate::usd_io::regular::open_regular(path).map_err(|e| err(format!("cannot open brush: {e}")));
    // The size as the header claims it, checked before the decoder sees it
    // (it refuses some huge sizes itself, with a message that names none).
    let mut head = Vec::with_capacity(24);
    open()?
        .take(24)
        .read_to_end(&mut head)
        .map_err(|e| err(format!("cannot read brush: {e}")))?;
    if let Some((w, h)) = png_header_size(&head) {
        if w > MAX_BRUSH_SIDE || h > MAX_BRUSH_SIDE {
            return Err(err(format!(
                "brush PNG is {w} x {h} pixels; painterly reads brushes of at most \
                 {MAX_BRUSH_SIDE} x {MAX_BRUSH_SIDE} (scale the footprint down)"
            )));
        }
    }
    let mut dec = png::Decoder::new(std::io::BufReader::new(open()?));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec
        .read_info()
        .map_err(|e| err(format!("cannot read brush PNG: {e}")))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| err("brush PNG is too large".into()))?;
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| err(format!("cannot read brush PNG: {e}")))?;
    let (w, h) = (info.width as usize, info.height as usize);
    if w == 0 || h == 0 {
        return Err(err("brush PNG is empty".into()));
    }
    let ch = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err(err("brush PNG: unexpanded palette".into())),
    };
    let values = buf[..w * h * ch]
        .chunks_exact(ch)
        .map(|p| {
            let f = |i: usize| p[i] as f32 / 255.0;
            match ch {
                1 => f(0),
                2 => f(0) * f(1),
                3 => 0.2126 * f(0) + 0.7152 * f(1) + 0.0722 * f(2),
                _ => (0.2126 * f(0) + 0.7152 * f(1) + 0.0722 * f(2)) * f(3),
            }
        })
        .collect();
    Ok(Brush {
        width: w,
        height: h,
        values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_table_matches() {
        let lut = SrgbTable::new();
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-5);
            let exact = to_u8(srgb_encode(x)) as i32;
            assert!((lut.get(x) as i32 - exact).abs() <= 1, "{x}");
        }
        assert_eq!(to_u8(srgb_encode(0.5)), 188);
    }

    #[test]
    fn png_pixels_unpremultiply_or_flatten() {
        let frame = Frame {
            width: 2,
            height: 1,
            rgba: vec![[0.25, 0.0, 0.0, 0.5], [0.0; 4]],
            z: vec![1.0, f32::INFINITY],
        };
        assert_eq!(frame_to_srgb8(&frame, None), vec![188, 0, 0, 128, 0, 0, 0, 0]);
        let flat = frame_to_srgb8(&frame, Some(Vec3::new(0.0, 0.0, 1.0)));
        assert_eq!(flat, vec![137, 0, 188, 0, 0, 255]);
    }

    #[test]
    fn exr_and_png_files_round_trip_through_their_decoders() {
        let dir = crate::test_dir::ScratchDir::new("image-io");
        let frame = Frame {
            width: 3,
            height: 2,
            rgba: (0..6)
                .map(|i| [i as f32 * 0.1, 0.5 - i as f32 * 0.05, 0.25, i as f32 / 5.0])
                .collect(),
            z: (0..6)
                .map(|i| if i == 2 { f32::INFINITY } else { i as f32 + 0.5 })
                .collect(),
        };
        let exr_path = dir.join("f.exr");
        write_exr(&exr_path, &frame).unwrap();
        let img = exr::prelude::read_all_flat_layers_from_file(&exr_path).unwrap();
        let layer = &img.layer_data[0];
        assert_eq!((layer.size.0, layer.size.1), (3, 2));
        let names: Vec<String> = layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
        assert_eq!(names, ["A", "B", "G", "R", "Z"]);
        // Every channel holds the frame's values, +∞ depth included.
        for ch in &layer.channel_data.list {
            let got: Vec<f32> = ch.sample_data.values_as_f32().collect();
            let want: Vec<f32> = match ch.name.to_string().as_str() {
                "R" => frame.rgba.iter().map(|p| p[0]).collect(),
                "G" => frame.rgba.iter().map(|p| p[1]).collect(),
                "B" => frame.rgba.iter().map(|p| p[2]).collect(),
                "A" => frame.rgba.iter().map(|p| p[3]).collect(),
                _ => frame.z.clone(),
            };
            assert_eq!(got, want, "{}", ch.name);
        }
        let png_path = dir.join("g.png");
        write_png8(&png_path, 2, 1, 3, &[1, 2, 3, 4, 5, 6], true).unwrap();
        let b = read_brush(&png_path).unwrap();
        assert_eq!((b.width, b.height), (2, 1));
        assert!((b.values[0] - (0.2126 + 0.7152 * 2.0 + 0.0722 * 3.0) / 255.0).abs() < 1e-6);
    }

    /// A PNG of `color` type and `depth` with these raw samples.
    fn png_bytes(
        w: u32,
        h: u32,
        color: png::ColorType,
        depth: png::BitDepth,
        data: &[u8],
        palette: Option<&[u8]>,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        if let Some(p) = palette {
            enc.set_palette(p.to_vec());
        }
        let mut wr = enc.write_header().unwrap();
        wr.write_image_data(data).unwrap();
        wr.finish().unwrap();
        out
    }

    #[test]
    fn brushes_read_every_png_colour_type() {
        use png::{BitDepth as D, ColorType as C};
        let dir = crate::test_dir::ScratchDir::new("brush");
        let read = |name: &str, bytes: Vec<u8>| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            read_brush(&p)
        };
        let luma = |r: f32, g: f32, b: f32| (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0;
        let close = |got: &[f32], want: &[f32]| {
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-6, "{got:?} vs {want:?}");
            }
        };
        let b = read("g.png", png_bytes(3, 1, C::Grayscale, D::Eight, &[0, 51, 255], None)).unwrap();
        assert_eq!((b.width, b.height), (3, 1));
        close(&b.values, &[0.0, 0.2, 1.0]);
        // Gray × alpha.
        let b = read(
            "ga.png",
            png_bytes(2, 1, C::GrayscaleAlpha, D::Eight, &[255, 51, 102, 255], None),
        )
        .unwrap();
        close(&b.values, &[0.2, 0.4]);
        // Rec. 709 luma × alpha.
        let b = read(
            "rgba.png",
            png_bytes(1, 2, C::Rgba, D::Eight, &[10, 20, 30, 255, 200, 100, 50, 51], None),
        )
        .unwrap();
        close(&b.values, &[luma(10.0, 20.0, 30.0), luma(200.0, 100.0, 50.0) * 0.2]);
        // 16 bits are cut to their high byte; 1-bit gray is expanded.
        let b = read(
            "g16.png",
            png_bytes(2, 1, C::Grayscale, D::Sixteen, &[0x33, 0xff, 0xff, 0x00], None),
        )
        .unwrap();
        close(&b.values, &[0.2, 1.0]);
        let b = read("g1.png", png_bytes(8, 1, C::Grayscale, D::One, &[0b1010_0000], None)).unwrap();
        close(&b.values, &[1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        // A palette expands to its colours.
        let pal = [255, 0, 0, 0, 0, 255];
        let b = read("p.png", png_bytes(2, 1, C::Indexed, D::Eight, &[1, 0], Some(&pal))).unwrap();
        close(&b.values, &[luma(0.0, 0.0, 255.0), luma(255.0, 0.0, 0.0)]);
        // Not a PNG: an error naming the file.
        let e = read("bad.png", b"not a png".to_vec()).unwrap_err();
        assert!(
            e.to_string().contains("bad.png") && e.to_string().contains("cannot read brush PNG"),
            "{e}"
        );
    }

    #[test]
    fn brushes_larger_than_the_limit_are_refused_before_decoding() {
        use png::{BitDepth as D, ColorType as C};
        let dir = crate::test_dir::ScratchDir::new("brush-limit");
        let write = |name: &str, bytes: Vec<u8>| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            p
        };
        // At the limit on either side: read.
        let b = read_brush(&write(
            "wide.png",
            png_bytes(4096, 1, C::Grayscale, D::Eight, &[7; 4096], None),
        ))
        .unwrap();
        assert_eq!((b.width, b.height), (4096, 1));
        let b = read_brush(&write(
            "tall.png",
            png_bytes(1, 4096, C::Grayscale, D::Eight, &[7; 4096], None),
        ))
        .unwrap();
        assert_eq!((b.width, b.height), (1, 4096));
        // One pixel more: refused from the header alone. The IHDR of a
        // 1 × 1 PNG is rewritten; its image data holds one pixel, so
        // decoding the claimed size would fail (or, huge, exhaust memory).
        for (w, h) in [
            (4097u32, 1u32),
            (1, 4097),
            (30000, 30000),
            (u32::MAX >> 1, u32::MAX >> 1),
        ] {
            let full = png_bytes(1, 1, C::Grayscale, D::One, &[0], None);
            let mut bytes = full.clone();
            bytes[16..20].copy_from_slice(&w.to_be_bytes());
            bytes[20..24].copy_from_slice(&h.to_be_bytes());
            let crc = crc32(&bytes[12..29]);
            bytes[29..33].copy_from_slice(&crc.to_be_bytes());
            let p = write("huge.png", bytes);
            let e = read_brush(&p).unwrap_err().to_string();
            assert_eq!(
                e,
                format!(
                    "{}: brush PNG is {w} x {h} pixels; painterly reads brushes of at most 4096 x 4096 \
                     (scale the footprint down)",
                    p.display()
                )
            );
        }
    }

    /// CRC-32 (IEEE, as PNG chunks use), bit by bit.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in bytes {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    #[test]
    fn srgb_codes_match_the_standard_at_every_8_bit_step() {
        // IEC 61966-2-1 in f64, rounded.
        let exact = |x: f64| {
            let e = if x <= 0.0031308 {
                12.92 * x
            } else {
                1.055 * x.powf(1.0 / 2.4) - 0.055
            };
            (e * 255.0).round() as i32
        };
        let lut = SrgbTable::new();
        for i in 0..=20_000 {
            let x = i as f64 / 20_000.0;
            assert!((to_u8(srgb_encode(x as f32)) as i32 - exact(x)).abs() <= 1, "{x}");
            assert!((lut.get(x as f32) as i32 - exact(x)).abs() <= 1, "{x}");
        }
        // Out of range, NaN and the steep foot.
        assert_eq!((lut.get(-1.0), lut.get(2.0), lut.get(f32::NAN)), (0, 255, 0));
        assert_eq!(lut.get(0.002) as i32, exact(0.002));
        assert_eq!((to_u8(-0.5), to_u8(1.5), to_u8(0.5)), (0, 255, 128));
        assert!((srgb_decode(0.5) - 0.214_041_14).abs() < 1e-6);
        assert!((srgb_decode(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }

    #[test]
    fn transparent_pixels_are_black_whatever_their_colour() {
        // Straight alpha has no colour where A = 0: (0, 0, 0, 0), not RGB / 0.
        let frame = Frame {
            width: 1,
            height: 1,
            rgba: vec![[0.5, 0.25, 1.0, 0.0]],
            z: vec![1.0],
        };
        assert_eq!(frame_to_srgb8(&frame, None), vec![0, 0, 0, 0]);
    }
}
