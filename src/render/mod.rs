//! `painterly render`: preview frames of painted strokes and view-dependent
//! meshes, as linear EXR (R, G, B, A, Z) and optional sRGB PNG previews and a
//! contact sheet.
//!
//! The input is composed with a bake layer (`--bake`, or one baked on the
//! fly into a temporary folder) through a temporary root layer that
//! sublayers both; each frame is then read ([`crate::usd_io::render_scene`]),
//! projected with the USD camera's own parameters ([`camera`]), turned into
//! pixel-space primitives ([`prepare`]), rasterised and composited
//! ([`raster`], [`composite`], shaded by [`shade`]) and written
//! ([`image_io`], [`sheet`]). Apart from `run`, the stage it composes and
//! reads, and [`image_io`] (which reads brush images and writes EXR/PNG
//! files), everything here is pure math on plain numbers. See
//! docs/render.md for the design notes.
//!
//! | module | concept |
//! |---|---|
//! | [`camera`] | UsdGeomCamera → frustum window → pixels; conform policy |
//! | [`curves`] | BasisCurves tessellation into stroke polylines |
//! | [`prepare`] | world-space strokes and meshes → pixel-space primitives |
//! | [`raster`] | ribbon coverage, triangle rasterisation |
//! | [`shade`] | Rademacher's warm/cool shading |
//! | [`composite`] | tiles, z-buffer, silhouettes, stroke compositing |
//! | [`image_io`] | EXR, PNG, brush footprints |
//! | [`sheet`] | contact sheets |

pub mod camera;
pub mod composite;
pub mod curves;
pub mod image_io;
pub mod prepare;
pub mod raster;
pub mod shade;
pub mod sheet;

use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;

use crate::bake::{bake_if_any, BakeOptions};
use crate::error::{Error, Result};
use crate::frames::FrameRange;
use crate::usd_io::atomic::write_atomic;
pub(crate) use crate::usd_io::atomic::TempDir;
use crate::usd_io::bake_layer::check_baked_from;
use crate::usd_io::render_scene::{layer_timing, RenderScene};
use crate::usd_io::stage::{require_file, StageReader};
use crate::words::plural;

/// Image size `WIDTHxHEIGHT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    pub width: usize,
    pub height: usize,
}

/// The most pixels a frame may have (`--size`), so that a typo fails fast
/// instead of allocating gigabytes.
pub const MAX_PIXELS: usize = 1 << 26;

impl std::str::FromStr for ImageSize {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("{s:?} is not a size (expected WIDTHxHEIGHT, e.g. 1920x1080)");
        let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
        let w: usize = w.trim().parse().map_err(|_| bad())?;
        let h: usize = h.trim().parse().map_err(|_| bad())?;
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(format!("{s:?}: width and height must be between 1 and 16384"));
        }
        // A frame's buffers take tens of bytes a pixel: 64 Mpx is ~2.5 GB.
        if w * h > MAX_PIXELS {
            return Err(format!(
                "{s:?} is {} pixels; at most {MAX_PIXELS} (8192x8192) are rendered",
                w * h
            ));
        }
        Ok(ImageSize { width: w, height: h })
    }
}

/// A colour given as `#rrggbb` or `R,G,B` (display sRGB values in 0..1); held linear.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rgb(pub Vec3);

impl std::str::FromStr for Rgb {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("{s:?} is not a colour (expected #rrggbb or R,G,B with values in 0..1)");
        let srgb: [f32; 3] = if let Some(hex) = s.strip_prefix('#') {
            if hex.len() != 6 {
                return Err(bad());
            }
            let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
            [
                byte(0)? as f32 / 255.0,
                byte(2)? as f32 / 255.0,
                byte(4)? as f32 / 255.0,
            ]
        } else {
            let v: Vec<f32> = s
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| bad())?;
            match v.as_slice() {
                [r, g, b] if [r, g, b].iter().all(|x| (0.0..=1.0).contains(*x)) => [*r, *g, *b],
                _ => return Err(bad()),
            }
        };
        Ok(Rgb(Vec3::from_array(srgb.map(image_io::srgb_decode))))
    }
}

