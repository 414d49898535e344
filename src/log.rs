//! `-v/--verbose`: what was read and how long each phase took, on stderr.
//!
//! One process-wide switch (the CLI sets it once); messages go to stderr so
//! `--json` output on stdout stays clean.

use std::sync::atomic::{AtomicBool, Ordering};

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
