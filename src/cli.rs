//! The `painterly` command line.
//!
//! Exit codes: 0 success; 1 bad input or a failed write (the message names the
//! file, prim and attribute); 2 bad command-line usage; 3 an internal error
//! (a bug: please report it with the input file).

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use crate::bake::{bake, BakeOptions};
use crate::error::Error;
use crate::frames::FrameRange;
use crate::inspect::inspect;

/// Painted strokes that follow rigged characters, baked into USD layers.
///
/// painterly reads a USD character (a rigged proxy Mesh plus BasisCurves
/// stroke layers marked with PainterlyStrokeLayerAPI), moves every stroke with
/// the rig (Bassett et al. 2013, stroke skinning) and writes the result as an
/// override layer to sublayer over the input.
#[derive(Debug, Parser)]
#[command(name = "painterly", version, about, long_about)]
pub struct Cli {
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
    /// time-code range, timeCodesPerSecond, upAxis and metersPerUnit. Open the
    /// input with the bake sublayered on top to see the result. The input is
    /// never modified; a failed bake leaves no output file.
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
        #[arg(long, value_name = "A:B[:STEP]")]
        frames: Option<FrameRange>,
        /// Also write every proxy mesh's evaluated points and extent; skinned
        /// proxies get skel:skeleton blocked so viewers do not deform them twice.
        #[arg(long)]
        bake_proxy: bool,
        /// Camera prim for viewDirection axes without a source and for
        /// view-dependent meshes without painterly:camera.
        #[arg(long, value_name = "PRIM")]
        camera: Option<String>,
        /// Print nothing on success.
        #[arg(short, long)]
        quiet: bool,
        /// Print a JSON summary on stdout instead of the summary line.
        #[arg(long)]
        json: bool,
    },
    /// List rigs, proxies, axes, stroke layers (Table I columns), view-dependent
    /// meshes and every problem found. Exits 1 when there are problems.
    ///
    /// Example: painterly inspect fixtures/blowfish.usda
    Inspect {
        /// The USD file to inspect.
        input: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Interpolation weights for keys and query points, JSON on stdin.
    ///
    /// Input: {"method": "smoothVoronoi"|"rbf"|"shepard", "radius": 1.0,
    /// "keys": [[...], ...], "points": [[...], ...]}. Output:
    /// {"weights": [[w_0, ..., w_n-1] per point]}. For tests and plots.
    #[command(hide = true)]
    Interpolate,
}

/// Runs a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> i32 {
    match cli.command {
        Command::Bake {
            input,
            output,
            frames,
            bake_proxy,
            camera,
            quiet,
            json,
        } => {
            let show_bar = !quiet && !json && std::io::stderr().is_terminal();
            let bar = ProgressBar::hidden();
            if show_bar {
                bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                bar.set_style(
                    ProgressStyle::with_template(
                        "{spinner} baking {pos}/{len} frames [{bar:30}] {elapsed} (eta {eta})",
                    )
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
                );
            }
            let mut progress = |done: usize, total: usize| {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            };
            let opts = BakeOptions {
                frames,
                bake_proxy,
                camera,
            };
            let result = bake(&input, &output, &opts, &mut progress);
            bar.finish_and_clear();
            match result {
                Ok(s) => {
                    if json {
                        println!("{}", serde_json::to_string(&s).unwrap_or_default());
                    } else if !quiet {
                        println!(
                            "baked {} frames: {} layers, {} strokes, {} points -> {} in {:.2} s",
                            s.frames,
                            s.layers,
                            s.strokes,
                            s.points,
                            s.output.display(),
                            s.seconds
                        );
                    }
                    0
                }
                Err(e) => report(&e),
            }
        }
        Command::Inspect { input, json } => match inspect(&input) {
            Ok(rep) => {
                if json {
                    println!("{}", serde_json::to_string_pretty(&rep).unwrap_or_default());
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
        },
        Command::Interpolate => {
            let mut input = String::new();
            if let Err(e) = std::io::Read::read_to_string(&mut std::io::stdin(), &mut input) {
                return report(&Error::msg(format!("cannot read stdin: {e}")));
            }
            match crate::interp::json::run_json(&input) {
                Ok(out) => {
                    println!("{out}");
                    0
                }
                Err(e) => report(&Error::msg(e)),
            }
        }
    }
}

fn report(e: &Error) -> i32 {
    eprintln!("error: {e}");
    1
}
