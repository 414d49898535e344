//! The composition watch (`usd_io::compose_watch`) as the binary runs it:
//! crash handlers installed, a crash or an overlong composition inside
//! `watched` ends the process with exit 1 and README's message naming the
//! file ("Limits"), and outside `watched` a fatal signal keeps its POSIX
//! default action (SIGABRT terminates the process by that signal) and
//! Rust's own stack-overflow report still runs. Each scenario ends the
//! process, so it runs in a child: this test binary re-run with
//! `PAINTERLY_COMPOSE_WATCH_CHILD=<scenario>` on the `child_scenario` test.

use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

use painterly::usd_io::compose_watch::{install_crash_handlers, timeout, watched};

const CHILD: &str = "PAINTERLY_COMPOSE_WATCH_CHILD";
const FILE: &str = "scene-under-watch.usda";

fn run_child(scenario: &str, compose_timeout: Option<&str>) -> Output {
    let mut c = Command::new(std::env::current_exe().unwrap());
    c.args(["--exact", "child_scenario", "--nocapture", "--test-threads=1"])
        .env(CHILD, scenario)
        .env_remove("PAINTERLY_COMPOSE_TIMEOUT")
        .env_remove("RUST_BACKTRACE");
    if let Some(t) = compose_timeout {
        c.env("PAINTERLY_COMPOSE_TIMEOUT", t);
    }
    // A mutated handler can leave the child hanging (a fault that re-faults
    // forever): give up after a minute, far beyond the 1-2 s it needs.
    // Its output is a few lines, well within a pipe's buffer.
    let mut child = c
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let o = child.wait_with_output().unwrap();
            panic!("scenario {scenario} hung: {}", describe(&o));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

fn describe(o: &Output) -> String {
    format!(
        "status {:?}\nstdout: {}\nstderr: {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Recursion the optimiser cannot turn into a loop: overflows any stack.
#[inline(never)]
fn recurse(n: u64) -> u64 {
    let buf = std::hint::black_box([n; 64]);
    if std::hint::black_box(n) == u64::MAX {
        return 0;
    }
    recurse(n + 1).wrapping_add(buf[7])
}

fn on_small_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

#[test]
fn child_scenario() {
    let Ok(scenario) = std::env::var(CHILD) else {
        return;
    };
    install_crash_handlers();
    let file = Path::new(FILE);
    match scenario.as_str() {
        "timeout" => println!("timeout={}", timeout().as_secs_f64()),
        "raise-segv-watched" => {
            let _ = watched(file, || {
                unsafe { libc::raise(libc::SIGSEGV) };
                Ok(())
            });
        }
        "raise-abrt-watched" => {
            let _ = watched(file, || {
                unsafe { libc::raise(libc::SIGABRT) };
                Ok(())
            });
        }
        "overflow-watched" => on_small_stack(|| {
            let _ = watched(Path::new(FILE), || Ok(recurse(0)));
        }),
        "overflow-outside" => on_small_stack(|| {
            recurse(0);
        }),
        "raise-abrt-outside" => {
            // A watched composition ran before (the handlers stay installed).
            watched(file, || Ok(())).unwrap();
            unsafe { libc::raise(libc::SIGABRT) };
        }
        "hang" => {
            let _ = watched(file, || {
                std::thread::sleep(Duration::from_secs(20));
                Ok(())
            });
        }
        "slow-but-in-time" => {
            watched(file, || {
                std::thread::sleep(Duration::from_secs(1));
                Ok(())
            })
            .unwrap();
        }
        other => panic!("unknown scenario {other}"),
    }
    println!("scenario {scenario} returned");
}

fn crashed_with_readme_message(o: &Output) {
    assert_eq!(o.status.code(), Some(1), "{}", describe(o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!(
            "error: {FILE}: openusd 0.8 crashed composing this stage (stack overflow or aborted allocation)."
        )),
        "{}",
        describe(o)
    );
    assert!(
        !String::from_utf8_lossy(&o.stdout).contains("returned"),
        "{}",
        describe(o)
    );
}

#[test]
fn a_fatal_signal_inside_a_composition_is_an_error_naming_the_file() {
    crashed_with_readme_message(&run_child("raise-segv-watched", None));
    crashed_with_readme_message(&run_child("raise-abrt-watched", None));
}

#[test]
fn a_stack_overflow_inside_a_composition_is_an_error_naming_the_file() {
    // The handler must run on the alternate stack (SA_ONSTACK): the
    // overflowed stack has no room for its frame.
    crashed_with_readme_message(&run_child("overflow-watched", None));
}

#[test]
fn sigabrt_outside_a_composition_keeps_its_default_action() {
    // POSIX: the default action of SIGABRT is to terminate the process.
    let o = run_child("raise-abrt-outside", None);
    assert_eq!(o.status.signal(), Some(libc::SIGABRT), "{}", describe(&o));
    assert!(
        !String::from_utf8_lossy(&o.stderr).contains("openusd"),
        "{}",
        describe(&o)
    );
}

#[test]
fn a_stack_overflow_outside_a_composition_gets_rusts_report() {
    // Rust's handler (kept and chained to) names the thread, then the
    // process dies of a fatal signal (its abort, raised while still on the
    // small alternate signal stack, may end as SIGSEGV).
    let o = run_child("overflow-outside", None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("has overflowed its stack"), "{}", describe(&o));
    assert!(
        matches!(o.status.signal(), Some(libc::SIGABRT | libc::SIGSEGV)),
        "{}",
        describe(&o)
    );
    assert!(!err.contains("openusd"), "{}", describe(&o));
}

#[test]
fn an_overlong_composition_is_stopped_with_readme_message() {
    let o = run_child("hang", Some("1"));
    assert_eq!(o.status.code(), Some(1), "{}", describe(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("error: {FILE}: composing this stage took longer than 1 s;")),
        "{}",
        describe(&o)
    );
    assert!(
        !String::from_utf8_lossy(&o.stdout).contains("returned"),
        "{}",
        describe(&o)
    );
}

#[test]
fn a_composition_within_the_default_limit_finishes() {
    // 1 s against README's default of 30 s.
    let o = run_child("slow-but-in-time", None);
    assert!(o.status.success(), "{}", describe(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("scenario slow-but-in-time returned"));
}

#[test]
fn compose_timeout_setting() {
    // README "Limits": 30 s unless PAINTERLY_COMPOSE_TIMEOUT=SECONDS; a
    // value that is not a positive finite number of seconds keeps 30.
    for (value, secs) in [
        (None, 30.0),
        (Some("2"), 2.0),
        (Some(" 0.25 "), 0.25),
        (Some("0"), 30.0),
        (Some("-1"), 30.0),
        (Some("inf"), 30.0),
        (Some("NaN"), 30.0),
        (Some("soon"), 30.0),
    ] {
        let o = run_child("timeout", value);
        assert!(o.status.success(), "{value:?}: {}", describe(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            out.contains(&format!("timeout={secs}\n")),
            "{value:?} should give {secs} s: {}",
            describe(&o)
        );
    }
}
