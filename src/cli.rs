//! The `painterly` command line.
//!
//! Exit codes: 0 success; 1 bad input or a failed write (the message names the
//! file, prim and attribute); 2 bad command-line usage; 3 an internal error
//! (a bug: please report it with the input file).

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};
use indicatif::ProgressBar;

use crate::author::{self, BindOptions, Brush, BrushOptions, KeyKind, KeyOptions};
use crate::bake::{bake, BakeOptions};
use crate::error::Error;
use crate::frames::FrameRange;
use crate::inspect::inspect;
use crate::tools::Falloff;
use crate::usd_io::edit::{EditSession, EditTarget};
use crate::words::plural;

/// Painted strokes that follow rigged characters, baked into USD layers.
///
/// painterly reads a USD character (a rigged proxy Mesh plus BasisCurves
/// stroke layers marked with PainterlyStrokeLayerAPI), moves every stroke with
/// the rig (Bassett et al. 2013, stroke skinning) and writes the result as an
/// override layer to sublayer over the input.
#[derive(Debug, Parser)]
#[command(
    name = "painterly",
    version,
    about,
    long_about,
    after_help = "Exit codes: 0 success; 1 bad input or a failed write (the message names the file, prim and attribute); 2 bad command-line usage; 3 internal error (a bug).\nDocs: README.md, docs/choices.md, schemas/painterly/schema.usda."
)]
pub struct Cli {
    /// Log what was read and the time of each phase (read, bind, evaluate,
    /// write) to stderr.
    #[arg(short, long, global = true)]
    pub verbose: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Bake deformed strokes (and optionally proxies) into an override layer.
    ///
    /// Writes a new layer holding only `over` specs: every stroke layer's
    /// points (in the stroke prim's local space), extent and
    /// primvars:displayOpacity at every baked time code, plus the input's
    /// time-code range, timeCodesPerSecond, framesPerSecond, upAxis and
    /// metersPerUnit. Open the input with the bake sublayered on top to see
    /// the result. The input is never modified; a failed bake leaves no
    /// output file.
    ///
    /// Example: painterly bake fixtures/blowfish.usda -o /tmp/blowfish_bake.usdc --frames 1:48
    Bake {
        /// The painted character (.usda, .usdc or .usdz).
        input: PathBuf,
        /// The layer to write: .usdc (default choice: compact, fast) or .usda.
        #[arg(short, long)]
        output: PathBuf,
        /// Time codes to bake: A, A:B or A:B:STEP (default: the stage's
        /// startTimeCode:endTimeCode). Must lie inside the stage's range.
        #[arg(long, value_name = "A:B[:STEP]", allow_hyphen_values = true)]
        frames: Option<FrameRange>,
        /// Also write every proxy mesh's evaluated points and extent; skinned
        /// proxies get skel:skeleton blocked so viewers do not deform them twice.
        #[arg(long)]
        bake_proxy: bool,
        /// Camera prim for viewDirection axes without a source and for every
        /// view-dependent mesh (overrides their painterly:camera).
        #[arg(long, value_name = "PRIM")]
        camera: Option<String>,
        /// Write USD value clips: chunk layers of N frames in OUTPUT's
        /// `<stem>.clips/` folder, and OUTPUT (.usda) as the clip set that
        /// composes them. Memory and each file stay small whatever the range.
        #[arg(long, value_name = "N", value_parser = crate::frames::positive_count)]
        chunk: Option<usize>,
        /// With --chunk: bake only chunk K (0-based) into its chunk layer;
        /// one farm task per chunk.
        #[arg(long, value_name = "K", requires = "chunk", conflicts_with = "assemble")]
        chunk_index: Option<usize>,
        /// With --chunk: only write the clip set, after checking that every
        /// chunk layer exists and was baked from this input by this version
        /// (a farm's last step).
        #[arg(long, requires = "chunk")]
        assemble: bool,
        /// Print nothing on success (errors still go to stderr); with --json,
        /// only the JSON.
        #[arg(short, long)]
        quiet: bool,
        /// Print a JSON summary on stdout instead of the summary line.
        #[arg(long)]
        json: bool,
    },
    /// List rigs, proxies, axes, stroke layers (Table I columns), view-dependent
    /// meshes and every problem found. Exits 1 when there are problems.
    ///
    /// When nothing else is wrong, every frame of the stage's range (or of
    /// --frames) is evaluated as `bake` would (nothing is written): exit 0
    /// means that `painterly bake` with the same --frames and --camera
    /// succeeds. A stage without a time range needs --frames, as bake does.
    ///
    /// Example: painterly inspect fixtures/blowfish.usda
    Inspect {
        /// The USD file to inspect.
        input: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Check the bake `painterly bake --camera PRIM` would make (for
        /// viewDirection axes without a source, view-dependent meshes
        /// without painterly:camera).
        #[arg(long, value_name = "PRIM")]
        camera: Option<String>,
        /// Check the frames `painterly bake --frames A:B[:STEP]` would bake
        /// (default: the stage's startTimeCode:endTimeCode).
        #[arg(long, value_name = "A:B[:STEP]", allow_hyphen_values = true)]
        frames: Option<FrameRange>,
    },
    /// Bind strokes painted in a pose: store their rest positions and binding.
    ///
    /// Each point of a layer's `points` (as painted, in the pose at --time)
    /// is bound to the closest point of the posed proxy and taken back to the
    /// rest pose by the inverse of its skinning blend. Writes
    /// painterly:restPoints, painterly:bindVertices and painterly:bindWeights.
    /// Baking at --time then gives back the painted positions (a layer with
    /// position keys, which shape its bake, is refused). Without --time the
    /// rest positions a bake reads (painterly:restPoints, else `points` as
    /// proxy-local) are bound to the closest point of the rest proxy, where
    /// they are.
    ///
    /// Example: painterly bind fixtures/blowfish.usda --layer /Blowfish/Paint/Hair --time 24 --edit-layer fish_edits.usda
    Bind {
        #[command(flatten)]
        edit: EditArgs,
        /// Stroke layer prim path (repeatable; default: every layer).
        #[arg(long, value_name = "PRIM")]
        layer: Vec<String>,
        /// The pose the strokes were painted in (default: the rest pose,
        /// binding the rest positions where they are).
        #[arg(long, value_name = "T", allow_negative_numbers = true)]
        time: Option<f64>,
    },
    /// Set a pose key (configuration at --time), a time key or a sentinel.
    ///
    /// A pose key captures every axis of the layer at --time as its
    /// coordinates; it captures the layer's current rest positions (--points)
    /// unless only --opacity V is given, which keys an opacity alone (pass
    /// both to key both). --time-key sets a PainterlyTimeKey at
    /// --time instead; --sentinel a sentinel time key. A key at the same
    /// coordinates (or time) as an existing key of the same channel, or with
    /// an existing name, is refused unless --replace.
    ///
    /// Example: painterly key fixtures/blowfish.usda --layer /Blowfish/Paint/Spikes --time 15 --points --edit-layer edits.usda
    Key {
        #[command(flatten)]
        edit: EditArgs,
        /// The stroke layer prim path.
        #[arg(long, value_name = "PRIM")]
        layer: String,
        /// Time code whose configuration (or timeline position) is keyed.
        #[arg(long, value_name = "T", allow_negative_numbers = true)]
        time: f64,
        /// Key prim name, a child of the layer (default: key1, time1,
        /// sentinel1, ...): letters, digits and _, not starting with a digit.
        #[arg(long)]
        name: Option<String>,
        /// Capture the layer's current rest positions (the default, unless
        /// only --opacity is given).
        #[arg(long)]
        points: bool,
        /// Key this opacity, in [0, 1].
        #[arg(long, value_name = "V", allow_negative_numbers = true)]
        opacity: Option<f32>,
        /// Set a time key instead of a pose key.
        #[arg(long, conflicts_with = "sentinel")]
        time_key: bool,
        /// Set a sentinel time key (bounds a time-keyed region; no data).
        #[arg(long, conflicts_with_all = ["points", "opacity"])]
        sentinel: bool,
        /// Overwrite a key of the same name or at the same coordinates/time;
        /// it then holds only what this command sets (its other attributes
        /// are blocked).
        #[arg(long)]
        replace: bool,
        /// Camera for viewDirection axes without a source.
        #[arg(long, value_name = "PRIM")]
        camera: Option<String>,
    },
    /// Smudge strokes along a tool path (Bassett §3.3).
    ///
    /// Points within --radius of the path move along its unit tangent at
    /// their closest path point by --strength × falloff(distance / radius).
    ///
    /// Example: painterly smudge fixtures/blowfish.usda --layer /Blowfish/Paint/Hair --path "3,6,-2 6,6,-1.5" --radius 1 --strength 0.2 --edit-layer brush.usda
    Smudge {
        #[command(flatten)]
        edit: EditArgs,
        #[command(flatten)]
        brush: BrushArgs,
    },
    /// Expand strokes along the proxy surface normal (Bassett §3.3).
    ///
    /// Points within --radius of the path move along the proxy's normal at
    /// their bound position by --strength × falloff(distance / radius).
    ///
    /// Example: painterly expand fixtures/blowfish.usda --layer /Blowfish/Paint/Hair --path "3,6,-2 6,6,-1.5" --radius 1 --strength 0.1 --edit-layer brush.usda
    Expand {
        #[command(flatten)]
        edit: EditArgs,
        #[command(flatten)]
        brush: BrushArgs,
    },
    /// Render preview frames: linear EXR (R, G, B, A, Z), optional sRGB PNGs
    /// and a contact sheet.
    ///
    /// Composes the input with a bake layer (--bake, or the input baked on
    /// the fly), projects through the USD camera's own focal length,
    /// apertures, offsets and clipping range (image aspect conformed by
    /// keeping the horizontal aperture), draws every BasisCurves curve as an
    /// antialiased camera-facing ribbon (widths, displayColor,
    /// displayOpacity) composited back to front, and every non-guide Mesh
    /// with Rademacher's warm/cool shading and silhouette lines.
    ///
    /// Example: painterly render fixtures/apple.usda --camera /Apple/Camera --frames 1:48:4 -o /tmp/apple.####.exr --png --sheet
    Render(crate::render::RenderArgs),
    /// Live preview in the browser: drag the configuration, scrub the
    /// timeline, orbit the camera and see the paint move.
    ///
    /// Serves one page (plain WebGL2, embedded in the binary, no network
    /// needed) on 127.0.0.1 and prints its URL. Every frame the page shows is
    /// evaluated on demand by the same code as bake (one frame, nothing
    /// written): the timeline plays and scrubs, one slider per axis pins that
    /// axis to a value (pose mode) and shows its keys and their weights,
    /// "view drives" makes the orbit camera the eye of viewDirection axes and
    /// view-dependent meshes, and "render" shows `painterly render`'s frame of
    /// the current view. The input is never written.
    ///
    /// Example: painterly preview fixtures/blowfish.usda --port 0
    Preview(crate::preview::PreviewArgs),
    /// Write a layer that shows a bake over its input in usdview.
    ///
    /// The layer sublayers BAKE over INPUT (relative paths when possible) and
    /// carries the baked time range, timeCodesPerSecond, framesPerSecond,
    /// upAxis, metersPerUnit and defaultPrim, so a viewer opens it at the
    /// right frames and UsdValidation finds nothing to report. A bake made
    /// from another input is refused.
    ///
    /// Example: painterly view fixtures/blowfish.usda --bake /tmp/blowfish_bake.usdc -o /tmp/fish_view.usda
    View {
        /// The input the bake was made from.
        input: PathBuf,
        /// The layer `painterly bake` wrote (a single file or a --chunk clip set).
        #[arg(long, value_name = "LAYER")]
        bake: PathBuf,
        /// The view layer to write (.usda).
        #[arg(short, long)]
        output: PathBuf,
        /// Print nothing on success (errors still go to stderr); with --json,
        /// only the JSON.
        #[arg(short, long)]
        quiet: bool,
        /// Print a JSON summary on stdout instead of the summary line.
        #[arg(long)]
        json: bool,
    },
    /// Bake a sequence on a farm: a task per chunk, then a dependent assembly.
    ///
    /// The same chunks as `bake --chunk N`, one scheduler task each
    /// (`bake --chunk N --chunk-index K`), and a task that runs after all of
    /// them (`bake --chunk N --assemble`). Slurm jobs are submitted with
    /// sbatch; Open Job Description templates are written for `openjd run`
    /// or a farm that takes them. `farm status` tells where a bake is.
    ///
    /// Example: painterly farm submit fixtures/blowfish.usda -o /tmp/shot.usda --chunk 12 --scheduler openjd
    #[command(subcommand)]
    Farm(crate::farm::FarmCommand),
    /// Interpolation weights for keys and query points, JSON on stdin.
    ///
    /// Input: {"method": "smoothVoronoi"|"rbf"|"shepard", "radius": 1.0,
    /// "keys": [[...], ...], "points": [[...], ...]}. Output:
    /// {"weights": [[w_0, ..., w_n-1] per point]}. For tests and plots. At
    /// most 64 MiB of request and 4,000,000 weights (points × keys) in one
    /// answer.
    ///
    /// Example: echo '{"method": "smoothVoronoi", "keys": [[0], [1], [3]], "points": [[0.5], [2]]}' | painterly interpolate
    Interpolate,
}

/// Where authoring commands write.
#[derive(Debug, clap::Args)]
pub struct EditArgs {
    /// The painted character (.usda, .usdc; .usdz only with --edit-layer).
    pub input: PathBuf,
    /// Layer that receives the edits; it sublayers the input and is created
    /// when missing (an existing one must sublayer the input). Open it to see
    /// the edited character.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "in_place",
        conflicts_with = "in_place"
    )]
    pub edit_layer: Option<PathBuf>,
    /// Edit the input file itself (atomically).
    #[arg(long)]
    pub in_place: bool,
    /// Print nothing on success (errors still go to stderr); with --json,
    /// only the JSON.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print a JSON summary on stdout instead of the text line: command,
    /// input, written (the layer saved), in_place, layers (stroke layers
    /// changed), points (points bound or moved; 0 for key), key (the key
    /// prim set, key only), message (the text line).
    #[arg(long)]
    pub json: bool,
}