/// `painterly render` options.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// The scene (.usda, .usdc or .usdz).
    pub input: PathBuf,
    /// A layer written by `painterly bake` to compose over the input. Without
    /// it the input is baked first (same frames and camera) into a temporary
    /// folder.
    #[arg(long, value_name = "LAYER")]
    pub bake: Option<PathBuf>,
    /// The UsdGeomCamera prim to render through.
    #[arg(long, value_name = "PRIM")]
    pub camera: String,
    /// Time codes to render: A, A:B or A:B:STEP.
    #[arg(long, value_name = "A:B[:STEP]", allow_hyphen_values = true)]
    pub frames: FrameRange,
    /// Output EXR path; a run of # is replaced by the zero-padded frame
    /// number (out/name.####.exr). The folder must exist.
    #[arg(short, long, value_name = "FILE.####.exr")]
    pub output: PathBuf,
    /// Also write an sRGB PNG preview beside each EXR.
    #[arg(long)]
    pub png: bool,
    /// Image size.
    #[arg(long, default_value = "1920x1080", value_name = "WxH")]
    pub size: ImageSize,
    /// Also write a contact sheet of all frames (NAME.sheet.png; at most 2000
    /// frames).
    #[arg(long)]
    pub sheet: bool,
    /// Grayscale PNG footprint modulating stroke alpha (x across the
    /// stroke's width, y along its length).
    #[arg(long, value_name = "PNG")]
    pub brush: Option<PathBuf>,
    /// Background for PNG previews and the sheet (#rrggbb or R,G,B sRGB).
    /// Without it PNG previews keep their alpha and the sheet uses a light
    /// paper colour. EXR frames always keep their alpha.
    #[arg(long, value_name = "COLOUR")]
    pub background: Option<Rgb>,
    /// Print nothing on success.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print a JSON summary on stdout instead of the summary line.
    #[arg(long)]
    pub json: bool,
}

/// Paper white (#f1ede4) for sheets without --background.
const PAPER: [f32; 3] = [0.879, 0.846, 0.776];

/// Frame names and sheet labels write a frame's whole number as an `i64`:
/// below 2^63 either side of 0 ([`check_args`] refuses frames beyond).
const NAMED_FRAME_BOUND: f64 = 9_223_372_036_854_775_808.0;

/// The whole frames and thousandths a frame's name shows, rounded to
/// thousandths first (12.9996 is frame 13, 0.0001 frame 0), of `|t|`.
fn frame_digits(t: f64) -> (f64, f64) {
    let mut whole = t.abs().trunc();
    let mut thousandths = ((t.abs() - whole) * 1000.0).round();
    if thousandths >= 1000.0 {
        whole += 1.0;
        thousandths = 0.0;
    }
    (whole, thousandths)
}

/// Whether frame `t`'s number is written exactly by [`frame_path`]: its
/// whole part fits an `i64` (beyond, `as i64` saturates).
fn frame_is_nameable(t: f64) -> bool {
    frame_digits(t).0 < NAMED_FRAME_BOUND
}

/// The output path of frame `t`: the first run of `#` becomes the frame
/// number, zero-padded to the run's length (fractional frames keep up to
/// three decimals: `0012.5`).
pub fn frame_path(pattern: &Path, t: f64) -> PathBuf {
    use std::os::unix::ffi::{OsStrExt, OsStringExt};
    // Bytes, not text: a name that is not UTF-8 keeps its bytes ('#' is ASCII).
    let name = pattern.file_name().map(OsStrExt::as_bytes).unwrap_or_default();
    let Some(start) = name.iter().position(|&b| b == b'#') else {
        return pattern.to_path_buf();
    };
    let len = name[start..].iter().take_while(|&&b| b == b'#').count();
    let (whole, thousandths) = frame_digits(t);
    // The sign is shown only when what is shown is not zero (−0.5: `-000.5`).
    let mut num = if t < 0.0 && (whole > 0.0 || thousandths > 0.0) {
        format!("-{:0len$}", whole as i64, len = len.saturating_sub(1))
    } else {
        format!("{:0len$}", whole as i64)
    };
    if thousandths > 0.0 {
        num.push_str(format!(".{:03}", thousandths as u32).trim_end_matches('0'));
    }
    let out = [&name[..start], num.as_bytes(), &name[start + len..]].concat();
    pattern.with_file_name(std::ffi::OsString::from_vec(out))
}

/// The contact sheet's path: the pattern's stem without its first `#` run
/// (the one [`frame_path`] numbers; a later run stays as written) and the
/// `.`, `_` or `-` just before it, extension `.sheet.png`. A run that starts
/// the name takes the separator after it instead (`####.a.exr` gives
/// `a.sheet.png`, not the hidden `.a.sheet.png`); nothing left gives `frames`.
pub fn sheet_path(pattern: &Path) -> PathBuf {
    use std::os::unix::ffi::{OsStrExt, OsStringExt};
    let stem = pattern.file_stem().map(OsStrExt::as_bytes).unwrap_or_default();
    let is_sep = |b: u8| matches!(b, b'.' | b'_' | b'-');
    let base = match stem.iter().position(|&b| b == b'#') {
        None => stem.to_vec(),
        Some(start) => {
            let end = stem[start..]
                .iter()
                .position(|&b| b != b'#')
                .map_or(stem.len(), |n| start + n);
            let (mut lo, mut hi) = (start, end);
            if start > 0 && is_sep(stem[start - 1]) {
                lo -= 1;
            } else if start == 0 && end < stem.len() && is_sep(stem[end]) {
                hi += 1;
            }
            [&stem[..lo], &stem[hi..]].concat()
        }
    };
    let base = if base.is_empty() { b"frames".to_vec() } else { base };
    pattern.with_file_name(std::ffi::OsString::from_vec([&base[..], b".sheet.png"].concat()))
}

