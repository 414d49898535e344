//! openusd composition under watch: what happens when openusd 0.8 itself
//! fails on a stage.
//!
//! The composition guard ([`super::guard`]) refuses what can be recognised
//! up front (deep namespaces and nesting, inherit/specialize cycles), but
//! openusd 0.8's prim indexer also overflows its stack or runs for minutes
//! on other arc combinations. Measured here on 150 random hierarchies (up
//! to 6 inherit/specialize/internal-reference arcs among 7 prims): the guard
//! refused 6, openusd crashed or ran over 10 s on 28 more; usd-core reports
//! arc cycles (`Pcp.ErrorArcCycle`) on 22 of those 28, cannot parse 2, and
//! composes 4 cleanly (e.g. `/C` inheriting `/B/Y` and specializing `/B`,
//! with a child, and a prim under `/A` inheriting `/C`: `OPENUSD_CRASH` in
//! `python_tests/test_reliability.py`). Recognising them up front means
//! re-implementing Pcp, so instead, while [`watched`] runs a composition:
//!
//! - a panic inside openusd becomes an error (exit 1) naming the file;
//! - a stack overflow or an aborted allocation (SIGSEGV, SIGBUS, SIGABRT)
//!   prints an error naming the file and exits 1 (the handler only writes a
//!   prepared message and calls `_exit`, which is async-signal-safe);
//! - a composition running longer than `PAINTERLY_COMPOSE_TIMEOUT` seconds
//!   (default [`DEFAULT_TIMEOUT_S`]) is stopped with an error, temporaries
//!   removed.
//!
//! Outside [`watched`] the previous handlers (Rust's stack-overflow report)
//! run as before. The handlers are installed by
//! [`super::atomic::install_signal_cleanup`] (the binary's `main`); a
//! library user who does not call it keeps openusd's behaviour.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex, Once};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// Seconds a stage may take to compose before painterly gives up (below
/// the 60 s a farm or the fuzz harness counts as a hang).
pub const DEFAULT_TIMEOUT_S: u64 = 30;

thread_local! {
    /// The message the crash handler writes for a watched composition on
    /// this thread (leaked bytes, null when none runs). Const-initialised and
    /// without a destructor, so the signal handler may read it.
    static MSG: Cell<(*const u8, usize)> = const { Cell::new((std::ptr::null(), 0)) };
}

/// Deadlines of the running watched compositions, by ticket.
struct Watchdog {
    deadlines: Mutex<BTreeMap<u64, (Instant, String)>>,
    wake: Condvar,
}

fn watchdog() -> &'static Watchdog {
    static W: std::sync::OnceLock<Watchdog> = std::sync::OnceLock::new();
    W.get_or_init(|| {
        let _ = std::thread::Builder::new()
            .name("painterly-compose-watch".into())
            .spawn(watch_loop);
        Watchdog {
            deadlines: Mutex::new(BTreeMap::new()),
            wake: Condvar::new(),
        }
    })
}

fn watch_loop() {
    let w = watchdog();
    let mut map = w.deadlines.lock().unwrap_or_else(|e| e.into_inner());
    loop {
        let first = map.values().min_by_key(|(at, _)| *at).cloned();
        match first {
            None => map = w.wake.wait(map).unwrap_or_else(|e| e.into_inner()),
            Some((at, msg)) => {
                let now = Instant::now();
                if now < at {
                    map = w.wake.wait_timeout(map, at - now).unwrap_or_else(|e| e.into_inner()).0;
                } else {
                    // Not eprintln!: it panics when stderr cannot be
                    // written, and this thread would end without the exit.
                    let _ = writeln!(std::io::stderr(), "{msg}");
                    super::atomic::remove_all_temporaries();
                    super::atomic::end_process(1);
                }
            }
        }
    }
}

/// Refuses a `PAINTERLY_COMPOSE_TIMEOUT` that is set but is no positive
/// number of seconds (a usage error: the CLI checks it before any work),
/// rather than waiting the default while the user believes otherwise.
pub fn check_timeout_setting() -> Result<(), crate::error::Error> {
    timeout_setting().map(|_| ())
}