/// What an authoring command changed, as `--json` prints it.
#[derive(Debug, serde::Serialize)]
pub struct EditSummary {
    pub command: &'static str,
    pub input: PathBuf,
    pub written: PathBuf,
    pub in_place: bool,
    pub layers: Vec<String>,
    pub points: usize,
    pub key: Option<String>,
    pub message: String,
}

/// Options shared by smudge and expand.
#[derive(Debug, clap::Args)]
pub struct BrushArgs {
    /// The stroke layer prim path.
    #[arg(long, value_name = "PRIM")]
    pub layer: String,
    /// Tool path in world space: "X,Y,Z X,Y,Z ..." (at least two points,
    /// separated by spaces or semicolons).
    #[arg(
        long,
        value_name = "\"X,Y,Z X,Y,Z ...\"",
        required_unless_present = "path_prim",
        conflicts_with = "path_prim",
        allow_hyphen_values = true
    )]
    pub path: Option<String>,
    /// A BasisCurves prim whose first curve is the tool path.
    #[arg(long, value_name = "PRIM")]
    pub path_prim: Option<String>,
    /// Radius of influence around the path (world units, > 0).
    #[arg(long, allow_negative_numbers = true)]
    pub radius: f64,
    /// Displacement at the path (world units; negative moves the other way).
    #[arg(long, allow_negative_numbers = true)]
    pub strength: f64,
    /// Falloff of the distance normalised by the radius.
    #[arg(long, value_enum, default_value = "cubic")]
    pub falloff: FalloffArg,
    /// Apply in the pose at this time (default: the rest pose).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// Edit this key's points instead of the layer's rest points: a
    /// PainterlyPoseKey or PainterlyTimeKey child of the layer (its name,
    /// or its path).
    #[arg(long, value_name = "NAME")]
    pub key: Option<String>,
    /// Only these strokes (curve indices), e.g. 3,7-12.
    #[arg(long, value_name = "LIST")]
    pub strokes: Option<String>,
}