fn check_args(args: &RenderArgs) -> Result<Vec<f64>> {
    let out = &args.output;
    let ext_ok = out
        .extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("exr"));
    if !ext_ok {
        return Err(
            Error::usage("output must be an .exr path (PNG previews are written beside it with --png)").in_file(out),
        );
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::msg(format!("output folder {} does not exist", dir.display())).in_file(out));
    }
    let times = args.frames.times();
    let has_hash = out.file_name().is_some_and(|n| n.to_string_lossy().contains('#'));
    if times.len() > 1 && !has_hash {
        return Err(Error::usage(format!(
            "{} frames would all write one file: put #### in the output name for the frame number",
            times.len()
        ))
        .in_file(out));
    }
    // A frame's number goes into its file name and its sheet label: one
    // beyond what they write exactly would be written as another number.
    if has_hash || args.sheet {
        if let Some(t) = times.iter().find(|&&t| !frame_is_nameable(t)) {
            // Beyond 2^53 every double is whole: `.0` writes its exact digits.
            return Err(Error::usage(format!(
                "frame {t:.0} cannot be written in a file name: painterly numbers frames from \
                 -{max} to {max}",
                max = i64::MAX
            )));
        }
    }
    // Frame names keep three decimals: closer frames would overwrite each
    // other's file. Names grow with the time, so only neighbours can clash.
    if has_hash {
        let names: Vec<PathBuf> = times.iter().map(|&t| frame_path(out, t)).collect();
        if let Some(i) = names.windows(2).position(|w| w[0] == w[1]) {
            return Err(Error::usage(format!(
                "frames {} and {} would both write {}: frame names keep three decimals, use a coarser --frames step",
                times[i],
                times[i + 1],
                names[i].display()
            )));
        }
    }
    if args.sheet && times.len() > sheet::MAX_SHEET_FRAMES {
        return Err(Error::usage(format!(
            "--sheet lays out at most {} frames, not {}: use a coarser --frames step, or render without --sheet",
            sheet::MAX_SHEET_FRAMES,
            times.len()
        )));
    }
    require_file(&args.input, "input")?;
    if let Some(b) = &args.bake {
        require_file(b, "bake layer")?;
    }
    Ok(times)
}

/// Writes the root layer that sublayers the bake (if any) over the input.
pub(crate) fn write_root(dir: &Path, input: &Path, bake_layer: Option<&Path>) -> Result<PathBuf> {
    let abs = |p: &Path| -> Result<String> {
        let a = p
            .canonicalize()
            .map_err(|e| Error::msg(format!("cannot resolve path: {e}")).in_file(p))?;
        let s = a.to_string_lossy().into_owned();
        crate::usd_io::layer::check_asset_path(&s, p)?;
        Ok(s)
    };
    let (tcps, fps, start, end) = layer_timing(input)?;
    let mut meta = format!("    timeCodesPerSecond = {tcps}\n    framesPerSecond = {fps}\n");
    if let (Some(s), Some(e)) = (start, end) {
        meta.push_str(&format!("    startTimeCode = {s}\n    endTimeCode = {e}\n"));
    }
    let mut layers = Vec::new();
    if let Some(b) = bake_layer {
        layers.push(format!("        @{}@", abs(b)?));
    }
    layers.push(format!("        @{}@", abs(input)?));
    let text = format!(
        "#usda 1.0\n(\n{meta}    subLayers = [\n{}\n    ]\n)\n",
        layers.join(",\n")
    );
    let root = dir.join("render_root.usda");
    write_atomic(&root, text.as_bytes())?;
    Ok(root)
}

/// What a render did, for the summary line and `--json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RenderSummary {
    pub input: PathBuf,
    /// The EXR path pattern.
    pub output: PathBuf,
    pub frames: usize,
    pub width: usize,
    pub height: usize,
    /// BasisCurves prims and the most strokes drawn in one frame.
    pub curves: usize,
    pub strokes: usize,
    /// Mesh prims and the most triangles drawn in one frame.
    pub meshes: usize,
    pub triangles: usize,
    /// The contact sheet, when written.
    pub sheet: Option<PathBuf>,
    /// Frames with nothing in view (every pixel's alpha 0).
    pub empty_frames: Vec<f64>,
    /// Everything that looks wrong but did not stop the render.
    pub warnings: Vec<String>,
    pub seconds: f64,
    pub median_frame_seconds: f64,
}