/// `PAINTERLY_COMPOSE_TIMEOUT` in seconds when set (None when not); the one
/// reading of it, for the CLI's check and for [`timeout`].
fn timeout_setting() -> Result<Option<f64>, crate::error::Error> {
    let Some(v) = std::env::var_os("PAINTERLY_COMPOSE_TIMEOUT") else {
        return Ok(None);
    };
    let text = v.to_string_lossy();
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Ok(Some(s)),
        _ => Err(crate::error::Error::usage(format!(
            "PAINTERLY_COMPOSE_TIMEOUT={text:?} is not a positive number of seconds"
        ))),
    }
}

/// The composition time limit: `PAINTERLY_COMPOSE_TIMEOUT` (seconds) or the
/// default (also for a value that is no positive number: the library runs
/// on, the CLI refuses it first with [`check_timeout_setting`]).
pub fn timeout() -> Duration {
    let s = timeout_setting().ok().flatten().unwrap_or(DEFAULT_TIMEOUT_S as f64);
    Duration::from_secs_f64(s.min(1e9))
}

/// Whether a watched composition is running on this thread (the panic hook
/// stays quiet then: the panic is reported as an error by [`watched`]).
pub fn is_active() -> bool {
    MSG.try_with(|m| !m.get().0.is_null()).unwrap_or(false)
}

static HANDLERS: Once = Once::new();
const FATAL: [libc::c_int; 3] = [libc::SIGSEGV, libc::SIGBUS, libc::SIGABRT];

struct Old(std::cell::UnsafeCell<[Option<libc::sigaction>; 3]>);
// Written once in `install_crash_handlers` before any handler can run.
unsafe impl Sync for Old {}
static OLD: Old = Old(std::cell::UnsafeCell::new([None, None, None]));

extern "C" fn on_fatal(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    // A read past the end of a mapped input that was cut short meanwhile
    // (rewritten in place, `cp` over it): not a crash of openusd's.
    if sig == libc::SIGBUS && !info.is_null() {
        // SAFETY: the siginfo the kernel passed for this signal.
        let (code, addr) = unsafe { ((*info).si_code, (*info).si_addr() as usize) };
        // Besides the executable and its libraries, the process maps only
        // the inputs `regular` maps (package entries are read): a bus
        // error past a mapped file's end is taken for one of them.
        if code == libc::BUS_ADRERR {
            let path = super::regular::mapped_file_at(addr).unwrap_or(super::atomic::UNKNOWN_FILE.as_ptr());
            super::atomic::input_truncated(path);
        }
    }
    let (p, n) = MSG.try_with(|m| m.get()).unwrap_or((std::ptr::null(), 0));
    if !p.is_null() {
        // SAFETY: write(2) and _exit(2) are async-signal-safe; the message
        // bytes stay allocated while this thread's MSG points at them.
        unsafe {
            libc::write(2, p as *const libc::c_void, n);
            libc::_exit(1);
        }
    }
    let Some(k) = FATAL.iter().position(|&s| s == sig) else {
        return;
    };
    // SAFETY: OLD was fully written before this handler was installed.
    let old = unsafe { (*OLD.0.get())[k] };
    match old {
        Some(old) if old.sa_sigaction != libc::SIG_DFL && old.sa_sigaction != libc::SIG_IGN => {
            // SAFETY: chaining to the handler that was installed before ours,
            // with the arguments the kernel gave us.
            unsafe {
                if old.sa_flags & libc::SA_SIGINFO != 0 {
                    let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                        std::mem::transmute(old.sa_sigaction);
                    f(sig, info, ctx);
                } else {
                    let f: extern "C" fn(libc::c_int) = std::mem::transmute(old.sa_sigaction);
                    f(sig);
                }
            }
        }
        _ => {
            // Default action: reset and re-raise (a SIGSEGV re-faults on return).
            // SAFETY: signal(2) and raise(3) are async-signal-safe.
            unsafe {
                libc::signal(sig, libc::SIG_DFL);
                if sig == libc::SIGABRT {
                    libc::raise(sig);
                }
            }
        }
    }
}