/// `--falloff` values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FalloffArg {
    /// 2r³ − 3r² + 1.
    Cubic,
    /// Constant within the radius.
    None,
}

fn parse_point(s: &str) -> Result<glam::DVec3, Error> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| Error::usage(format!("--path point {s:?} is not X,Y,Z")))?;
    match v.as_slice() {
        [x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) => Ok(glam::DVec3::new(*x, *y, *z)),
        [_, _, _] => Err(Error::usage(format!("--path point {s:?} is not finite"))),
        _ => Err(Error::usage(format!("--path point {s:?} is not X,Y,Z"))),
    }
}

/// `--path`: points separated by spaces or `;`, a tool path of at least two
/// distinct points (a bad value is a usage error, exit 2).
fn parse_path(s: &str) -> Result<Vec<glam::DVec3>, Error> {
    let path: Vec<glam::DVec3> = s
        .split([' ', ';'])
        .filter(|p| !p.trim().is_empty())
        .map(parse_point)
        .collect::<Result<_, _>>()?;
    if let Some(problem) = crate::tools::tool_path_problem(&path) {
        return Err(Error::usage(format!("--path {problem}")));
    }
    Ok(path)
}

fn open_session(e: &EditArgs) -> Result<EditSession, Error> {
    let target = match &e.edit_layer {
        Some(p) => EditTarget::Layer(p.clone()),
        None => EditTarget::InPlace,
    };
    EditSession::open(&e.input, &target)
}

