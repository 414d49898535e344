//! Contact sheets: every frame scaled down (box filter in linear light),
//! flattened over a background colour, laid out in a grid with its frame
//! number underneath.

use glam::Vec3;

use super::composite::Frame;
use super::image_io::srgb_encode;

/// Widest sheet the layout aims for, in pixels.
pub const MAX_SHEET_WIDTH: usize = 1600;
/// Most frames a sheet lays out (`render --sheet` refuses more): keeps the
/// thumbnails held until the sheet is written, and the sheet, bounded.
pub const MAX_SHEET_FRAMES: usize = 2000;
const MARGIN: usize = 12;
const GAP: usize = 8;
/// Most columns that fit in [`MAX_SHEET_WIDTH`] at one pixel per thumbnail.
const MAX_COLUMNS: usize = (MAX_SHEET_WIDTH - 2 * MARGIN + GAP) / (1 + GAP);
/// Label glyphs are 5 × 7 cells drawn at this scale (at 1 when a sheet's
/// labels do not all fit their thumbnails at it).
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

/// The sheet's size in pixels for `n` thumbnails of `tw` × `th` in `cols`
/// columns: margins, gaps, and a label band under every row.
pub fn sheet_size(n: usize, cols: usize, tw: usize, th: usize) -> (usize, usize) {
    let cols = cols.clamp(1, n.max(1));
    let rows = n.div_ceil(cols).max(1);
    (
        2 * MARGIN + cols * tw + (cols - 1) * GAP,
        2 * MARGIN + rows * (th + LABEL_BAND) + (rows - 1) * GAP,
    )
}

/// Columns for `n` frames of `width` × `height` pixels: the count whose
/// whole sheet (thumbnails reduced to fit, gaps, label bands, margins) is
/// closest to 16:10 in ratio, the fewer columns on a tie, at most as many as
/// fit in [`MAX_SHEET_WIDTH`]. The label bands and gaps count: with small
/// thumbnails they are most of a row's height.
pub fn columns(n: usize, width: usize, height: usize) -> usize {
    let off = |c: usize| {
        let f = reduction(width, c);
        let (w, h) = sheet_size(n, c, (width / f).max(1), (height / f).max(1));
        (w as f64 / h as f64 / 1.6).ln().abs()
    };
    (1..=n.clamp(1, MAX_COLUMNS))
        .min_by(|&a, &b| off(a).total_cmp(&off(b)))
        .unwrap_or(1)
}