/// Installs the crash handlers (once). Rust's own stack-overflow handler is
/// kept and called outside watched compositions.
pub fn install_crash_handlers() {
    HANDLERS.call_once(|| {
        // SAFETY: plain sigaction(2) calls; OLD is written before the first
        // handler is installed and never again.
        unsafe {
            let olds = &mut *OLD.0.get();
            for (k, &sig) in FATAL.iter().enumerate() {
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(sig, std::ptr::null(), &mut old) == 0 {
                    olds[k] = Some(old);
                }
            }
            for &sig in &FATAL {
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = on_fatal as *const () as usize;
                act.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
                libc::sigemptyset(&mut act.sa_mask);
                libc::sigaction(sig, &act, std::ptr::null_mut());
            }
        }
    });
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown".into())
}

/// Runs `f` (opening and composing `file` with openusd) under watch: panics
/// become errors, crashes and overlong compositions end the process with an
/// error naming the file (exit 1). Compositions on several threads are each
/// watched; a nested call keeps the outer watch.
pub fn watched<T>(file: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    if is_active() {
        return f();
    }
    let msg = format!(
        "error: {}: openusd 0.8 crashed composing this stage (stack overflow or aborted allocation). \
         Its composition arcs are beyond what openusd can compose (e.g. recursive inherits, specializes \
         or references, which usd-core reports as arc cycles), or composing it needs more memory than \
         the process may use (ulimit -v).\n",
        file.display()
    );
    let bytes: Box<[u8]> = msg.into_bytes().into_boxed_slice();
    MSG.with(|m| m.set((bytes.as_ptr(), bytes.len())));
    static TICKET: AtomicU64 = AtomicU64::new(0);
    let ticket = TICKET.fetch_add(1, Ordering::Relaxed);
    let limit = timeout();
    if HANDLERS.is_completed() {
        let w = watchdog();
        let text = format!(
            "error: {}: composing this stage took longer than {} s; openusd 0.8 is slow on some stages: \
             recursive inherits/specializes/references (exponential), thousands of sublayers, namespaces \
             composed hundreds of prims deep through references, or tens of thousands of properties on one \
             prim of a .usda (a .usdc reads fast) (set PAINTERLY_COMPOSE_TIMEOUT=SECONDS to wait longer)",
            file.display(),
            limit.as_secs_f64()
        );
        w.deadlines
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(ticket, (Instant::now() + limit, text));
        w.wake.notify_all();
    }
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    if HANDLERS.is_completed() {
        watchdog()
            .deadlines
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&ticket);
    }
    MSG.with(|m| m.set((std::ptr::null(), 0)));
    drop(bytes);
    match result {
        Ok(r) => r,
        Err(p) => Err(Error::msg(format!(
            "openusd 0.8 failed reading this stage: {}",
            panic_message(p.as_ref())
        ))
        .in_file(file)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_inside_becomes_an_error_naming_the_file() {
        let e = watched(Path::new("x.usda"), || -> Result<()> { panic!("boom") }).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(Path::new("x.usda")));
        assert!(e.message.contains("boom"), "{e}");
        assert!(!is_active());
    }

    #[test]
    fn watches_nest_and_run_on_several_threads() {
        let inner = watched(Path::new("a.usda"), || {
            assert!(is_active());
            watched(Path::new("b.usda"), || Ok(7))
        });
        assert_eq!(inner.unwrap(), 7);
        assert!(!is_active());
        let handles: Vec<_> = (0..4)
            .map(|i| {
                std::thread::spawn(move || {
                    (0..200)
                        .map(|k| watched(Path::new("t.usda"), || Ok(i * 1000 + k)).unwrap())
                        .sum::<i32>()
                })
            })
            .collect();
        for (i, h) in handles.into_iter().enumerate() {
            let i = i as i32;
            assert_eq!(h.join().unwrap(), (0..200).map(|k| i * 1000 + k).sum::<i32>());
        }
    }
}