fn run_brush(edit: &EditArgs, b: &BrushArgs, which: Brush) -> Result<EditSummary, Error> {
    let session = open_session(edit)?;
    let start = session.reader.metadata().start_time_code.unwrap_or(0.0);
    let path = match &b.path_prim {
        Some(p) => author::path_from_prim(&session.reader, p, b.time, start)?,
        None => parse_path(b.path.as_deref().unwrap_or(""))?,
    };
    let strokes = match &b.strokes {
        Some(s) => Some(crate::tools::parse_strokes(s).map_err(|m| Error::usage(format!("--strokes: {m}")))?),
        None => None,
    };
    let opts = BrushOptions {
        layer: b.layer.clone(),
        path,
        radius: b.radius,
        strength: b.strength,
        falloff: match b.falloff {
            FalloffArg::Cubic => Falloff::Cubic,
            FalloffArg::None => Falloff::None,
        },
        time: b.time,
        key: b.key.clone(),
        strokes,
    };
    let moved = author::brush(&session, which, &opts)?;
    if moved == 0 {
        // Nothing changed: say so and leave every file as it was.
        return Err(Error::prim(
            &b.layer,
            format!(
                "no point lies within --radius {} of the tool path (in the pose at {}): nothing changed, nothing written",
                b.radius,
                b.time.map_or("rest".to_string(), |t| format!("time {t}"))
            ),
        ));
    }
    let target = session.target().to_path_buf();
    session.save()?;
    let message = format!(
        "moved {} of {} -> {}",
        plural(moved, "point"),
        b.layer,
        target.display()
    );
    let command = match which {
        Brush::Smudge => "smudge",
        Brush::Expand => "expand",
    };
    Ok(summary(
        edit,
        command,
        target,
        vec![b.layer.clone()],
        moved,
        None,
        message,
    ))
}

