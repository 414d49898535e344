//! The `painterly` binary: parses arguments, runs, maps failures to exit codes.

use clap::Parser;

fn main() {
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
        // A reader that went away (`painterly inspect --json | head`) ends
        // the run quietly, as SIGPIPE ends Unix tools: exit 128 + 13.
        if msg.contains("failed printing to") && msg.contains("Broken pipe") {
            std::process::exit(141);
        }
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "error: internal error{at}: {msg} (this is a bug in painterly; please report it with the input file)"
        );
    }));
    // SIGTERM/SIGINT/SIGHUP remove this run's temporary files, then exit 128+signo.
    painterly::usd_io::atomic::install_signal_cleanup();
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