impl RenderSummary {
    /// The summary line.
    pub fn line(&self) -> String {
        let sheet = self
            .sheet
            .as_ref()
            .map(|p| format!(", sheet {}", p.display()))
            .unwrap_or_default();
        format!(
            "rendered {} at {}x{}: {} ({}), {} ({}) -> {}{sheet} in {:.2} s (median {:.3} s/frame)",
            plural(self.frames, "frame"),
            self.width,
            self.height,
            plural(self.curves, "curves prim"),
            plural(self.strokes, "stroke"),
            plural(self.meshes, "mesh"),
            plural(self.triangles, "triangle"),
            self.output.display(),
            self.seconds,
            self.median_frame_seconds
        )
    }
}

/// Checks a `--bake` layer against the render: a bake of another input is
/// refused; a stale one (see [`check_baked_from`]) and frames outside the
/// baked range are warned about (strokes show their authored points there).
/// `opened` is the input's stage when the caller has it open.
pub(crate) fn check_bake(
    input: &Path,
    opened: Option<&StageReader>,
    bake: &Path,
    times: &[f64],
    warnings: &mut Vec<String>,
) -> Result<()> {
    let Some(p) = check_baked_from(input, opened, bake, warnings)? else {
        return Ok(());
    };
    if let Some((a, b, _)) = p.frame_range() {
        let outside: Vec<String> = times
            .iter()
            .filter(|&&t| t < a - 1e-9 || t > b + 1e-9)
            .map(|t| t.to_string())
            .collect();
        if !outside.is_empty() {
            warnings.push(format!(
                "{} outside the bake's frames {a}:{b} ({}): strokes there show their authored points",
                plural(outside.len(), "frame"),
                outside.join(", ")
            ));
        }
    }
    Ok(())
}

/// Frames for a warning: all of up to five, else the first five and a
/// count.
fn frame_list(times: &[f64]) -> String {
    let word = if times.len() == 1 { "frame" } else { "frames" };
    format!(
        "{word} {}",
        crate::words::at_most_five(times.iter().map(f64::to_string))
    )
}

/// Renders every frame.
pub fn run(args: &RenderArgs) -> Result<RenderSummary> {
    let started = Instant::now();
    let times = check_args(args)?;
    let brush = match &args.brush {
        Some(p) => Some(image_io::read_brush(p)?),
        None => None,
    };
    let mut warnings = Vec::new();
    if let Some(b) = &args.bake {
        check_bake(&args.input, None, b, &times, &mut warnings)?;
    }
    let tmp = TempDir::new()?;
    let stage = RenderStage::open(args, tmp.path())?;
    let bar = crate::log::frame_bar(!args.quiet, "rendering {pos}/{len} frames");
    bar.set_length(times.len() as u64);

    let (w, h) = (args.size.width, args.size.height);
    let style = prepare::Style::default();
    let sheet_bg = args.background.map(|c| c.0).unwrap_or(Vec3::from_array(PAPER));
    let cols = sheet::columns(times.len(), w, h);
    let factor = sheet::reduction(w, cols);
    let mut thumbs = Vec::new();
    let mut seconds = Vec::with_capacity(times.len());
    let (mut strokes, mut triangles) = (0usize, 0usize);
    let mut empty = Vec::new();
    // Curves prims that drew nothing: (first message, frames).
    let mut undrawn: BTreeMap<String, (String, Vec<f64>)> = BTreeMap::new();
    for &t in &times {
        let frame_start = Instant::now();
        let (cam, curves, meshes) = stage.at(t)?;
        // A file saved while the render reads it: no frame of the new
        // version over the old (a stat per layer file).
        stage.reader.check_unchanged()?;
        let per_prim: Vec<Vec<curves::Polyline>> = curves.par_iter().map(curves::CurvesData::polylines).collect();
        for (c, lines) in curves.iter().zip(&per_prim) {
            if let Some(why) = c.undrawn(lines) {
                undrawn.entry(c.path.clone()).or_insert((why, Vec::new())).1.push(t);
            }
        }
        let lines: Vec<curves::Polyline> = per_prim.into_iter().flatten().collect();
        let proj = camera::Projector::new(&cam, w, h);
        let fs = prepare::build_scene_of_lines(&proj, &lines, &meshes, &style);
        strokes = strokes.max(fs.strokes.len());
        triangles = triangles.max(fs.triangles.len());
        let frame = composite::render(&fs, brush.as_ref());
        if frame.rgba.iter().all(|p| p[3] <= 0.0) {
            empty.push(t);
        }
        let path = frame_path(&args.output, t);
        image_io::write_exr(&path, &frame)?;
        if args.png {
            image_io::write_png(&path.with_extension("png"), &frame, args.background.map(|c| c.0))?;
        }
        if args.sheet {
            let label = frame_path(Path::new("#"), t).to_string_lossy().into_owned();
            thumbs.push(sheet::thumbnail(&frame, factor, sheet_bg, label));
        }
        seconds.push(frame_start.elapsed().as_secs_f64());
        bar.inc(1);
    }
    bar.finish_and_clear();
    let sheet_path_out = if args.sheet {
        Some(write_sheet(&thumbs, cols, sheet_bg, &args.output)?)
    } else {
        None
    };
    if !empty.is_empty() {
        warnings.push(format!(
            "{} of {} empty: nothing in front of {} at {}",
            plural(empty.len(), "frame"),
            times.len(),
            args.camera,
            empty.iter().map(|t| t.to_string()).collect::<Vec<_>>().join(", ")
        ));
    }
    for (why, at) in undrawn.into_values() {
        warnings.push(format!("{why} at {}", frame_list(&at)));
    }
    let (curves, meshes) = stage.scene.counts();
    Ok(RenderSummary {
        input: args.input.clone(),
        output: args.output.clone(),
        frames: times.len(),
        width: w,
        height: h,
        curves,
        strokes,
        meshes,
        triangles,
        sheet: sheet_path_out,
        empty_frames: empty,
        warnings,
        seconds: started.elapsed().as_secs_f64(),
        median_frame_seconds: median(seconds),
    })
}