fn summary(
    edit: &EditArgs,
    command: &'static str,
    written: PathBuf,
    layers: Vec<String>,
    points: usize,
    key: Option<String>,
    message: String,
) -> EditSummary {
    EditSummary {
        command,
        input: edit.input.clone(),
        written,
        in_place: edit.in_place,
        layers,
        points,
        key,
        message,
    }
}

fn finish(result: Result<EditSummary, Error>, edit: &EditArgs) -> i32 {
    match result {
        Ok(s) => {
            if edit.json {
                return print_json(&s, false);
            } else if !edit.quiet {
                println!("{}", s.message);
            }
            0
        }
        Err(e) => report(&e.in_file(&edit.input)),
    }
}

/// Runs a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> i32 {
    crate::log::set_verbose(cli.verbose);
    if let Err(e) = crate::usd_io::compose_watch::check_timeout_setting() {
        return report(&e);
    }
    match cli.command {
        Command::Bake {
            input,
            output,
            frames,
            bake_proxy,
            camera,
            chunk,
            chunk_index,
            assemble,
            quiet,
            json,
        } => {
            let opts = BakeOptions {
                frames,
                bake_proxy,
                camera,
                chunk,
                chunk_index,
                assemble,
                cancel: None,
            };
            run_bake(&input, &output, &opts, quiet, json)
        }
        Command::Inspect {
            input,
            json,
            camera,
            frames,
        } => run_inspect(&input, camera.as_deref(), frames, json),
        Command::Bind { edit, layer, time } => finish(run_bind(&edit, BindOptions { layers: layer, time }), &edit),
        Command::Key {
            edit,
            layer,
            time,
            name,
            points,
            opacity,
            time_key,
            sentinel,
            replace,
            camera,
        } => {
            let kind = if sentinel {
                KeyKind::Sentinel
            } else if time_key {
                KeyKind::Time
            } else {
                KeyKind::Pose
            };
            let opts = KeyOptions {
                layer,
                time,
                kind,
                name,
                // A key holds points unless it only sets an opacity (or is a sentinel).
                points: points || (opacity.is_none() && kind != KeyKind::Sentinel),
                opacity,
                replace,
                camera,
            };
            finish(run_key(&edit, opts), &edit)
        }
        Command::Smudge { edit, brush } => finish(run_brush(&edit, &brush, Brush::Smudge), &edit),
        Command::Expand { edit, brush } => finish(run_brush(&edit, &brush, Brush::Expand), &edit),
        Command::Render(args) => run_render(&args),
        Command::Preview(args) => match crate::preview::run(&args) {
            Ok(()) => 0,
            Err(e) => report(&e),
        },
        Command::View {
            input,
            bake,
            output,
            quiet,
            json,
        } => run_view(&input, &bake, &output, quiet, json),
        Command::Farm(cmd) => crate::farm::run(cmd),
        Command::Interpolate => run_interpolate(),
    }
}