/// The smallest integer reduction factor so `columns` thumbnails of a
/// `width`-pixel frame fit in [`MAX_SHEET_WIDTH`] (a thumbnail is
/// ⌊width / factor⌋ wide).
pub fn reduction(width: usize, columns: usize) -> usize {
    let columns = columns.clamp(1, MAX_COLUMNS);
    let avail = (MAX_SHEET_WIDTH - 2 * MARGIN - (columns - 1) * GAP) / columns;
    // ⌊width / f⌋ ≤ avail exactly when f > width / (avail + 1).
    width / (avail.max(1) + 1) + 1
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

/// Pixels from the left of a label's first glyph to the right of its last,
/// at `scale`.
fn label_width(glyphs: usize, scale: usize) -> usize {
    (glyphs * 6).saturating_sub(1) * scale
}

/// The glyph scale for a sheet's labels: 2 when every label fits its
/// thumbnail's width at 2, else 1 (one size on a sheet, so the numbers read
/// alike). At 1 a label still wider than its thumbnail is left out: a
/// clipped number would read as another number.
fn label_scale(thumbs: &[Thumbnail]) -> usize {
    let fits = |t: &Thumbnail| label_width(t.label.chars().filter_map(glyph).count(), GLYPH_SCALE) <= t.width;
    if thumbs.iter().all(fits) {
        GLYPH_SCALE
    } else {
        1
    }
}

/// Lays the thumbnails out; returns (width, height, 8-bit sRGB RGB pixels).
/// Each thumbnail's cell is its column's width by its row's thumbnail and
/// label band; nothing is drawn outside it.
pub fn compose(thumbs: &[Thumbnail], cols: usize, background: Vec3, ink: Vec3) -> (usize, usize, Vec<u8>) {
    let tw = thumbs.iter().map(|t| t.width).max().unwrap_or(1);
    let th = thumbs.iter().map(|t| t.height).max().unwrap_or(1);
    let cols = cols.clamp(1, thumbs.len().max(1));
    let (width, height) = sheet_size(thumbs.len(), cols, tw, th);
    let scale = label_scale(thumbs);
    let mut px = vec![background; width * height];
    for (k, t) in thumbs.iter().enumerate() {
        let (c, r) = (k % cols, k / cols);
        let x0 = MARGIN + c * (tw + GAP);
        let y0 = MARGIN + r * (th + LABEL_BAND + GAP);
        for y in 0..t.height {
            let dst = (y0 + y) * width + x0;
            px[dst..dst + t.width].copy_from_slice(&t.rgb[y * t.width..(y + 1) * t.width]);
        }
        // The label, centred under the thumbnail, when it fits its width.
        let glyphs: Vec<[u8; 7]> = t.label.chars().filter_map(glyph).collect();
        if label_width(glyphs.len(), scale) > t.width {
            continue;
        }
        let advance = 6 * scale;
        let lx = x0 + t.width.saturating_sub(glyphs.len() * advance) / 2;
        let ly = y0 + t.height + 4;
        for (g, rows_bits) in glyphs.iter().enumerate() {
            for (gy, bits) in rows_bits.iter().enumerate() {
                for gx in 0..5 {
                    if bits & (0x10 >> gx) == 0 {
                        continue;
                    }
                    for sy in 0..scale {
                        for sx in 0..scale {
                            let x = lx + g * advance + gx * scale + sx;
                            let y = ly + gy * scale + sy;
                            px[y * width + x] = ink;
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
        assert!(reduction(1920, 7) >= 1920 * 7 / MAX_SHEET_WIDTH);
    }

    /// sRGB 8-bit code of a linear value (IEC 61966-2-1), for expected pixels.
    fn srgb8(v: f32) -> u8 {
        let v = v.clamp(0.0, 1.0) as f64;
        let e = if v <= 0.0031308 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (e * 255.0).round() as u8
    }

    #[test]
    fn columns_make_the_whole_sheet_about_16_10() {
        // By hand: c columns reduce by f = ⌊w / (avail + 1)⌋ + 1, avail =
        // ⌊(1576 − 8 (c − 1)) / c⌋; the sheet is 24 + c·tw + 8 (c − 1) by
        // 24 + rows·(th + 22) + 8 (rows − 1); the best |ln(aspect / 1.6)| wins.
        //
        // The bug report: 1999 frames of 192 × 108. c = 77: avail 12, f 15,
        // 12 × 7 thumbnails, 26 rows: 1556 × 978 (1.591). c = 76: 27 rows,
        // 1536 × 1015 (1.513); c = 78: 1576 × 978 (1.611). The old rule
        // (42 columns by the thumbnails alone) gave a portrait 1486 × 2176.
        assert_eq!(columns(1999, 192, 108), 77);
        assert_eq!(sheet_size(1999, 77, 12, 7), (1556, 978));
        // 9 of 360 × 225, no reduction: c = 3 is 1120 × 781 (1.434), c = 4
        // 1488 × 781 (1.905), c = 2 752 × 1291.
        assert_eq!(columns(9, 360, 225), 3);
        // 12 of 320 × 200: c = 4 is 1328 × 706 (1.881), c = 3 1000 × 936
        // (1.068), c = 5 reduces by 2: 856 × 406 (2.108).
        assert_eq!(columns(12, 320, 200), 4);
        assert_eq!(sheet_size(12, 3, 320, 200), (1000, 936));
        assert_eq!(columns(1, 1, 1), 1);
        assert_eq!(columns(0, 100, 100), 1);
        // Tall frames: no more columns than fit one pixel each with their
        // gaps: (1600 − 2·12 + 8) / 9 = 176, even though the sheet stays tall.
        assert_eq!(columns(2000, 1, 1000), 176);
        // Wide frames: 3 of 1000 × 100 in one column are 1024 × 406 (2.52);
        // two columns reduce by 2 to 500 × 50: 1032 × 176 (5.86).
        assert_eq!(columns(3, 1000, 100), 1);
    }

    #[test]
    fn reduced_sheets_fit_the_width() {
        // avail = (1600 − 24 − 8 (c − 1)) / c; the factor is the smallest f
        // with ⌊width / f⌋ ≤ avail.
        assert_eq!(reduction(1920, 7), 9); // avail 218: 8 × 218 = 1744 < 1920
        assert_eq!(reduction(1576, 1), 1);
        assert_eq!(reduction(1577, 1), 2);
        assert_eq!(reduction(100, 1), 1);
        assert_eq!(reduction(16, 176), 9); // avail 1: ⌊16 / 8⌋ = 2 is too wide
        assert_eq!(reduction(4096, 11), 30); // avail 136 = ⌊4096 / 30⌋
        assert_eq!(reduction(16, 0), 1);
        for c in 1..=176 {
            for w in [1, 7, 100, 333, 1920, 4096] {
                let f = reduction(w, c);
                let tw = (w / f).max(1);
                assert!(2 * MARGIN + c * tw + (c - 1) * GAP <= MAX_SHEET_WIDTH, "{c} × {w}");
                // And the factor is the smallest that fits.
                if f > 1 {
                    let wider = w / (f - 1);
                    assert!(
                        2 * MARGIN + c * wider + (c - 1) * GAP > MAX_SHEET_WIDTH,
                        "{c} × {w}: {f}"
                    );
                }
            }
        }
    }

    fn frame(width: usize, height: usize, f: impl Fn(usize, usize) -> [f32; 4]) -> Frame {
        Frame {
            width,
            height,
            rgba: (0..height)
                .flat_map(|y| (0..width).map(move |x| (x, y)))
                .map(|(x, y)| f(x, y))
                .collect(),
            z: vec![0.0; width * height],
        }
    }

    #[test]
    fn thumbnails_are_block_means_over_the_background() {
        // 5 × 3 by 2: two 2 × 2 blocks; column 4 and row 2 are dropped.
        let f = frame(5, 3, |x, y| {
            let a = (x + 2 * y) as f32 / 8.0;
            [a * 0.5, a * 0.25, 0.0, a]
        });
        let bg = Vec3::new(0.2, 0.4, 0.6);
        let t = thumbnail(&f, 2, bg, "12".into());
        assert_eq!((t.width, t.height, t.label.as_str()), (2, 1, "12"));
        // Block 0: alphas (0, 1, 2, 3)/8, mean 1.5/8; block 1: (2, 3, 4, 5)/8, mean 3.5/8.
        for (k, mean) in [(0, 1.5f32 / 8.0), (1, 3.5 / 8.0)] {
            let want = Vec3::new(mean * 0.5, mean * 0.25, 0.0) + bg * (1.0 - mean);
            assert!((t.rgb[k] - want).length() < 1e-6, "{k}: {} vs {want}", t.rgb[k]);
        }
        // A frame smaller than the factor still gives one pixel.
        let one = thumbnail(&frame(3, 2, |_, _| [0.0, 0.0, 0.0, 0.0]), 4, bg, String::new());
        assert_eq!((one.width, one.height, one.rgb[0]), (1, 1, bg));
    }

    #[test]
    fn glyphs_cover_frame_numbers() {
        let chars = "0123456789.-";
        let all: Vec<[u8; 7]> = chars.chars().map(|c| glyph(c).unwrap()).collect();
        for (i, g) in all.iter().enumerate() {
            assert!(g.iter().all(|&row| row < 0x20), "{i}: five columns");
            assert!(g.iter().any(|&row| row != 0));
            for (j, h) in all.iter().enumerate().skip(i + 1) {
                assert_ne!(g, h, "{} and {} look alike", &chars[i..=i], &chars[j..=j]);
            }
        }
        assert_eq!(glyph('x'), None);
        assert_eq!(glyph(' '), None);
    }

    #[test]
    fn compose_lays_out_thumbnails_and_labels() {
        let (bg, ink) = (Vec3::splat(0.5), Vec3::ZERO);
        let thumb = |label: &str, c: f32| Thumbnail {
            label: label.into(),
            width: 30,
            height: 20,
            rgb: vec![Vec3::new(c, 0.0, 1.0 - c); 600],
        };
        let thumbs: Vec<Thumbnail> = (0..5).map(|k| thumb(&format!("{k}"), k as f32 / 4.0)).collect();
        let (w, h, px) = compose(&thumbs, 2, bg, ink);
        // 2 columns, 3 rows.
        assert_eq!(w, 2 * MARGIN + 2 * 30 + GAP);
        assert_eq!(h, 2 * MARGIN + 3 * (20 + LABEL_BAND) + 2 * GAP);
        let at = |x: usize, y: usize| [px[3 * (y * w + x)], px[3 * (y * w + x) + 1], px[3 * (y * w + x) + 2]];
        let code = |c: Vec3| [srgb8(c.x), srgb8(c.y), srgb8(c.z)];
        for (k, t) in thumbs.iter().enumerate() {
            let (x0, y0) = (
                MARGIN + (k % 2) * (30 + GAP),
                MARGIN + (k / 2) * (20 + LABEL_BAND + GAP),
            );
            // The thumbnail's corners, and background just outside them.
            for (x, y) in [(x0, y0), (x0 + 29, y0 + 19)] {
                assert_eq!(at(x, y), code(t.rgb[0]), "thumbnail {k}");
            }
            assert_eq!(at(x0 - 1, y0), code(bg));
            assert_eq!(at(x0 + 30, y0 + 19), code(bg));
            // Its one-digit label: 12 px advance, centred: (30 − 12) / 2 = 9 px in,
            // 4 px under; each glyph cell is 2 × 2 pixels of ink.
            let g = glyph(char::from(b'0' + k as u8)).unwrap();
            let (lx, ly) = (x0 + 9, y0 + 20 + 4);
            for (gy, bits) in g.iter().enumerate() {
                for gx in 0..5 {
                    let want = if bits & (0x10 >> gx) != 0 { code(ink) } else { code(bg) };
                    for (sx, sy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        assert_eq!(at(lx + 2 * gx + sx, ly + 2 * gy + sy), want, "label {k} cell {gx},{gy}");
                    }
                }
            }
        }
        // The sixth cell of the grid is empty.
        assert_eq!(
            at(MARGIN + 30 + GAP + 15, MARGIN + 2 * (20 + LABEL_BAND + GAP) + 10),
            code(bg)
        );
        // More columns than thumbnails: one row; a label wider than its
        // thumbnail even at scale 1 (10 glyphs: 59 px > 30) is left out.
        let wide = Thumbnail {
            label: "-1234567.5".into(),
            ..thumb("", 0.0)
        };
        let (w1, h1, px1) = compose(&[wide], 4, bg, ink);
        assert_eq!((w1, h1), (2 * MARGIN + 30, 2 * MARGIN + 20 + LABEL_BAND));
        assert_eq!(px1.len(), w1 * h1 * 3);
        for y in MARGIN + 20..h1 {
            for x in 0..w1 {
                assert_eq!(px1[3 * (y * w1 + x)..3 * (y * w1 + x) + 3], code(bg), "{x},{y}");
            }
        }
        // No thumbnails: an empty sheet of margins.
        let (w0, h0, _) = compose(&[], 3, bg, ink);
        assert_eq!((w0, h0), (2 * MARGIN + 1, 2 * MARGIN + 1 + LABEL_BAND));
    }

    #[test]
    fn thumbnail_rows_below_the_first_average_their_own_block() {
        // 4 × 4 by 2, opaque, R = (x + 4y) / 16: block means by hand.
        let f = frame(4, 4, |x, y| [(x + 4 * y) as f32 / 16.0, 0.0, 0.0, 1.0]);
        let t = thumbnail(&f, 2, Vec3::ONE, String::new());
        assert_eq!((t.width, t.height), (2, 2));
        let r: Vec<f32> = t.rgb.iter().map(|c| c.x).collect();
        assert_eq!(r, [10.0 / 64.0, 18.0 / 64.0, 42.0 / 64.0, 50.0 / 64.0]);
    }

    #[test]
    fn the_label_band_is_22_pixels() {
        // 4 px gap, 7 glyph rows × 2 px, 4 px below: the sheet's height and the
        // second row's top in literal pixels, one 30 × 20 thumbnail per row.
        let t = Thumbnail {
            label: "7".into(),
            width: 30,
            height: 20,
            rgb: vec![Vec3::ONE; 600],
        };
        let (w, h, px) = compose(&[t.clone(), t], 1, Vec3::ZERO, Vec3::ZERO);
        assert_eq!((w, h), (12 + 30 + 12, 12 + 20 + 22 + 8 + 20 + 22 + 12));
        let at = |x: usize, y: usize| px[3 * (y * w + x)];
        assert_eq!((at(12, 61), at(12, 62)), (0, 255));
    }

    #[test]
    fn labels_run_left_to_right_and_stay_off_the_margin() {
        let (bg, ink) = (Vec3::splat(0.5), Vec3::ZERO);
        let thumb = |label: &str| Thumbnail {
            label: label.into(),
            width: 30,
            height: 20,
            rgb: vec![Vec3::ONE; 600],
        };
        let (b, i) = (srgb8(0.5), srgb8(0.0));
        // "10": 24 px of text centred in 30, 3 px in; '0' starts 12 px after '1'.
        let (w, _, px) = compose(&[thumb("10")], 1, bg, ink);
        let at = |x: usize, y: usize| px[3 * (y * w + x)];
        let (lx, ly) = (MARGIN + 3, MARGIN + 20 + 4);
        for (k, c) in ['1', '0'].into_iter().enumerate() {
            for (gy, bits) in glyph(c).unwrap().iter().enumerate() {
                for gx in 0..5 {
                    let want = if bits & (0x10 >> gx) != 0 { i } else { b };
                    let (x, y) = (lx + 12 * k + 2 * gx, ly + 2 * gy);
                    assert_eq!([at(x, y), at(x + 1, y + 1)], [want; 2], "{c} cell {gx},{gy}");
                }
            }
        }
        // A label wider than the sheet is left out: nothing wraps into the
        // next rows' left margin.
        let (w, h, px) = compose(&[thumb("-1234567.5")], 1, bg, ink);
        for y in 0..h {
            for x in 0..MARGIN {
                assert_eq!(px[3 * (y * w + x)], b, "{x},{y}");
            }
        }
    }

    /// Ink pixels of a composed sheet, as (x, y).
    #[test]
    fn a_label_exactly_as_wide_as_its_thumbnail_is_drawn() {
        // Glyphs are 5 cells wide with 1 cell between: n glyphs take 6n − 1
        // cells, each `scale` pixels.
        assert_eq!(
            [
                label_width(1, 1),
                label_width(4, 1),
                label_width(4, 2),
                label_width(0, 2)
            ],
            [5, 23, 46, 0]
        );
        // "1.01" is 23 px at scale 1: a thumbnail 23 px wide shows it, 22 px not.
        let (bg, ink) = (Vec3::splat(0.5), Vec3::ZERO);
        for (width, drawn) in [(23, true), (22, false)] {
            let t = Thumbnail {
                label: "1.01".into(),
                width,
                height: 4,
                rgb: vec![Vec3::ONE; width * 4],
            };
            let (w, _, px) = compose(&[t], 1, bg, ink);
            assert_eq!(!ink_pixels(w, &px, ink).is_empty(), drawn, "{width}");
        }
    }

    fn ink_pixels(w: usize, px: &[u8], ink: Vec3) -> Vec<(usize, usize)> {
        let want = [srgb8(ink.x), srgb8(ink.y), srgb8(ink.z)];
        px.chunks(3)
            .enumerate()
            .filter(|(_, c)| *c == want)
            .map(|(i, _)| (i % w, i / w))
            .collect()
    }

    #[test]
    fn labels_that_do_not_fit_shrink_or_are_left_out_never_leaving_their_cell() {
        // The bug report's labels: frames 1, 1.01, 1.02, ... under 27 × 15
        // thumbnails (192 × 108 reduced by 7). "1.01" is 4 glyphs: 4·6 − 1 =
        // 23 cells, 46 px at scale 2 (too wide), 23 px at scale 1 (fits).
        let (bg, ink) = (Vec3::splat(0.5), Vec3::ZERO);
        let thumb = |label: &str| Thumbnail {
            label: label.into(),
            width: 27,
            height: 15,
            rgb: vec![Vec3::ONE; 27 * 15],
        };
        let labels: Vec<String> = (0..12)
            .map(|k| if k == 0 { "1".into() } else { format!("1.{k:02}") })
            .collect();
        let mut thumbs: Vec<Thumbnail> = labels.iter().map(|l| thumb(l)).collect();
        // One that fits at neither scale: 10 glyphs, 59 px at scale 1.
        thumbs[7].label = "-1234567.5".into();
        let cols = 4;
        let (w, _, px) = compose(&thumbs, cols, bg, ink);
        // Cell k: x ∈ [12 + 35 c, +27), y ∈ [12 + 45 r, +15 + 22).
        let cell = |k: usize| (MARGIN + (k % cols) * 35, MARGIN + (k / cols) * 45);
        let mut per_cell = vec![0usize; thumbs.len()];
        for (x, y) in ink_pixels(w, &px, ink) {
            let k = (0..thumbs.len())
                .find(|&k| {
                    let (x0, y0) = cell(k);
                    (x0..x0 + 27).contains(&x) && (y0 + 15..y0 + 37).contains(&y)
                })
                .unwrap_or_else(|| panic!("ink at {x},{y} outside every label cell"));
            per_cell[k] += 1;
        }
        assert_eq!(per_cell[7], 0, "the label that cannot fit is left out");
        assert!(
            per_cell.iter().enumerate().all(|(k, &n)| k == 7 || n > 0),
            "{per_cell:?}"
        );
        // Every label at scale 1, "1.05" (cell 5) exactly: 24 px of advance
        // centred in 27 → 1 px in, 4 px under the thumbnail, one pixel a cell.
        let (x0, y0) = cell(5);
        let (lx, ly) = (x0 + 1, y0 + 15 + 4);
        let at = |x: usize, y: usize| px[3 * (y * w + x)];
        for (g, ch) in "1.05".chars().enumerate() {
            for (gy, bits) in glyph(ch).unwrap().iter().enumerate() {
                for gx in 0..5 {
                    let want = if bits & (0x10 >> gx) != 0 {
                        srgb8(0.0)
                    } else {
                        srgb8(0.5)
                    };
                    assert_eq!(at(lx + 6 * g + gx, ly + gy), want, "{ch} cell {gx},{gy}");
                }
            }
        }
        // "1" alone would fit at scale 2 but takes the sheet's scale 1: one
        // pixel per ink cell of its glyph.
        let one_ink = glyph('1')
            .unwrap()
            .iter()
            .map(|r| r.count_ones() as usize)
            .sum::<usize>();
        assert_eq!(per_cell[0], one_ink);

        // `--size 1x1`: one-pixel thumbnails fit no label; nothing but the
        // thumbnails on the background.
        let tiny: Vec<Thumbnail> = labels
            .iter()
            .map(|l| Thumbnail {
                label: l.clone(),
                width: 1,
                height: 1,
                rgb: vec![Vec3::ONE],
            })
            .collect();
        let (w, _, px) = compose(&tiny, 6, bg, ink);
        assert_eq!(ink_pixels(w, &px, ink), []);

        // All labels fit at scale 2 (wide thumbnails): drawn at 2, 2 × 2 px a cell.
        let wide: Vec<Thumbnail> = labels
            .iter()
            .map(|l| Thumbnail {
                width: 60,
                rgb: vec![Vec3::ONE; 60 * 15],
                ..thumb(l)
            })
            .collect();
        let (w, _, px) = compose(&wide, 4, bg, ink);
        let ones = ink_pixels(w, &px, ink)
            .into_iter()
            .filter(|&(x, y)| x < MARGIN + 60 && y < MARGIN + 15 + LABEL_BAND)
            .count();
        assert_eq!(ones, 4 * one_ink);
    }
}