/// What a render reads: the input with its bake on top (the one given, or
/// one made here into `tmp` for the frames and camera asked), opened
/// through a root layer in `tmp`.
struct RenderStage {
    reader: StageReader,
    scene: RenderScene,
    root: PathBuf,
    input: PathBuf,
    /// The `--bake` layer, canonical; None when the render baked its own.
    bake: Option<PathBuf>,
    /// Keeps every frame written off the files the scene reads.
    _inputs: crate::usd_io::atomic::InputGuard,
}

impl RenderStage {
    fn open(args: &RenderArgs, tmp: &Path) -> Result<Self> {
        let mut baked_from = None;
        let bake_layer = match &args.bake {
            Some(b) => Some(b.clone()),
            None => {
                let out = tmp.join("bake.usdc");
                let opts = BakeOptions {
                    frames: Some(args.frames),
                    camera: Some(args.camera.clone()),
                    ..Default::default()
                };
                // A plain scene (no painted strokes) renders without a bake.
                bake_if_any(&args.input, &out, &opts)?.map(|(_, opened)| {
                    baked_from = Some(opened);
                    out
                })
            }
        };
        let root = write_root(tmp, &args.input, bake_layer.as_deref())?;
        let named = |e| name_input(e, &root, &args.input);
        let reader = StageReader::open(&root).map_err(named)?;
        // The input is read twice, by the bake and here: a save in between
        // would draw the old strokes over the new scene.
        if let Some(opened) = &baked_from {
            crate::usd_io::stage::check_unchanged(opened)?;
        }
        reader.require_resolved().map_err(named)?;
        // write_root resolved it: canonicalize succeeds.
        let bake = args.bake.as_ref().and_then(|b| b.canonicalize().ok());
        let scene = RenderScene::discover(&reader, &args.camera)
            .map_err(|e| name_source(e, &reader, bake.as_deref(), None))
            .map_err(named)?;
        Ok(RenderStage {
            _inputs: crate::usd_io::atomic::InputGuard::new(crate::usd_io::clips::input_files(&reader)),
            reader,
            scene,
            root,
            input: args.input.clone(),
            bake,
        })
    }

    /// The camera, curves and meshes at time `t`.
    fn at(&self, t: f64) -> Result<(camera::CameraParams, Vec<curves::CurvesData>, Vec<prepare::MeshData>)> {
        let named = |e| {
            name_input(
                name_source(e, &self.reader, self.bake.as_deref(), Some(t)),
                &self.root,
                &self.input,
            )
        };
        Ok((
            self.scene.camera_at(&self.reader, t).map_err(named)?,
            self.scene.curves_at(&self.reader, t).map_err(named)?,
            self.scene.meshes_at(&self.reader, t).map_err(named)?,
        ))
    }
}