/// `painterly bake`: the bake with a progress bar on a terminal, then its
/// summary line or JSON.
fn run_bake(input: &Path, output: &Path, opts: &BakeOptions, quiet: bool, json: bool) -> i32 {
    let bar = crate::log::frame_bar(!quiet && !json, "baking frame {pos}/{len}");
    let result = bake(input, output, opts, &frames_done(&bar));
    bar.finish_and_clear();
    match result {
        Ok(s) => {
            if json {
                return print_json(&s, false);
            } else if !quiet {
                // An assembly bakes nothing: it writes the clip set over the chunks.
                let done = if opts.assemble {
                    format!("assembled {}", plural(s.chunks.len(), "chunk layer"))
                } else {
                    format!("baked {}", plural(s.frames, "frame"))
                };
                let chunks = if opts.assemble || s.chunks.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", plural(s.chunks.len(), "chunk layer"))
                };
                println!(
                    "{done}: {}, {}, {}, {} -> {}{chunks} in {:.2} s",
                    plural(s.layers, "layer"),
                    plural(s.strokes, "stroke"),
                    plural(s.points, "point"),
                    plural(s.view_meshes, "view-dependent mesh"),
                    s.output.display(),
                    s.seconds
                );
            }
            0
        }
        Err(e) => report(&e),
    }
}

/// The progress callback ([`crate::bake::Progress`]) that moves `bar`.
fn frames_done(bar: &ProgressBar) -> impl Fn(usize, usize) + Sync + '_ {
    move |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    }
}

/// `painterly inspect`: exit 1 when the report lists problems. Evaluating
/// every frame of a long range takes a while: a bar shows it on a terminal.
fn run_inspect(input: &Path, camera: Option<&str>, frames: Option<FrameRange>, json: bool) -> i32 {
    let bar = crate::log::frame_bar(!json, "checking frame {pos}/{len}");
    let result = inspect(input, camera, frames, &frames_done(&bar));
    bar.finish_and_clear();
    match result {
        Ok(rep) => {
            if json {
                let printed = print_json(&rep, true);
                if printed != 0 {
                    return printed;
                }
            } else {
                print!("{}", rep.to_text());
            }
            if rep.problems.is_empty() {
                0
            } else {
                1
            }
        }
        Err(e) => report(&e),
    }
}

/// `painterly bind`: stores the closest-point binding of the chosen layers.
fn run_bind(edit: &EditArgs, opts: BindOptions) -> Result<EditSummary, Error> {
    let session = open_session(edit)?;
    let report = author::bind(&session, &opts)?;
    let target = session.target().to_path_buf();
    session.save()?;
    let n: usize = report.iter().map(|r| r.1).sum();
    let message = format!(
        "bound {} in {} -> {}",
        plural(n, "point"),
        plural(report.len(), "layer"),
        target.display()
    );
    let layers = report.into_iter().map(|r| r.0).collect();
    Ok(summary(edit, "bind", target, layers, n, None, message))
}

