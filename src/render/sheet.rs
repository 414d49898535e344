//! Contact sheets: every frame scaled down (box filter in linear light),
//! flattened over a background colour, laid out in a grid with its frame
//! number underneath.

use glam::Vec3;

use super::composite::Frame;
use super::image_io::srgb_encode;

/// Widest sheet the layout aims for, in pixels.
pub const MAX_SHEET_WIDTH: usize = 1600;
const MARGIN: usize = 12;
const GAP: usize = 8;
/// Label glyphs are 5 × 7 cells drawn at this scale.
const GLYPH_SCALE: usize = 2;
const LABEL_BAND: usize = 7 * GLYPH_SCALE + 8;

/// One frame, reduced.
#[derive(Debug, Clone)]
pub struct Thumbnail {
    pub label: String,
    pub width: usize,
    pub height: usize,
    /// Linear RGB, flattened over the background.
    pub rgb: Vec<Vec3>,
}

/// Columns for `n` thumbnails of aspect `aspect` so the sheet is roughly 16:10.
pub fn columns(n: usize, aspect: f64) -> usize {
    let c = ((n as f64) * 1.6 / aspect).sqrt().round() as usize;
    c.clamp(1, n.max(1))
}

/// The integer reduction factor so `columns` thumbnails of a `width`-pixel
/// frame fit in [`MAX_SHEET_WIDTH`].
pub fn reduction(width: usize, columns: usize) -> usize {
    let avail = (MAX_SHEET_WIDTH - 2 * MARGIN - (columns - 1) * GAP) / columns;
    width.div_ceil(avail.max(1)).max(1)
}

/// Box-filters `frame` by `factor` and flattens it over `background`.
pub fn thumbnail(frame: &Frame, factor: usize, background: Vec3, label: String) -> Thumbnail {
    let (w, h) = ((frame.width / factor).max(1), (frame.height / factor).max(1));
    let mut rgb = Vec::with_capacity(w * h);
    for ty in 0..h {
        for tx in 0..w {
            let mut acc = [0.0f32; 4];
            let mut n = 0.0;
            for y in ty * factor..((ty + 1) * factor).min(frame.height) {
                for x in tx * factor..((tx + 1) * factor).min(frame.width) {
                    let p = frame.rgba[y * frame.width + x];
                    for k in 0..4 {
                        acc[k] += p[k];
                    }
                    n += 1.0;
                }
            }
            let a = acc[3] / n;
            rgb.push(Vec3::new(acc[0], acc[1], acc[2]) / n + background * (1.0 - a));
        }
    }
    Thumbnail {
        label,
        width: w,
        height: h,
        rgb,
    }
}

/// 5 × 7 glyphs, one row per entry, bit 4 = leftmost column.
fn glyph(c: char) -> Option<[u8; 7]> {
    Some(match c {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1e, 0x01, 0x01, 0x0e, 0x01, 0x01, 0x1e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        '-' => [0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00],
        _ => return None,
    })
}

/// Lays the thumbnails out; returns (width, height, 8-bit sRGB RGB pixels).
pub fn compose(thumbs: &[Thumbnail], cols: usize, background: Vec3, ink: Vec3) -> (usize, usize, Vec<u8>) {
    let tw = thumbs.iter().map(|t| t.width).max().unwrap_or(1);
    let th = thumbs.iter().map(|t| t.height).max().unwrap_or(1);
    let cols = cols.clamp(1, thumbs.len().max(1));
    let rows = thumbs.len().div_ceil(cols).max(1);
    let width = 2 * MARGIN + cols * tw + (cols - 1) * GAP;
    let height = 2 * MARGIN + rows * (th + LABEL_BAND) + (rows - 1) * GAP;
    let mut px = vec![background; width * height];
    for (k, t) in thumbs.iter().enumerate() {
        let (c, r) = (k % cols, k / cols);
        let x0 = MARGIN + c * (tw + GAP);
        let y0 = MARGIN + r * (th + LABEL_BAND + GAP);
        for y in 0..t.height {
            let dst = (y0 + y) * width + x0;
            px[dst..dst + t.width].copy_from_slice(&t.rgb[y * t.width..(y + 1) * t.width]);
        }
        // The label, centred under the thumbnail.
        let glyphs: Vec<[u8; 7]> = t.label.chars().filter_map(glyph).collect();
        let advance = 6 * GLYPH_SCALE;
        let text_w = glyphs.len() * advance;
        let lx = x0 + t.width.saturating_sub(text_w) / 2;
        let ly = y0 + t.height + 4;
        for (g, rows_bits) in glyphs.iter().enumerate() {
            for (gy, bits) in rows_bits.iter().enumerate() {
                for gx in 0..5 {
                    if bits & (0x10 >> gx) == 0 {
                        continue;
                    }
                    for sy in 0..GLYPH_SCALE {
                        for sx in 0..GLYPH_SCALE {
                            let x = lx + g * advance + gx * GLYPH_SCALE + sx;
                            let y = ly + gy * GLYPH_SCALE + sy;
                            if x < width && y < height {
                                px[y * width + x] = ink;
                            }
                        }
                    }
                }
            }
        }
    }
    let bytes = px
        .iter()
        .flat_map(|c| [c.x, c.y, c.z])
        .map(|v| (srgb_encode(v) * 255.0 + 0.5) as u8)
        .collect();
    (width, height, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thumbnails_average_in_linear_light_and_grid_fits() {
        let frame = Frame {
            width: 4,
            height: 2,
            rgba: vec![
                [1.0, 0.0, 0.0, 1.0],
                [0.0; 4],
                [0.0; 4],
                [0.0; 4],
                [1.0, 0.0, 0.0, 1.0],
                [0.0; 4],
                [0.0; 4],
                [0.0; 4],
            ],
            z: vec![0.0; 8],
        };
        let t = thumbnail(&frame, 2, Vec3::new(0.0, 0.0, 1.0), "1".into());
        assert_eq!((t.width, t.height), (2, 1));
        assert!((t.rgb[0] - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-6);
        assert_eq!(t.rgb[1], Vec3::new(0.0, 0.0, 1.0));
        let (w, h, px) = compose(&[t.clone(), t.clone(), t], 2, Vec3::ONE, Vec3::ZERO);
        assert_eq!(px.len(), w * h * 3);
        assert_eq!(w, 2 * MARGIN + 2 * 2 + GAP);
        assert_eq!(h, 2 * MARGIN + 2 * (1 + LABEL_BAND) + GAP);
        assert_eq!(columns(48, 16.0 / 9.0), 7);
        assert!(reduction(1920, 7) >= 1920 * 7 / MAX_SHEET_WIDTH);
    }
}