/// A bad value the `--bake` layer gives (its opinion is the one read at
/// `time`) is the bake's to fix, and named so; what the input gives stays
/// the input's.
fn name_source(mut e: Error, reader: &StageReader, bake: Option<&Path>, time: Option<f64>) -> Error {
    if let (None, Some(bake), Some(prim), Some(attr)) = (&e.file, bake, &e.prim, &e.attribute) {
        let source = reader.value_source(prim, attr, time);
        if source.and_then(|s| s.canonicalize().ok()).as_deref() == Some(bake) {
            e.file = Some(bake.to_path_buf());
        }
    }
    e
}

/// An error in the temporary root layer (or in no file) is the input's to
/// the user, who never sees the root.
fn name_input(mut e: Error, root: &Path, input: &Path) -> Error {
    if e.file.as_deref() == Some(root) || e.file.is_none() {
        e.file = Some(input.to_path_buf());
    }
    e
}

/// The contact sheet of `thumbs`, `cols` to a row, beside the frames.
fn write_sheet(thumbs: &[sheet::Thumbnail], cols: usize, background: Vec3, output: &Path) -> Result<PathBuf> {
    // Dark labels on light backgrounds, light ones on dark.
    let luminance = background.dot(Vec3::new(0.2126, 0.7152, 0.0722));
    let ink = Vec3::splat(if luminance > 0.18 { 0.02 } else { 0.8 });
    let (sw, sh, px) = sheet::compose(thumbs, cols, background, ink);
    let sp = sheet_path(output);
    image_io::write_png8(&sp, sw, sh, 3, &px, true)?;
    Ok(sp)
}

/// The median of per-frame seconds (0 for none).
fn median(mut seconds: Vec<f64>) -> f64 {
    seconds.sort_by(f64::total_cmp);
    seconds.get(seconds.len() / 2).copied().unwrap_or(0.0)
}

