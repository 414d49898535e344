//! The `painterly` binary: parses arguments, runs, maps failures to exit codes.

use std::io::Write;

use clap::Parser;

fn main() {
    tune_malloc();
    // A bug must still end in a clear message and a non-zero exit, not a
    // Rust backtrace in a farm log.
    std::panic::set_hook(Box::new(|info| {
        // A panic inside openusd while composing is reported as an input error.
        if painterly::usd_io::compose_watch::is_active() {
            return;
        }
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        // `println!` panics when stdout or stderr cannot be written. A
        // reader that went away (`painterly inspect --json | head`) ends the
        // run quietly, as SIGPIPE ends Unix tools: exit 128 + 13. Any other
        // such failure (a full disk) is a failed write, not a bug: exit 1.
        if msg.starts_with("failed printing to") {
            // Ending the process runs no destructors: the temporaries go first.
            painterly::usd_io::atomic::remove_all_temporaries_unless_held();
            if msg.contains("Broken pipe") {
                painterly::usd_io::atomic::end_process(141);
            }
            // The work may be done already: say so.
            let written = painterly::usd_io::atomic::written_before(painterly::usd_io::atomic::published());
            // Not eprintln!: when stderr is what failed, a second panic
            // inside this hook aborts the process (SIGABRT, no message).
            let _ = writeln!(std::io::stderr(), "error: {msg}{written}");
            painterly::usd_io::atomic::end_process(1);
        }
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let _ = writeln!(
            std::io::stderr(),
            "error: internal error{at}: {msg} (this is a bug in painterly; please report it with the input file)"
        );
    }));
    // SIGTERM/SIGINT/SIGHUP remove this run's temporary files, then exit 128+signo.
    painterly::usd_io::atomic::install_signal_cleanup();
    if let Some(problem) = painterly::cli::json_args_problem(std::env::args_os()) {
        let _ = writeln!(std::io::stderr(), "error: {problem}");
        std::process::exit(2);
    }
    let cli = painterly::cli::Cli::parse();
    let code = std::panic::catch_unwind(|| {
        // The one way to reach exit code 3 on purpose: the contract tests
        // check that a bug ends in this message and code (docs/testing.md).
        if std::env::var_os("PAINTERLY_TEST_INTERNAL_ERROR").is_some() {
            panic!("PAINTERLY_TEST_INTERNAL_ERROR is set");
        }
        painterly::cli::run(cli)
    })
    .unwrap_or(3);
    std::process::exit(code);
}

/// One malloc arena for all threads. With glibc's default of one arena per
/// thread, freed frame buffers stayed cached in each, and a bake's peak RSS
/// crept up with its length though its live heap does not (heaptrack, Dog
/// bench: 28.7 MiB live at 48 frames, 29.9 MiB at 471; RSS 39 and 45 MiB,
/// 38 and 40 MiB with one arena). Frames allocate a few large buffers, so
/// the shared arena's lock costs nothing measurable. Set before any thread
/// starts; `GLIBC_TUNABLES` in the environment overrides it.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn tune_malloc() {
    if std::env::var_os("GLIBC_TUNABLES").is_some() {
        return;
    }
    // SAFETY: mallopt only sets an allocator parameter; called on the main
    // thread before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_malloc() {}
