//! What painterly says on stderr: `-v/--verbose` (what was read and how
//! long each phase took) and the bar of frames done on long commands.
//!
//! One process-wide switch (the CLI sets it once); messages go to stderr so
//! `--json` output on stdout stays clean.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

static VERBOSE: AtomicBool = AtomicBool::new(false);

/// Turns verbose logging on or off.
pub fn set_verbose(on: bool) {
    VERBOSE.store(on, Ordering::Relaxed);
}

/// Whether verbose logging is on.
pub fn enabled() -> bool {
    VERBOSE.load(Ordering::Relaxed)
}

/// Logs a line to stderr when `--verbose` is on.
#[macro_export]
macro_rules! vlog {
    ($($arg:tt)*) => {
        if $crate::log::enabled() {
            eprintln!("painterly: {}", format!($($arg)*));
        }
    };
}

/// A bar of frames done on stderr, drawn only when `show` and stderr is a
/// terminal: piped output and logs stay clean. `label` is the bar's words,
/// an indicatif template such as `"baking frame {pos}/{len}"`; the spinner,
/// the bar and the times go around it.
pub fn frame_bar(show: bool, label: &str) -> ProgressBar {
    let bar = ProgressBar::hidden();
    if show && std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(&format!("{{spinner}} {label} [{{bar:30}}] {{elapsed}} (eta {{eta}})"))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
    }
    bar
}