/// Renders one frame of world-space curves and meshes through a camera
/// given as numbers into PNG bytes (the preview's "render" button): the same
/// projection, tessellation, shading and compositing as [`run`], no brush.
pub fn render_png(
    cam: &camera::CameraParams,
    curves: &[curves::CurvesData],
    meshes: &[prepare::MeshData],
    size: ImageSize,
    background: Option<Vec3>,
) -> Result<Vec<u8>> {
    cam.validate()
        .map_err(|e| Error::msg(format!("bad camera ({}): {}", e.attribute, e.message)))?;
    let proj = camera::Projector::new(cam, size.width, size.height);
    let scene = prepare::build_scene(&proj, curves, meshes, &prepare::Style::default());
    let frame = composite::render(&scene, None);
    let data = image_io::frame_to_srgb8(&frame, background);
    let channels = if background.is_some() { 3 } else { 4 };
    image_io::encode_png8(size.width, size.height, channels, &data, false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_warning_lists_up_to_five_frames() {
        assert_eq!(frame_list(&[3.0]), "frame 3");
        assert_eq!(frame_list(&[1.0, 2.5, 4.0, 5.0, 6.0]), "frames 1, 2.5, 4, 5, 6");
        let many: Vec<f64> = (1..=12).map(f64::from).collect();
        assert_eq!(frame_list(&many), "frames 1, 2, 3, 4, 5 and 7 more");
    }

    #[test]
    fn frame_and_sheet_paths_keep_bytes_that_are_not_utf8() {
        use std::os::unix::ffi::{OsStrExt, OsStringExt};
        let pattern = PathBuf::from(std::ffi::OsString::from_vec(b"/o/f\xfd.####.exr".to_vec()));
        assert_eq!(frame_path(&pattern, 1.0).as_os_str().as_bytes(), b"/o/f\xfd.0001.exr");
        assert_eq!(sheet_path(&pattern).as_os_str().as_bytes(), b"/o/f\xfd.sheet.png");
    }

    #[test]
    fn frame_and_sheet_paths() {
        let p = Path::new("out/fish.####.exr");
        assert_eq!(frame_path(p, 7.0), PathBuf::from("out/fish.0007.exr"));
        assert_eq!(frame_path(p, 12.5), PathBuf::from("out/fish.0012.5.exr"));
        assert_eq!(frame_path(p, -3.0), PathBuf::from("out/fish.-003.exr"));
        assert_eq!(frame_path(Path::new("a.exr"), 3.0), PathBuf::from("a.exr"));
        assert_eq!(sheet_path(p), PathBuf::from("out/fish.sheet.png"));
        assert_eq!(sheet_path(Path::new("f_##.exr")), PathBuf::from("f.sheet.png"));
        assert_eq!(sheet_path(Path::new("####.exr")), PathBuf::from("frames.sheet.png"));
    }

    #[test]
    fn sheet_names_drop_only_the_numbered_hash_run_and_its_separator() {
        // docs/render.md: the first `#` run (the one frame_path numbers) and
        // the `.`, `_` or `-` just before it go; a later run stays as written.
        let sheet = |p: &str| sheet_path(Path::new(p));
        assert_eq!(sheet("####.exr"), PathBuf::from("frames.sheet.png"));
        assert_eq!(sheet("shot_####.exr"), PathBuf::from("shot.sheet.png"));
        assert_eq!(sheet("out/fish.####.exr"), PathBuf::from("out/fish.sheet.png"));
        assert_eq!(sheet("c.####.v##.exr"), PathBuf::from("c.v##.sheet.png"));
        assert_eq!(sheet("a-##-b.exr"), PathBuf::from("a-b.sheet.png"));
        assert_eq!(sheet("take##x.exr"), PathBuf::from("takex.sheet.png"));
        assert_eq!(sheet("v#_shot_###.exr"), PathBuf::from("v_shot_###.sheet.png"));
        // Starting the name, the run takes the separator after it: no hidden
        // `.a.sheet.png`.
        assert_eq!(sheet("####.a.exr"), PathBuf::from("a.sheet.png"));
        assert_eq!(sheet("##_##.exr"), PathBuf::from("##.sheet.png"));
        // No run (one frame): the name as given.
        assert_eq!(sheet("out/still.exr"), PathBuf::from("out/still.sheet.png"));
        // The frames keep the second run too: the sheet sits beside them.
        assert_eq!(
            frame_path(Path::new("c.####.v##.exr"), 7.0),
            PathBuf::from("c.0007.v##.exr")
        );
    }

    #[test]
    fn sizes_and_colours_parse() {
        assert_eq!(
            "640x360".parse::<ImageSize>().unwrap(),
            ImageSize {
                width: 640,
                height: 360
            }
        );
        for bad in ["640", "0x10", "ax3", "99999x2"] {
            assert!(bad.parse::<ImageSize>().is_err(), "{bad}");
        }
        let c: Rgb = "#ffffff".parse().unwrap();
        assert!((c.0 - Vec3::ONE).length() < 1e-6);
        let c: Rgb = "0.5,0,1".parse().unwrap();
        assert!((c.0.x - 0.214).abs() < 1e-3);
        assert!("1,2,3".parse::<Rgb>().is_err() && "#12".parse::<Rgb>().is_err());
    }

    #[test]
    fn sizes_up_to_16384_on_either_side_and_64_megapixels_parse() {
        // The messages' own bounds: "between 1 and 16384", inclusive, and
        // 8192 x 8192 = 2^26 pixels in all.
        for (text, width, height) in [
            ("16384x4096", 16384, 4096),
            ("4096x16384", 4096, 16384),
            ("8192x8192", 8192, 8192),
        ] {
            assert_eq!(text.parse::<ImageSize>(), Ok(ImageSize { width, height }));
        }
        for bad in [
            "16385x2",
            "2x16385",
            "2x99999",
            "3x0",
            "16384x4097",
            "8193x8192",
            "16384x16384",
        ] {
            assert!(bad.parse::<ImageSize>().is_err(), "{bad}");
        }
        assert_eq!(
            "8193x8192".parse::<ImageSize>(),
            Err("\"8193x8192\" is 67117056 pixels; at most 67108864 (8192x8192) are rendered".into())
        );
    }

    #[test]
    fn frame_numbers_are_named_exactly_up_to_the_i64_range() {
        let name = |t: f64| frame_path(Path::new("f.####.exr"), t).to_string_lossy().into_owned();
        // The largest f64 below 2^63 is 2^63 − 1024: written digit for digit.
        let top = 9_223_372_036_854_774_784.0;
        assert!(frame_is_nameable(top) && frame_is_nameable(-top));
        assert_eq!(name(top), "f.9223372036854774784.exr");
        assert_eq!(name(-top), "f.-9223372036854774784.exr");
        // 2^63 and beyond would be written as i64::MAX: not nameable.
        for t in [9_223_372_036_854_775_808.0, 1e19, -1e19, 1e300] {
            assert!(!frame_is_nameable(t), "{t}");
        }
        assert!(frame_is_nameable(0.0) && frame_is_nameable(-12.5));
    }

    #[test]
    fn fractional_frames_round_to_three_decimals_and_keep_their_sign() {
        let name = |t: f64| {
            frame_path(Path::new("out/fish.####.exr"), t)
                .to_string_lossy()
                .into_owned()
        };
        assert_eq!(name(0.0), "out/fish.0000.exr");
        assert_eq!(name(0.25), "out/fish.0000.25.exr");
        assert_eq!(name(12.125), "out/fish.0012.125.exr");
        // Three decimals at most: what rounds to a whole frame is that frame.
        assert_eq!(name(1e-9), "out/fish.0000.exr");
        assert_eq!(name(0.0001), "out/fish.0000.exr");
        assert_eq!(name(12.9996), "out/fish.0013.exr");
        assert_eq!(name(12.0004), "out/fish.0012.exr");
        // Between −1 and 0 the sign stays (−0.5 and 0.5 are two files),
        // unless the frame shown is 0.
        assert_eq!(name(-0.5), "out/fish.-000.5.exr");
        assert_eq!(name(-2.75), "out/fish.-002.75.exr");
        assert_eq!(name(-0.0001), "out/fish.0000.exr");
        assert_eq!(name(-0.9996), "out/fish.-001.exr");
    }

    fn args(input: &Path, output: &str, frames: (f64, f64), sheet: bool) -> RenderArgs {
        RenderArgs {
            input: input.to_path_buf(),
            bake: None,
            camera: "/Cam".into(),
            frames: FrameRange {
                start: frames.0,
                end: frames.1,
                step: 1.0,
            },
            output: PathBuf::from(output),
            png: false,
            size: ImageSize { width: 4, height: 4 },
            sheet,
            brush: None,
            background: None,
            quiet: true,
            json: false,
        }
    }

    #[test]
    fn output_folders_and_sheet_lengths_are_checked() {
        let tmp = TempDir::new().unwrap();
        let input = tmp.path().join("in.usda");
        std::fs::write(&input, "#usda 1.0\n").unwrap();
        // A bare file name is in the current folder, which exists.
        assert_eq!(
            check_args(&args(&input, "f.####.exr", (1.0, 2.0), false)).unwrap(),
            [1.0, 2.0]
        );
        let missing = tmp.path().join("nope").join("f.####.exr");
        let err = check_args(&args(&input, missing.to_str().unwrap(), (1.0, 1.0), false)).unwrap_err();
        assert!(err.to_string().contains("does not exist"), "{err}");
        // README, Limits: a sheet holds at most 2000 frames; 2000 is allowed.
        let out = tmp.path().join("f.####.exr");
        let out = out.to_str().unwrap();
        assert_eq!(check_args(&args(&input, out, (1.0, 2000.0), true)).unwrap().len(), 2000);
        assert!(check_args(&args(&input, out, (1.0, 2001.0), true)).is_err());
    }

    #[test]
    fn frames_before_or_after_the_bake_are_warned_about() {
        let tmp = TempDir::new().unwrap();
        let input = tmp.path().join("in.usda");
        std::fs::write(&input, "#usda 1.0\n").unwrap();
        let abs = input.canonicalize().unwrap();
        let bake = tmp.path().join("bake.usda");
        let layer = format!(
            "#usda 1.0\n(\n    customLayerData = {{\n        dictionary painterly = {{\n            \
             string frames = \"3:5:1\"\n            string input = \"{}\"\n        }}\n    }}\n)\n",
            abs.display()
        );
        std::fs::write(&bake, layer).unwrap();
        let warned = |times: &[f64]| {
            let mut w = Vec::new();
            check_bake(&input, None, &bake, times, &mut w).unwrap();
            w
        };
        assert_eq!(
            warned(&[1.0, 2.0, 3.0, 4.0, 5.0]),
            ["2 frames outside the bake's frames 3:5 (1, 2): strokes there show their authored points"]
        );
        assert_eq!(
            warned(&[5.0, 6.0]),
            ["1 frame outside the bake's frames 3:5 (6): strokes there show their authored points"]
        );
        assert!(warned(&[3.0, 5.0]).is_empty());
        // Within 1e-9 of the ends (A:B:STEP arithmetic's rounding) is inside.
        assert!(warned(&[3.0 - 1e-9, 5.0 + 1e-9]).is_empty());
    }

    #[test]
    fn render_png_encodes_the_frame_at_its_size() {
        let decode = |bytes: Vec<u8>| {
            let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
            let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
            let info = reader.next_frame(&mut buf).unwrap();
            buf.truncate(info.buffer_size());
            (info.width, info.height, info.color_type, buf)
        };
        let cam = camera::CameraParams::default();
        let size = ImageSize { width: 5, height: 3 };
        // Nothing in view: every pixel is the background (linear red is sRGB
        // 255, 0, 0), or transparent without one.
        let png = render_png(&cam, &[], &[], size, Some(Vec3::new(1.0, 0.0, 0.0))).unwrap();
        let (w, h, ct, px) = decode(png);
        assert_eq!((w, h, ct), (5, 3, png::ColorType::Rgb));
        assert_eq!(px, [255, 0, 0].repeat(15));
        let (w, h, ct, px) = decode(render_png(&cam, &[], &[], size, None).unwrap());
        assert_eq!((w, h, ct), (5, 3, png::ColorType::Rgba));
        assert_eq!(px, vec![0; 60]);
    }
}