/// `painterly key`: adds (or replaces) one key on a layer.
fn run_key(edit: &EditArgs, opts: KeyOptions) -> Result<EditSummary, Error> {
    let session = open_session(edit)?;
    let layer = opts.layer.clone();
    let path = author::key(&session, &opts)?;
    let target = session.target().to_path_buf();
    session.save()?;
    let message = format!("set {path} -> {}", target.display());
    Ok(summary(edit, "key", target, vec![layer], 0, Some(path), message))
}

/// `painterly render`: warnings on stderr, then the summary line or JSON.
fn run_render(args: &crate::render::RenderArgs) -> i32 {
    match crate::render::run(args) {
        Ok(summary) => {
            if !args.quiet {
                for w in &summary.warnings {
                    eprintln!("warning: {w}");
                }
            }
            if args.json {
                return print_json(&summary, false);
            } else if !args.quiet {
                println!("{}", summary.line());
            }
            0
        }
        Err(e) => report(&e),
    }
}

/// `painterly view`: writes the layer that shows a bake over its input.
fn run_view(input: &Path, bake: &Path, output: &Path, quiet: bool, json: bool) -> i32 {
    match crate::usd_io::assembly::write_view_layer(input, bake, output) {
        Ok(s) => {
            if !quiet {
                for w in &s.warnings {
                    eprintln!("warning: {w}");
                }
            }
            if json {
                return print_json(&s, false);
            } else if !quiet {
                println!(
                    "wrote {}: {} over {}, frames {}:{}, defaultPrim {}",
                    s.output.display(),
                    s.bake.display(),
                    s.input.display(),
                    s.start_time_code,
                    s.end_time_code,
                    s.default_prim
                );
            }
            0
        }
        Err(e) => report(&e),
    }
}

/// `painterly interpolate`: one JSON request on stdin, its answer on stdout.
fn run_interpolate() -> i32 {
    use crate::interp::json::MAX_REQUEST_BYTES;
    let mut input = String::new();
    // One byte past the limit tells a request at the limit from a longer one.
    let mut stdin = std::io::Read::take(std::io::stdin().lock(), MAX_REQUEST_BYTES + 1);
    if let Err(e) = std::io::Read::read_to_string(&mut stdin, &mut input) {
        return report(&Error::msg(format!("cannot read stdin: {e}")));
    }
    if input.len() as u64 > MAX_REQUEST_BYTES {
        return report(&Error::msg(format!(
            "the request on stdin is longer than {} MiB; painterly interpolate reads at most that \
             (send the points in several requests)",
            MAX_REQUEST_BYTES >> 20
        )));
    }
    match crate::interp::json::run_json(&input) {
        Ok(out) => {
            println!("{out}");
            0
        }
        Err(e) => report(&Error::msg(e)),
    }
}

/// `--json` output: one document on stdout, exit 0. JSON strings are
/// Unicode, so a value that cannot be one (a file name that is not UTF-8,
/// from the stage) is an error, not an empty line with exit 0.
fn print_json(value: &impl serde::Serialize, pretty: bool) -> i32 {
    let text = if pretty {
        serde_json::to_string_pretty(value)
    } else {
        serde_json::to_string(value)
    };
    match text {
        Ok(t) => {
            println!("{t}");
            0
        }
        Err(e) => report(&Error::msg(format!(
            "cannot write the --json output: {e} (JSON names files in UTF-8)"
        ))),
    }
}

/// Why `args` cannot run with `--json`, checked before any work: every
/// file named on the command line must be UTF-8 to be named in the JSON.
pub fn json_args_problem(args: impl IntoIterator<Item = std::ffi::OsString>) -> Option<String> {
    let args: Vec<_> = args.into_iter().collect();
    if !args.iter().any(|a| a == "--json") {
        return None;
    }
    let bad = args.iter().skip(1).find(|a| a.to_str().is_none())?;
    Some(format!(
        "--json names files in UTF-8, and {} is not: rename it, or run without --json",
        bad.to_string_lossy()
    ))
}

fn report(e: &Error) -> i32 {
    eprintln!("error: {e}");
    e.exit_code()
}
