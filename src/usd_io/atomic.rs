//! Every file painterly writes goes through here: bakes, edit layers, the
//! scratch header of a new edit layer, rendered EXR/PNG frames and the
//! render's temporary folder.
//!
//! A write goes to a temporary sibling of the target, named
//! `.<name>.painterly-<host>-<pid>.tmp`, and is renamed into place once
//! complete, so readers and failed runs never see a partial file. Live
//! temporaries are registered here so that:
//!
//! - a failed write removes its temporary;
//! - SIGTERM, SIGINT and SIGHUP (farm schedulers stop tasks with SIGTERM)
//!   remove every registered temporary and exit with 128 + the signal number;
//! - after a `kill -9`, the next painterly run writing into the same folder
//!   removes temporaries whose process no longer exists. The host name in
//!   the temporary's name keeps a run from touching another machine's live
//!   files on a shared (NFS) folder; the check reads `/proc`, so it runs on
//!   Linux only.
//!
//! SIGXFSZ is caught too, so a write past `ulimit -f` fails with an error
//! (EFBIG) that is reported and cleaned up instead of killing the process.

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard, Once, OnceLock};

use crate::error::{Error, Result};

/// Marker in every temporary's name, before `<host>-<pid>`.
const MARK: &str = ".painterly-";
/// Suffix of a temporary file.
const TMP_SUFFIX: &str = ".tmp";
/// Suffix of a scratch layer (openusd picks the format by extension).
const SCRATCH_SUFFIX: &str = ".scratch.usda";
/// Prefix of a render's temporary folder in the system temp dir.
const RENDER_DIR_PREFIX: &str = "painterly-render-";

/// Registered live temporaries (files and folders), and the folders already
/// swept for stale ones.
struct Registry {
    /// The temporaries this process is writing, removed on a signal and
    /// never swept, each with, for a file, a handle holding its `flock`: a
    /// process whose pid /proc cannot see (another PID namespace of this
    /// host name, as containers on the host network are) still shows it is
    /// alive. Folders have none. A map: a chunked bake registers a
    /// temporary per chunk until it publishes them all.
    live: HashMap<PathBuf, Option<File>>,
    swept: HashSet<PathBuf>,
    /// How many files this process has renamed into place, and the first:
    /// a failure after them (a report that cannot be printed) says so.
    published: usize,
    first_published: Option<PathBuf>,
}

impl Registry {
    fn holds(&self, p: &Path) -> bool {
        self.live.contains_key(p)
    }

    fn remove_all(&mut self) {
        for (p, _lock) in self.live.drain() {
            remove_any(&p);
        }
    }
}

fn registry_mutex() -> &'static Mutex<Registry> {
    static REG: OnceLock<Mutex<Registry>> = OnceLock::new();
    REG.get_or_init(|| {
        Mutex::new(Registry {
            live: HashMap::new(),
            swept: HashSet::new(),
            published: 0,
            first_published: None,
        })
    })
}

fn registry() -> MutexGuard<'static, Registry> {
    registry_mutex()
        .lock()
        // A panic while holding the lock leaves the list intact; keep using it.
        .unwrap_or_else(|e| e.into_inner())
}

/// This machine's name as used in temporaries (`[A-Za-z0-9._]` only).
fn host() -> &'static str {
    static HOST: OnceLock<String> = OnceLock::new();
    HOST.get_or_init(|| {
        let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| std::env::var("HOSTNAME"))
            .unwrap_or_default();
        let clean: String = raw
            .trim()
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '.' { c } else { '_' })
            .collect();
        if clean.is_empty() {
            "localhost".into()
        } else {
            clean
        }
    })
}

/// Installs the SIGTERM/SIGINT/SIGHUP cleanup and catches SIGXFSZ. Called
/// once from `main`; harmless to call again. Library users who install their
/// own handlers can skip it: temporaries are still removed on every error.
pub fn install_signal_cleanup() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        super::compose_watch::install_crash_handlers();
        use signal_hook::consts::signal::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};
        // A handler that only sets a flag: write() then fails with EFBIG.
        static FSIZE: AtomicBool = AtomicBool::new(false);
        let _ = signal_hook::flag::register(SIGXFSZ, &FSIZE);
        // A mask inherited through exec (a job runner's thread that
        // blocked SIGTERM) would keep every signal below from ever
        // arriving: unblocked here, before any other thread starts.
        // SAFETY: sigset operations on a local set; pthread_sigmask on the
        // calling thread.
        #[allow(unsafe_code)]
        unsafe {
            let mut set: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut set);
            for sig in [SIGTERM, SIGINT, SIGHUP] {
                libc::sigaddset(&mut set, sig);
            }
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        }
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGTERM, SIGINT, SIGHUP]) else {
            return;
        };
        let spawned = std::thread::Builder::new()
            .name("painterly-signals".into())
            .spawn(move || {
                if let Some(sig) = signals.forever().next() {
                    let truncated = TRUNCATED.load(Ordering::SeqCst);
                    // Let a publication under way finish (see
                    // [`hold_signals`]), and hold off any other until exit;
                    // after a bus error not for long: the thread that
                    // faulted never goes on, and may hold one.
                    let (holds, done) = signal_holds();
                    let mut n = holds.lock().unwrap_or_else(|e| e.into_inner());
                    while *n > 0 {
                        if truncated.is_null() {
                            n = done.wait(n).unwrap_or_else(|e| e.into_inner());
                        } else {
                            let wait = std::time::Duration::from_secs(2);
                            match done.wait_timeout(n, wait) {
                                Ok((g, t)) if !t.timed_out() => n = g,
                                _ => break,
                            }
                        }
                    }
                    if !truncated.is_null() {
                        report_truncated(truncated);
                    }
                    // Holding the lock until exit: no temporary can be created
                    // or renamed after the sweep.
                    let mut reg = registry();
                    reg.remove_all();
                    // Not eprintln!: with stderr unwritable (a full log
                    // disk, a closed pipe) it panics, and the panic hook
                    // would wait for the registry this thread holds.
                    let _ = writeln!(
                        std::io::stderr(),
                        "painterly: stopped by signal {sig}; temporary files removed"
                    );
                    end_process(128 + sig);
                }
            });
        SIGNAL_THREAD.store(spawned.is_ok(), Ordering::SeqCst);
    });
}

/// Whether the signal thread runs (it reports [`input_truncated`]).
static SIGNAL_THREAD: AtomicBool = AtomicBool::new(false);

/// The path of a mapped input that shrank under a read (a bus error), set
/// by [`input_truncated`] for the signal thread.
static TRUNCATED: std::sync::atomic::AtomicPtr<libc::c_char> = std::sync::atomic::AtomicPtr::new(std::ptr::null_mut());

/// What [`input_truncated`] gets for a mapping whose file is not known.
pub(crate) const UNKNOWN_FILE: &std::ffi::CStr = c"";

/// Called from the bus-error handler when a read met the end of a mapped
/// input file (`path`, NUL-terminated, or [`UNKNOWN_FILE`]) that was cut
/// short while mapped: the signal thread removes this run's temporaries and
/// ends the process with exit 1 and an error naming the file; this thread
/// waits for that, 5 s at most. Only async-signal-safe calls.
pub(crate) fn input_truncated(path: *const libc::c_char) -> ! {
    TRUNCATED.store(path.cast_mut(), Ordering::SeqCst);
    // SAFETY: kill, getpid, nanosleep, write and _exit are
    // async-signal-safe.
    #[allow(unsafe_code)]
    unsafe {
        if SIGNAL_THREAD.load(Ordering::SeqCst) {
            libc::kill(libc::getpid(), libc::SIGTERM);
            let tenth = libc::timespec {
                tv_sec: 0,
                tv_nsec: 100_000_000,
            };
            for _ in 0..50 {
                libc::nanosleep(&tenth, std::ptr::null_mut());
            }
        }
        // No signal thread, or it did not end the process: without
        // removing temporaries (the next run does).
        let m = b"error: an input file was cut short while painterly read it (rewritten in place during this run?); run again once it is saved\n";
        libc::write(2, m.as_ptr().cast(), m.len());
        libc::_exit(1);
    }
}

/// The signal thread's end after [`input_truncated`]: temporaries removed,
/// the error, exit 1.
fn report_truncated(path: *const libc::c_char) -> ! {
    // SAFETY: a NUL-terminated path leaked by `regular::note_mapping`, or
    // UNKNOWN_FILE.
    #[allow(unsafe_code)]
    let path = unsafe { std::ffi::CStr::from_ptr(path) };
    let path = Path::new(std::ffi::OsStr::from_bytes(path.to_bytes()));
    // Held until exit, as the signal path does: a writer thread going on
    // cannot create a temporary after the sweep.
    let held = registry_for_exit();
    let written = written_before(match &held {
        Some(reg) => (reg.published, reg.first_published.clone()),
        None => published(),
    });
    let file = if path.as_os_str().is_empty() {
        "an input file".to_string()
    } else {
        format!("{}", path.display())
    };
    let _ = writeln!(
        std::io::stderr(),
        "error: {file}: was cut short while painterly read it (rewritten in place during this run?): what was \
         read is not what the file now holds; run again once it is saved{written}",
    );
    end_process(1)
}

/// Ends the process now with `code`, from a thread other than the one
/// running `main` or from a hook: the signal thread, the composition
/// watchdog, the panic hook. Not `std::process::exit`: the runtime cleanup
/// it runs first unmaps the main thread's alternate signal stack, and the
/// main thread may be running a signal handler on it (waiting in the
/// bus-error handler for the cut-short report): it then died of SIGSEGV
/// after the message, 4 runs in 1,000. Nothing is left to flush: stderr is
/// unbuffered, and a run ended so has no stdout worth keeping.
pub fn end_process(code: i32) -> ! {
    // SAFETY: _exit(2) ends the process at once.
    #[allow(unsafe_code)]
    unsafe {
        libc::_exit(code)
    }
}

/// The registry, its temporaries removed, for a thread about to end the
/// process (held until exit, no temporary is made after the sweep); None
/// when another thread held it for half a second (a thread that faulted,
/// or the panicking one, may hold it for ever).
fn registry_for_exit() -> Option<MutexGuard<'static, Registry>> {
    let deadline = std::time::Instant::now() + std::time::Duration::from_millis(500);
    loop {
        match registry_mutex().try_lock() {
            Ok(mut reg) => {
                reg.remove_all();
                return Some(reg);
            }
            Err(std::sync::TryLockError::Poisoned(e)) => {
                let mut reg = e.into_inner();
                reg.remove_all();
                return Some(reg);
            }
            Err(std::sync::TryLockError::WouldBlock) if std::time::Instant::now() < deadline => {
                std::thread::sleep(std::time::Duration::from_millis(5))
            }
            Err(std::sync::TryLockError::WouldBlock) => return None,
        }
    }
}

/// The count of [`SignalHold`]s alive, and the signal it went to zero.
fn signal_holds() -> &'static (Mutex<usize>, std::sync::Condvar) {
    static HOLDS: (Mutex<usize>, std::sync::Condvar) = (Mutex::new(0), std::sync::Condvar::new());
    &HOLDS
}

/// While alive, a SIGTERM/SIGINT/SIGHUP waits before it cleans up and
/// exits: for renames that publish several files as one (a chunked bake's
/// chunks and clip set), which a signal between two of them would leave
/// half old, half new.
pub struct SignalHold(());

/// Starts a [`SignalHold`]; blocks if a signal is already being handled
/// (the process is about to exit).
pub fn hold_signals() -> SignalHold {
    let (holds, _) = signal_holds();
    *holds.lock().unwrap_or_else(|e| e.into_inner()) += 1;
    SignalHold(())
}

impl Drop for SignalHold {
    fn drop(&mut self) {
        let (holds, done) = signal_holds();
        let mut n = holds.lock().unwrap_or_else(|e| e.into_inner());
        *n -= 1;
        done.notify_all();
    }
}

/// Checks that a write could replace `target` (not a folder, and see
/// [`check_replaceable`]), for writes that must all succeed or none start.
pub fn check_target(target: &Path) -> Result<()> {
    let target = &through_links(target);
    if target.is_dir() {
        return Err(Error::msg("is a folder, not a file").in_file(target));
    }
    check_replaceable(target).map(drop)
}

/// Removes every registered temporary (before an exit that skips destructors).
pub fn remove_all_temporaries() {
    registry().remove_all();
}

/// [`remove_all_temporaries`] for a panic hook, which must not wait for
/// ever: the registry may be held by the panicking thread itself, or by the
/// signal thread, which removes them and exits. Waits a moment at most.
pub fn remove_all_temporaries_unless_held() {
    drop(registry_for_exit());
}

fn remove_any(p: &Path) {
    if p.is_dir() {
        let _ = std::fs::remove_dir_all(p);
    } else {
        let _ = std::fs::remove_file(p);
    }
}

fn dir_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// The temporary sibling of `path` with `suffix`, for this process.
fn temp_path(path: &Path, suffix: &str) -> Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::msg("output path has no file name").in_file(path))?
        .to_string_lossy();
    let tail = format!("{MARK}{}-{}{suffix}", host(), std::process::id());
    // Keep within the usual 255-byte name limit.
    let room = 255usize.saturating_sub(tail.len() + 1);
    if name.len() <= room {
        return Ok(dir_of(path).join(format!(".{name}{tail}")));
    }
    // A cut name loses its end, which is what tells chunks (`shot.0000.1-5`,
    // `shot.0001.6-10`) apart: a digest of the whole name keeps them distinct.
    let digest = {
        use sha2::{Digest, Sha256};
        let d = Sha256::digest(path.file_name().unwrap_or_default().as_encoded_bytes());
        d[..8].iter().map(|b| format!("{b:02x}")).collect::<String>()
    };
    let mut keep = room.saturating_sub(digest.len() + 1);
    while !name.is_char_boundary(keep) {
        keep -= 1;
    }
    Ok(dir_of(path).join(format!(".{}~{digest}{tail}", &name[..keep])))
}

/// `(host, pid)` of a temporary's file name, if it is one of ours.
fn parse_temp_name(name: &str) -> Option<(&str, u32)> {
    let name = name.strip_prefix('.')?;
    let rest = name
        .strip_suffix(TMP_SUFFIX)
        .or_else(|| name.strip_suffix(SCRATCH_SUFFIX))?;
    let (_, owner) = rest.rsplit_once(MARK)?;
    let (host, pid) = owner.rsplit_once('-')?;
    if host.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((host, pid.parse().ok()?))
}

/// Whether process `pid` is gone (Linux only: None where /proc is missing).
fn process_gone(pid: u32) -> Option<bool> {
    if !Path::new("/proc/self").exists() {
        return None;
    }
    Some(!Path::new(&format!("/proc/{pid}")).exists())
}

/// Removes, once per folder and process, temporaries left in `dir` by
/// painterly processes of this host that no longer exist (killed with -9).
/// Returns the paths removed.
pub fn sweep_stale(dir: &Path) -> Vec<PathBuf> {
    let key = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    {
        let mut reg = registry();
        if !reg.swept.insert(key) {
            return Vec::new();
        }
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let me = std::process::id();
    let mut removed = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let stale = match parse_temp_name(name) {
            Some((h, pid)) if h == host() && pid != me => process_gone(pid) == Some(true),
            // Our own pid: a previous process that had it died; ours are registered.
            Some((h, pid)) if h == host() && pid == me => {
                let p = entry.path();
                !registry().holds(&p)
            }
            _ => false,
        };
        let is_file = entry.file_type().map(|t| t.is_file()).unwrap_or(false);
        if stale && is_file {
            let p = entry.path();
            // Removed only while we hold its lock: a live writer holds it.
            let Some(_held) = lock_if_free(&p) else { continue };
            if std::fs::remove_file(&p).is_ok() {
                removed.push(p);
            }
        }
    }
    removed
}

/// Creates `tmp` (read-write) and registers it, under the registry lock, so
/// a signal never finds it created but unregistered. A temporary this
/// process holds already is refused (AlreadyExists), never truncated: two
/// writes of one target in one process (Python threads, a bake from a
/// progress hook) each need their own file.
#[cfg(test)]
fn create_registered(tmp: &Path) -> std::io::Result<File> {
    create_locked(&mut registry(), tmp)
}

fn create_locked(reg: &mut Registry, tmp: &Path) -> std::io::Result<File> {
    if reg.holds(tmp) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            "this process is writing that temporary already",
        ));
    }
    // A leftover with our own pid belongs to a dead process (pid reuse).
    // It may be a symlink, even a dangling one: remove the link itself
    // (symlink_metadata does not follow it), then create the file only if
    // nothing is there, so a link put back meanwhile is never followed.
    if tmp.symlink_metadata().is_ok() {
        let _ = std::fs::remove_file(tmp);
    }
    let f = File::options().read(true).write(true).create_new(true).open(tmp)?;
    // Held until the temporary is renamed or removed (the writer's handle is
    // closed before the rename; this one, of the same open file, is not).
    let lock = f.try_clone()?;
    if !try_flock(&lock) {
        let _ = std::fs::remove_file(tmp);
        return Err(std::io::Error::new(
            std::io::ErrorKind::WouldBlock,
            "another process locked this temporary as it was made",
        ));
    }
    reg.live.insert(tmp.to_path_buf(), Some(lock));
    Ok(f)
}

/// Takes an exclusive `flock` on `f` without waiting; false when another
/// open file holds one.
fn try_flock(f: &File) -> bool {
    use std::os::fd::AsRawFd;
    // SAFETY: flock on a descriptor this File owns for the call's duration.
    unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) == 0 }
}

/// An exclusive `flock` on the file at `path` (created when missing), held
/// until the returned file is dropped; `None` when another process still
/// holds it after `wait`. For steps that must not run twice at once (a
/// farm submission reads, submits and writes its plan).
pub fn hold_lock(path: &Path, wait: std::time::Duration) -> std::io::Result<Option<File>> {
    use std::os::unix::fs::OpenOptionsExt;
    // A FIFO or device there is refused, not used as the lock.
    let f = super::regular::regular_only(
        File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
            .open(path)
            .map_err(|e| match e.raw_os_error() {
                // O_NOFOLLOW's answer for a link, in the system's words
                // "Too many levels of symbolic links", which say nothing of why.
                Some(libc::ELOOP) => std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "it is a symbolic link, and a lock is never taken through one (remove the link)",
                ),
                _ => e,
            }),
    )?;
    let deadline = std::time::Instant::now() + wait;
    loop {
        if try_flock(&f) {
            return Ok(Some(f));
        }
        if std::time::Instant::now() >= deadline {
            return Ok(None);
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// The file at `p` opened and locked, when no live writer holds its lock
/// (and it is not a link: a leftover is never followed).
fn lock_if_free(p: &Path) -> Option<File> {
    // Never waits on a FIFO put there meanwhile.
    let f = super::regular::open_regular_with(p, true).ok()?;
    try_flock(&f).then_some(f)
}

/// Most writes of one target at once in one process (each has its own
/// temporary): a bound, so that no fault can make the search endless.
const MAX_SAME_NAME: u32 = 1000;

/// Creates and registers this process's temporary for `named` with
/// `suffix`: the plain name, or, while this process writes that one
/// already, `<name>+2`, `<name>+3`, … (the last write renamed wins, whole).
fn create_unique(named: &Path, suffix: &str) -> Result<(PathBuf, std::io::Result<File>)> {
    let mut reg = registry();
    // Ours already, or locked by a live writer this process cannot see
    // (another PID namespace with our pid): another name, never theirs.
    let held_elsewhere =
        |p: &Path| std::fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_file()) && lock_if_free(p).is_none();
    let name = named.file_name().unwrap_or_default().to_string_lossy();
    for k in 1..=MAX_SAME_NAME {
        let path = if k == 1 {
            temp_path(named, suffix)?
        } else {
            temp_path(&named.with_file_name(format!("{name}+{k}")), suffix)?
        };
        if !reg.holds(&path) && !held_elsewhere(&path) {
            let f = create_locked(&mut reg, &path);
            return Ok((path, f));
        }
    }
    Err(Error::msg(format!(
        "cannot write output: {MAX_SAME_NAME} writes of this file are under way at once"
    ))
    .in_file(named))
}

fn unregister(reg: &mut Registry, p: &Path) {
    reg.live.remove(p);
}

/// Removes a registered temporary and forgets it.
fn discard(tmp: &Path) {
    let mut reg = registry();
    let _ = std::fs::remove_file(tmp);
    unregister(&mut reg, tmp);
}

/// What a write callback may fail with: an I/O error (reported as "cannot
/// write output") or a painterly error kept as it is.
pub trait WriteFailure {
    /// The error to report.
    fn report(self) -> Error;
}

impl WriteFailure for std::io::Error {
    fn report(self) -> Error {
        Error::msg(format!("cannot write output: {self}"))
    }
}

impl WriteFailure for Error {
    fn report(self) -> Error {
        self
    }
}

/// A registered temporary file beside a target, for writes that stream
/// into it over a while (a bake's frames): removed when dropped, on signals,
/// and by the next run after a `kill -9`; [`TempFile::persist`] renames it
/// into place.
pub struct TempFile {
    path: PathBuf,
    persisted: bool,
}

impl TempFile {
    /// Creates `.<target name><tag>.painterly-<host>-<pid>.tmp` beside
    /// `target` (`tag` tells several temporaries of one target apart, e.g.
    /// `.samples`), read-write, after sweeping the folder's stale ones.
    pub fn create(target: &Path, tag: &str) -> Result<(TempFile, File)> {
        let target = &through_links(target);
        // Fail before the work, not after it.
        check_replaceable(target)?;
        sweep_stale(dir_of(target));
        let named = if tag.is_empty() {
            target.to_path_buf()
        } else {
            let name = target
                .file_name()
                .ok_or_else(|| Error::msg("output path has no file name").in_file(target))?;
            target.with_file_name(format!("{}{tag}", name.to_string_lossy()))
        };
        let (path, file) = create_unique(&named, TMP_SUFFIX)?;
        match file {
            Ok(f) => Ok((TempFile { path, persisted: false }, f)),
            Err(e) if e.raw_os_error() == Some(libc::ENAMETOOLONG) => {
                discard(&path);
                // The target's own path may fit where the longer name of
                // the temporary beside it does not.
                Err(Error::msg(format!(
                    "cannot write output: its temporary {} is {} bytes long, more than the system takes \
                     (File name too long): use a shorter folder path or name",
                    path.display(),
                    path.as_os_str().len()
                ))
                .in_file(target))
            }
            Err(e) => {
                discard(&path);
                Err(e.report().in_file(target))
            }
        }
    }

    /// Where the temporary is.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the temporary to `target` (its file must be closed), with
    /// the permission bits of the file it replaces; on failure it is removed.
    pub fn persist(self, target: &Path) -> Result<()> {
        self.publish(target, Publish::Replace)
    }

    /// [`TempFile::persist`], taking `target`'s place as `publish` says.
    pub fn publish(mut self, target: &Path, publish: Publish) -> Result<()> {
        let target = &through_links(target);
        if let Some(old) = check_replaceable(target)? {
            std::fs::set_permissions(&self.path, old.permissions()).map_err(|e| e.report().in_file(target))?;
        }
        // Under the registry's lock: a signal cannot remove the temporary
        // half-way through.
        let mut reg = registry();
        let placed = self.take_place(target, publish);
        unregister(&mut reg, &self.path);
        // Files in a temporary folder of ours (a render's own bake) are
        // not what the user asked for.
        let scratch = reg.live.iter().any(|(p, lock)| lock.is_none() && target.starts_with(p));
        if placed.is_ok() && !scratch {
            reg.published += 1;
            reg.first_published.get_or_insert_with(|| target.clone());
        }
        drop(reg);
        if placed.is_ok() {
            self.persisted = true;
        }
        placed
    }

    /// Puts the temporary at `target` as `publish` says; on failure the
    /// temporary is still there (and removed when dropped) unless it holds
    /// another program's file, which is then kept and named.
    fn take_place(&mut self, target: &Path, publish: Publish) -> Result<()> {
        let io = |e: std::io::Error| e.report().in_file(target);
        match publish {
            Publish::Replace => std::fs::rename(&self.path, target).map_err(io),
            Publish::ReplaceIf(check) => {
                // Checked here, not before the work: a save by another
                // program during the work is seen.
                check(target)?;
                match exchange(&self.path, target) {
                    Ok(()) => self.keep_if_read(target, check),
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                        Err(check(target).err().unwrap_or_else(|| io(e)))
                    }
                    // No exchange on this filesystem: the check just before
                    // the rename is all there is.
                    Err(e) if matches!(e.raw_os_error(), Some(libc::EINVAL | libc::ENOSYS)) => {
                        std::fs::rename(&self.path, target).map_err(io)
                    }
                    Err(e) => Err(io(e)),
                }
            }
            // A dangling link is replaced itself, as usd-core's save does
            // (the no-replace rename would see its name as taken).
            Publish::CreateNew if is_symlink(target) => std::fs::rename(&self.path, target).map_err(io),
            Publish::CreateNew => rename_no_replace(&self.path, target).map_err(|e| {
                if e.kind() == std::io::ErrorKind::AlreadyExists {
                    Error::msg(
                        "another process created this file while this edit ran; nothing was written: \
                         run the edit again to add it to that file",
                    )
                    .in_file(target)
                } else {
                    io(e)
                }
            }),
        }
    }

    /// After the exchange the replaced file is at the temporary's path: it
    /// is removed if it is the version read; otherwise a save landed
    /// between the check and the exchange, and it goes back.
    fn keep_if_read(&mut self, target: &Path, check: &dyn Fn(&Path) -> Result<()>) -> Result<()> {
        let Err(e) = check(&self.path) else {
            let _ = std::fs::remove_file(&self.path);
            return Ok(());
        };
        if exchange(&self.path, target).is_err() {
            // Theirs stays at the temporary's path: never removed, and
            // said where.
            self.persisted = true;
            return Err(Error::msg(format!(
                "{}; the other program's version could not be put back and is at {}",
                e.message,
                self.path.display()
            ))
            .in_file(target));
        }
        Err(e)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.persisted {
            discard(&self.path);
        }
    }
}

/// How many files this process has written (renamed into place), and the
/// first; `(0, None)` also when another thread holds the list (a panic
/// hook must not wait).
pub fn published() -> (usize, Option<PathBuf>) {
    let reg = match registry_mutex().try_lock() {
        Ok(reg) => reg,
        Err(std::sync::TryLockError::Poisoned(e)) => e.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return (0, None),
    };
    (reg.published, reg.first_published.clone())
}

/// What a failure message adds about [`published`] files: the work may be
/// done already, and a TD who knows it does not rerun an in-place edit
/// that was saved.
pub fn written_before((n, first): (usize, Option<PathBuf>)) -> String {
    match (n, first) {
        (1, Some(p)) => format!(" ({} was written before it)", p.display()),
        (n, Some(p)) => format!(" ({n} files were written before it, the first {})", p.display()),
        _ => String::new(),
    }
}

/// How a finished temporary takes its target's place.
#[derive(Clone, Copy)]
pub enum Publish<'a> {
    /// Whatever is there is replaced (a bake's output).
    Replace,
    /// The file is replaced if it is still the version read: `check(at)`
    /// says whether the file at `at` is. It runs on the target just before
    /// an atomic exchange, then on the file the exchange took out, which
    /// is put back when another program saved in between (an in-place
    /// edit).
    ReplaceIf(&'a dyn Fn(&Path) -> Result<()>),
    /// Only if nothing is there (a new edit layer: another process may
    /// create it meanwhile, and its file must not be lost).
    CreateNew,
}

/// Swaps the files at `a` and `b` atomically (`renameat2(RENAME_EXCHANGE)`).
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    renameat2(a, b, libc::RENAME_EXCHANGE)
}

fn renameat2(from: &Path, to: &Path, flags: libc::c_uint) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (f, t) = (c(from)?, c(to)?);
    // SAFETY: both are valid NUL-terminated paths for the duration of the call.
    let r = unsafe { libc::renameat2(libc::AT_FDCWD, f.as_ptr(), libc::AT_FDCWD, t.as_ptr(), flags) };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Renames `from` to `to` unless `to` exists (`AlreadyExists` then).
/// `renameat2(RENAME_NOREPLACE)`; where the filesystem lacks it, a hard
/// link (which fails on an existing name too) and an unlink.
fn rename_no_replace(from: &Path, to: &Path) -> std::io::Result<()> {
    let Err(e) = renameat2(from, to, libc::RENAME_NOREPLACE) else {
        return Ok(());
    };
    if !matches!(e.raw_os_error(), Some(libc::EINVAL | libc::ENOSYS)) {
        return Err(e);
    }
    match std::fs::hard_link(from, to) {
        Ok(()) => {
            let _ = std::fs::remove_file(from);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(e),
        // No hard links either (some network and FUSE filesystems): a
        // look, then a rename, which narrows the race to microseconds.
        Err(_) if std::fs::symlink_metadata(to).is_ok() => Err(std::io::ErrorKind::AlreadyExists.into()),
        Err(_) => std::fs::rename(from, to),
    }
}

fn is_symlink(p: &Path) -> bool {
    std::fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_symlink())
}

/// The file a write to `target` replaces: through a symbolic link, the
/// file it names (as usd-core's `Save` writes through a link and keeps
/// it: a versioned `tube_latest.usda -> v003/tube.usda` stays a link, and
/// the relative assets of the file stay anchored where they were).
/// A dangling link is replaced itself.
fn through_links(target: &Path) -> PathBuf {
    match std::fs::symlink_metadata(target) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(target).unwrap_or_else(|_| target.to_path_buf()),
        _ => target.to_path_buf(),
    }
}

/// The files the inputs of running work read, with how many pieces of work
/// read each: a write that would land on one (a chunk, the manifest or a
/// rendered frame whose name is a link to the input) is refused.
fn protected() -> MutexGuard<'static, std::collections::BTreeMap<PathBuf, usize>> {
    static FILES: Mutex<std::collections::BTreeMap<PathBuf, usize>> = Mutex::new(std::collections::BTreeMap::new());
    FILES.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// While alive, no write of this process replaces one of the files given
/// (canonical paths: the files an input reads). Bakes and renders hold one
/// for the files they read; an in-place edit, which must write its input,
/// holds none.
pub struct InputGuard(Vec<PathBuf>);

impl InputGuard {
    pub fn new<'a>(files: impl IntoIterator<Item = &'a PathBuf>) -> InputGuard {
        let files: Vec<PathBuf> = files.into_iter().cloned().collect();
        let mut set = protected();
        for f in &files {
            *set.entry(f.clone()).or_default() += 1;
        }
        InputGuard(files)
    }
}

impl Drop for InputGuard {
    fn drop(&mut self) {
        let mut set = protected();
        for f in &self.0 {
            if let Some(n) = set.get_mut(f) {
                *n -= 1;
                if *n == 0 {
                    set.remove(f);
                }
            }
        }
    }
}

/// Refuses a write that would replace a file an input reads (see
/// [`InputGuard`]); `target` is the file itself, links already followed.
fn check_not_protected(target: &Path) -> Result<()> {
    let Ok(file) = target.canonicalize() else {
        return Ok(()); // nothing there yet
    };
    if protected().contains_key(&file) {
        return Err(Error::msg(format!(
            "would overwrite {}, a file the input reads (through a link of that name?), or the input of other \
             painterly work running in this process (another Python thread's); inputs are never modified: \
             remove the link or write elsewhere",
            file.display()
        ))
        .in_file(target));
    }
    Ok(())
}

/// Refuses to replace a file this user may not write. The rename would
/// succeed in a writable folder and drop the file's protection; usd-core's
/// `Save` refuses such a file too. Returns the file it would replace, if
/// any, whose mode the new file takes.
fn check_replaceable(target: &Path) -> Result<Option<std::fs::Metadata>> {
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::PermissionsExt;
    check_not_protected(target)?;
    let Ok(meta) = std::fs::metadata(target) else {
        return Ok(None); // nothing there yet (or nothing we can see: the write says why)
    };
    if meta.is_dir() {
        return Ok(None); // the rename fails and says so
    }
    if !meta.is_file() {
        // A rename would put a regular file where the device or FIFO was
        // (an output linked to /dev/null replaced /dev/null itself).
        return Err(Error::msg(
            "cannot write over something that is not a regular file (a device, FIFO or socket): \
             name a file to write",
        )
        .in_file(target));
    }
    let Ok(c) = std::ffi::CString::new(target.as_os_str().as_bytes()) else {
        return Ok(Some(meta));
    };
    // SAFETY: `c` is a valid NUL-terminated path for the duration of the call.
    if unsafe { libc::access(c.as_ptr(), libc::W_OK) } == 0 {
        return Ok(Some(meta));
    }
    let why = std::io::Error::last_os_error();
    if why.raw_os_error() == Some(libc::EROFS) {
        return Err(Error::msg(format!("cannot replace the file: {why}")).in_file(target));
    }
    Err(Error::msg(format!(
        "cannot replace a file this user may not write (mode {:03o}): change its permissions first",
        meta.permissions().mode() & 0o7777
    ))
    .in_file(target))
}

/// Writes `bytes` to a temporary sibling of `path` and renames it into place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |out| out.write_all(bytes))
}

/// Runs `write` on a buffered temporary sibling of `path` and renames it into
/// place once `write` succeeds; on failure the temporary file is removed and
/// `path` is untouched. `write` fails with an I/O error or a painterly one
/// (kept as it is, e.g. naming a spec).
pub fn write_atomic_with<E: WriteFailure>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::result::Result<(), E>,
) -> Result<()> {
    write_atomic_as(path, Publish::Replace, write)
}

/// [`write_atomic_with`], taking `path`'s place as `publish` says.
pub fn write_atomic_as<E: WriteFailure>(
    path: &Path,
    publish: Publish,
    write: impl FnOnce(&mut BufWriter<File>) -> std::result::Result<(), E>,
) -> Result<()> {
    let (tmp, file) = TempFile::create(path, "")?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    write(&mut out).map_err(|e| e.report().in_file(path))?;
    // No fsync: the rename makes the write atomic for readers and for a
    // failed run; durability across power loss is the filesystem's.
    out.into_inner()
        .map_err(|e| e.into_error().report().in_file(path))
        .map(drop)?;
    tmp.publish(path, publish)
}

/// A scratch file beside `target` (e.g. the header a new edit layer is
/// opened from), removed when dropped, on failure and on signals.
pub struct ScratchFile {
    path: PathBuf,
}

impl ScratchFile {
    /// Writes `contents` to `.<target name>.painterly-<host>-<pid>.scratch.usda`
    /// beside `target`. Nothing is left behind when the write fails.
    pub fn create(target: &Path, contents: &[u8]) -> Result<ScratchFile> {
        sweep_stale(dir_of(target));
        let (path, file) = create_unique(target, SCRATCH_SUFFIX)?;
        let result = file.and_then(|mut f| f.write_all(contents));
        if let Err(e) = result {
            discard(&path);
            return Err(Error::msg(format!("cannot create a scratch file: {e}")).in_file(target));
        }
        Ok(ScratchFile { path })
    }

    /// Where the scratch file is.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for ScratchFile {
    fn drop(&mut self) {
        discard(&self.path);
    }
}

/// A temporary folder under the system temp dir, removed when dropped and on
/// signals; stale ones of dead processes are removed when the next is made.
pub struct TempDir {
    path: PathBuf,
}

impl TempDir {
    /// Creates `painterly-render-<host>-<pid>-<n>` in the system temp dir,
    /// `n` from the clock; a new folder every time, even for two threads
    /// in the same nanosecond (the next `n` is tried).
    pub fn new() -> Result<TempDir> {
        let base = std::env::temp_dir();
        sweep_stale_dirs(&base);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let mut reg = registry();
        let stem = format!("{RENDER_DIR_PREFIX}{}-{}-", host(), std::process::id());
        let path = create_new_dir(&base, &stem, nanos)?;
        reg.live.insert(path.clone(), None);
        Ok(TempDir { path })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let mut reg = registry();
        let _ = std::fs::remove_dir_all(&self.path);
        unregister(&mut reg, &self.path);
    }
}

/// Creates the folder `base/<stem><n>` for the first `n` from `first` on
/// that does not exist yet, trying [`NEW_DIR_TRIES`] names at most.
fn create_new_dir(base: &Path, stem: &str, first: u128) -> Result<PathBuf> {
    for n in first..first + NEW_DIR_TRIES {
        let path = base.join(format!("{stem}{n}"));
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(Error::msg(format!("cannot create a temporary folder: {e}")).in_file(&path)),
        }
    }
    Err(Error::msg(format!(
        "cannot create a temporary folder: {NEW_DIR_TRIES} names from {stem}{first} are taken"
    ))
    .in_file(base))
}

/// How many names [`create_new_dir`] tries: a clock tick shared by a few
/// threads needs a few; more means something else is making them.
const NEW_DIR_TRIES: u128 = 1000;

/// Removes render folders of dead processes of this host from `base`.
fn sweep_stale_dirs(base: &Path) {
    let key = base.join(RENDER_DIR_PREFIX);
    {
        let mut reg = registry();
        if !reg.swept.insert(key) {
            return;
        }
    }
    let Ok(entries) = std::fs::read_dir(base) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(RENDER_DIR_PREFIX)) else {
            continue;
        };
        // <host>-<pid>-<nanos>
        let mut parts = rest.rsplitn(3, '-');
        let (Some(_nanos), Some(pid), Some(h)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let Ok(pid) = pid.parse::<u32>() else { continue };
        if h == host() && pid != std::process::id() && process_gone(pid) == Some(true) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_dir::ScratchDir;

    /// A fresh empty folder for one test (the registry sweeps each folder
    /// once), removed when the test ends, passed or failed.
    fn fresh_dir(tag: &str) -> ScratchDir {
        ScratchDir::new(&format!("atomic-{tag}"))
    }

    /// The temporary name a write of `target` in `dir` by process `pid` on
    /// `host` uses (as `temp_path` builds it for this process).
    fn leftover(dir: &Path, target: &str, host: &str, pid: u32) -> PathBuf {
        dir.join(format!(".{target}{MARK}{host}-{pid}{TMP_SUFFIX}"))
    }

    /// This process's temporary for `target` in `dir`.
    fn ours(dir: &Path, target: &str) -> PathBuf {
        temp_path(&dir.join(target), TMP_SUFFIX).unwrap()
    }

    #[test]
    fn leftover_names_are_the_names_temp_path_gives() {
        let dir = Path::new("/x");
        assert_eq!(ours(dir, "t.usdc"), leftover(dir, "t.usdc", host(), std::process::id()));
    }

    #[test]
    fn temp_names_round_trip() {
        let t = temp_path(Path::new("/x/out.usdc"), TMP_SUFFIX).unwrap();
        let name = t.file_name().unwrap().to_str().unwrap();
        assert_eq!(parse_temp_name(name), Some((host(), std::process::id())));
        let s = temp_path(Path::new("e.usda"), SCRATCH_SUFFIX).unwrap();
        assert_eq!(
            parse_temp_name(s.file_name().unwrap().to_str().unwrap()),
            Some((host(), std::process::id()))
        );
        for other in [
            ".out.usdc.tmp",
            "out.usdc",
            ".a.painterly-h-x.tmp",
            ".a.painterly--12.tmp",
        ] {
            assert_eq!(parse_temp_name(other), None, "{other}");
        }
        assert_eq!(parse_temp_name(".a-b.painterly-my-host-12.tmp"), Some(("my-host", 12)));
        let long = "n".repeat(300) + ".usdc";
        let t = temp_path(Path::new(&long), TMP_SUFFIX).unwrap();
        assert!(t.file_name().unwrap().len() <= 255);
    }

    #[test]
    fn long_names_that_differ_only_at_their_end_get_distinct_temporaries() {
        // Chunks of a long stem differ after the cut: `<stem>.0000.1-5.usdc`.
        let stem = "s".repeat(240);
        let a = temp_path(Path::new(&format!("/x/{stem}.0000.1-5.usdc")), TMP_SUFFIX).unwrap();
        let b = temp_path(Path::new(&format!("/x/{stem}.0001.6-10.usdc")), TMP_SUFFIX).unwrap();
        assert_ne!(a, b);
        for t in [&a, &b] {
            let name = t.file_name().unwrap().to_str().unwrap();
            assert!(name.len() <= 255 && name.starts_with(".sss"), "{name}");
            assert_eq!(
                parse_temp_name(name).map(|(_, pid)| pid),
                Some(std::process::id()),
                "{name}"
            );
        }
        // A name that fits keeps its plain form.
        let short = temp_path(Path::new("/x/out.usdc"), TMP_SUFFIX).unwrap();
        assert!(!short.to_str().unwrap().contains('~'));
    }

    #[test]
    fn sweep_removes_only_dead_local_temporaries() {
        let dir = fresh_dir("test");
        // pid_max on Linux is at most 2^22: this pid cannot be running.
        let dead = leftover(&dir, "a.usdc", host(), 4194305);
        let alive = leftover(&dir, "b.usdc", host(), 1);
        let remote = leftover(&dir, "c.usdc", "otherhost", 4194305);
        let user = dir.join("notes.tmp");
        for p in [&dead, &alive, &remote, &user] {
            std::fs::write(p, b"x").unwrap();
        }
        let removed = sweep_stale(&dir);
        if Path::new("/proc/self").exists() {
            assert_eq!(removed, vec![dead.clone()]);
            assert!(!dead.exists());
        }
        assert!(alive.exists() && remote.exists() && user.exists());
    }

    #[test]
    fn a_locked_temporary_of_a_pid_this_process_cannot_see_is_kept() {
        // Two farm containers on the host network share a host name but not
        // a PID namespace: /proc shows neither the other's pid, and each
        // sweep removed the other's live temporary (the task failed, ENOENT).
        let dir = fresh_dir("locked");
        let theirs = leftover(&dir, "a.usdc", host(), 4194305);
        std::fs::write(&theirs, b"x").unwrap();
        let held = File::open(&theirs).unwrap();
        assert!(try_flock(&held));
        let removed_while_held = sweep_stale(&dir);
        let kept = theirs.exists();
        // Once its writer is gone (the lock with it), the next sweep removes it.
        drop(held);
        let again = fresh_dir("locked-again");
        let gone = leftover(&again, "a.usdc", host(), 4194305);
        std::fs::rename(&theirs, &gone).unwrap();
        let removed = sweep_stale(&again);
        if Path::new("/proc/self").exists() {
            assert_eq!((removed_while_held, kept), (vec![], true));
            assert_eq!(removed, vec![gone]);
        }
        // Ours are locked from creation to rename.
        let target = dir.join("b.usdc");
        let (tmp, f) = TempFile::create(&target, "").unwrap();
        drop(f);
        let other = File::open(tmp.path()).unwrap();
        let free = try_flock(&other);
        tmp.persist(&target).unwrap();
        assert!(!free, "a live temporary's lock was free after its writer closed it");
        assert!(try_flock(&File::open(&target).unwrap()), "the lock outlived the rename");
    }

    #[test]
    fn a_temporary_name_locked_by_another_writer_is_not_taken() {
        // Another PID namespace may run a process with our pid: its live
        // temporary has the name ours would have, and its lock says so.
        let dir = fresh_dir("same-name");
        let target = dir.join("t.usdc");
        let theirs = ours(&dir, "t.usdc");
        std::fs::write(&theirs, b"theirs").unwrap();
        let held = File::open(&theirs).unwrap();
        assert!(try_flock(&held));
        let (tmp, _f) = TempFile::create(&target, "").unwrap();
        let name = tmp.path().file_name().unwrap().to_str().unwrap().to_string();
        drop(tmp);
        let kept = std::fs::read(&theirs).unwrap();
        drop(held);
        assert_eq!(
            name,
            format!(".t.usdc+2.painterly-{}-{}.tmp", host(), std::process::id())
        );
        assert_eq!(kept, b"theirs");
    }

    #[test]
    fn a_temporary_path_too_long_for_the_system_is_named_with_its_length() {
        // A target whose own path fits in PATH_MAX (4096) while the
        // temporary's longer name beside it does not: the error said "File
        // name too long" of the target.
        let scratch = fresh_dir("long-path");
        let mut dir = scratch.to_path_buf();
        while dir.as_os_str().len() < 3880 {
            dir = dir.join("d".repeat(50));
            std::fs::create_dir(&dir).unwrap();
        }
        // A 4,090-byte target (a name of 158 to 209 bytes): its temporary
        // adds about 35 bytes, past 4,095.
        let name = 4090 - dir.as_os_str().len() - 1;
        let target = dir.join("t".repeat(name - 5) + ".usdc");
        assert_eq!(target.as_os_str().len(), 4090);
        let e = TempFile::create(&target, "").map(|_| ()).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(target.as_path()));
        assert!(
            e.message.starts_with("cannot write output: its temporary ")
                && e.message.contains(
                    " bytes long, more than the system takes (File name too long): use a shorter folder path or name"
                ),
            "{e}"
        );
    }

    #[test]
    fn a_replaced_file_keeps_its_mode_and_a_new_one_gets_the_default() {
        use std::os::unix::fs::PermissionsExt;
        let dir = fresh_dir("mode");
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
        let fresh = dir.join("fresh.usda");
        write_atomic(&fresh, b"new").unwrap();
        let default = mode(&fresh);
        for m in [0o600, 0o640, 0o755] {
            let out = dir.join(format!("out{m:o}.usda"));
            std::fs::write(&out, b"old").unwrap();
            std::fs::set_permissions(&out, std::fs::Permissions::from_mode(m)).unwrap();
            write_atomic(&out, b"new").unwrap();
            assert_eq!((mode(&out), std::fs::read(&out).unwrap()), (m, b"new".to_vec()));
            assert_ne!(m, default);
        }
        // A folder is not replaced: the rename says why.
        let folder = dir.join("folder.usda");
        std::fs::create_dir(&folder).unwrap();
        assert!(write_atomic(&folder, b"x").is_err());
        assert!(folder.is_dir());
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = fresh_dir("fail");
        let out = dir.join("out.usda");
        let e = write_atomic_with(&out, |w| {
            w.write_all(b"partial").unwrap();
            Err(Error::msg("serialiser failed"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("serialiser failed"));
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        write_atomic(&out, b"ok").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"ok");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    }

    #[test]
    fn temporaries_go_in_the_target_folder_or_the_current_one() {
        assert_eq!(dir_of(Path::new("/x/out.usdc")), Path::new("/x"));
        assert_eq!(dir_of(Path::new("sub/out.usdc")), Path::new("sub"));
        // No folder in the path: the current one, "." (read_dir("") fails).
        assert_eq!(dir_of(Path::new("out.usdc")), Path::new("."));
    }

    #[test]
    fn long_multibyte_names_are_cut_on_a_char_boundary() {
        // '€' is 3 bytes: with 0, 1 or 2 ASCII bytes before them, one of the
        // three names has its 255-byte cut inside a '€', whatever the tail's length.
        for prefix in ["", "a", "aa"] {
            let long = format!("{prefix}{}.usdc", "€".repeat(100));
            let t = temp_path(Path::new(&long), TMP_SUFFIX).unwrap();
            let name = t.file_name().unwrap().to_str().unwrap();
            // The longest whole-char prefix that fits: within 2 bytes of 255.
            assert!((253..=255).contains(&name.len()), "{} bytes: {name}", name.len());
            assert!(name.starts_with(&format!(".{prefix}€")), "{name}");
        }
    }

    #[test]
    fn sweep_removes_unregistered_temporaries_of_our_own_pid() {
        let dir = fresh_dir("own-pid");
        let me = std::process::id();
        // Left by a dead process that had our pid: nobody here registered it.
        let stale = leftover(&dir, "a.usdc", host(), me);
        // Ours and live: registered.
        let live = leftover(&dir, "b.usdc", host(), me);
        // Another host's, with the same pid number: not ours to judge.
        let remote = leftover(&dir, "c.usdc", "otherhost", me);
        std::fs::write(&stale, b"x").unwrap();
        std::fs::write(&remote, b"x").unwrap();
        let _live_file = create_registered(&live).unwrap();
        let removed = sweep_stale(&dir);
        let kept = (live.exists(), remote.exists());
        discard(&live);
        assert_eq!(removed, vec![stale.clone()]);
        assert!(!stale.exists());
        assert_eq!(kept, (true, true));
    }

    #[test]
    fn a_leftover_symlink_is_replaced_not_followed() {
        use std::os::unix::fs::symlink;
        let dir = fresh_dir("symlink");
        // Another live temporary, so the registry holds a path other than tmp.
        let other = ours(&dir, "o.usdc");
        let _other_file = create_registered(&other).unwrap();
        let victim = dir.join("victim.usda");
        std::fs::write(&victim, b"keep").unwrap();
        let tmp = ours(&dir, "t.usdc");
        symlink(&victim, &tmp).unwrap();
        let f = create_registered(&tmp);
        let is_symlink = std::fs::symlink_metadata(&tmp).unwrap().file_type().is_symlink();
        let victim_bytes = std::fs::read(&victim).unwrap();
        discard(&tmp);
        discard(&other);
        assert!(f.is_ok());
        // Opening through the link would have truncated the victim.
        assert_eq!(victim_bytes, b"keep");
        assert!(!is_symlink);
    }

    #[test]
    fn a_second_write_of_a_target_in_one_process_gets_its_own_temporary() {
        use std::os::unix::fs::MetadataExt;
        let dir = fresh_dir("again");
        let target = dir.join("t.usdc");
        // Two bakes of one output in one process (Python threads): the
        // second truncated the first's temporary, and the two wrote into one
        // file, which one of them then published mixed.
        let (a, mut fa) = TempFile::create(&target, "").unwrap();
        let (b, mut fb) = TempFile::create(&target, "").unwrap();
        let (c, _fc) = TempFile::create(&target, "").unwrap();
        fa.write_all(b"first").unwrap();
        fb.write_all(b"second").unwrap();
        let names = [a.path(), b.path(), c.path()].map(|p| p.file_name().unwrap().to_str().unwrap().to_string());
        let inode_a = fa.metadata().unwrap().ino() == std::fs::metadata(a.path()).unwrap().ino();
        drop((fa, fb));
        b.persist(&target).unwrap();
        let after_b = std::fs::read(&target).unwrap();
        a.persist(&target).unwrap();
        let after_a = std::fs::read(&target).unwrap();
        drop(c);
        let me = std::process::id();
        let h = host();
        assert_eq!(
            names,
            [
                format!(".t.usdc.painterly-{h}-{me}.tmp"),
                format!(".t.usdc+2.painterly-{h}-{me}.tmp"),
                format!(".t.usdc+3.painterly-{h}-{me}.tmp"),
            ]
        );
        assert!(inode_a);
        assert_eq!((after_b, after_a), (b"second".to_vec(), b"first".to_vec()));
        // Each temporary is its own; none is left.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        // The registry's own refusal, under the plain name.
        let tmp = ours(&dir, "u.usdc");
        let first = create_registered(&tmp).unwrap();
        let again = create_registered(&tmp).map(drop).map_err(|e| e.kind());
        drop(first);
        discard(&tmp);
        assert_eq!(again, Err(std::io::ErrorKind::AlreadyExists));
    }

    #[test]
    fn discard_removes_and_forgets_the_temporary() {
        let dir = fresh_dir("discard");
        let tmp = ours(&dir, "t.usdc");
        drop(create_registered(&tmp).unwrap());
        assert!(registry().holds(&tmp));
        discard(&tmp);
        // A forgotten path is no longer removed on signals nor kept by sweeps.
        assert!(!registry().holds(&tmp));
        assert!(!tmp.exists());
    }

    #[test]
    fn temp_file_is_named_after_target_and_tag_beside_it() {
        let dir = fresh_dir("tempfile");
        let target = dir.join("out.usdc");
        let (tmp, _file) = TempFile::create(&target, ".samples").unwrap();
        // The documented name: .<target name><tag>.painterly-<host>-<pid>.tmp
        let want = dir.join(format!(
            ".out.usdc.samples.painterly-{}-{}.tmp",
            host(),
            std::process::id()
        ));
        assert_eq!(tmp.path(), want);
        assert!(want.is_file());
        drop(tmp);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    }

    #[test]
    fn scratch_file_holds_its_contents_until_dropped() {
        let dir = fresh_dir("scratch");
        let s = ScratchFile::create(&dir.join("e.usda"), b"#usda 1.0\n").unwrap();
        let want = dir.join(format!(
            ".e.usda.painterly-{}-{}.scratch.usda",
            host(),
            std::process::id()
        ));
        assert_eq!(s.path(), want);
        assert_eq!(std::fs::read(&want).unwrap(), b"#usda 1.0\n");
        drop(s);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    }

    #[test]
    fn temp_dir_is_in_the_system_temp_dir_until_dropped() {
        let d = TempDir::new().unwrap();
        let path = d.path().to_path_buf();
        assert_eq!(path.parent(), Some(std::env::temp_dir().as_path()));
        assert!(path
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("painterly-render-"));
        assert!(path.is_dir());
        std::fs::write(path.join("f"), b"x").unwrap();
        drop(d);
        assert!(!path.exists());
    }

    #[test]
    fn a_new_temp_dir_skips_a_folder_that_exists() {
        // Python bakes in several threads each take one: a clock tick
        // shared by two must not give them the same folder.
        let base = fresh_dir("new-dir");
        std::fs::create_dir(base.join("t-7")).unwrap();
        std::fs::write(base.join("t-7").join("bake.usda"), b"theirs").unwrap();
        assert_eq!(create_new_dir(&base, "t-", 7).unwrap(), base.join("t-8"));
        assert_eq!(create_new_dir(&base, "t-", 7).unwrap(), base.join("t-9"));
        assert_eq!(std::fs::read(base.join("t-7").join("bake.usda")).unwrap(), b"theirs");
        // Another error is reported at once, as the system gave it.
        let err = create_new_dir(&base.join("missing"), "t-", 0).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("cannot create a temporary folder: No such file or directory (os error 2)"),
            "{err}"
        );
        // Every name taken: an error, not a hang.
        for n in 100..100 + NEW_DIR_TRIES {
            std::fs::create_dir(base.join(format!("u-{n}"))).unwrap();
        }
        let err = create_new_dir(&base, "u-", 100).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("cannot create a temporary folder: 1000 names from u-100 are taken"),
            "{err}"
        );
    }

    #[test]
    fn sweep_removes_only_dead_local_render_folders() {
        let base = fresh_dir("render-sweep");
        // pid_max on Linux is at most 2^22: 4194305 cannot be running; pid 1 is.
        let dead = base.join(format!("{RENDER_DIR_PREFIX}{}-4194305-7", host()));
        let alive = base.join(format!("{RENDER_DIR_PREFIX}{}-1-7", host()));
        let remote = base.join(format!("{RENDER_DIR_PREFIX}otherhost-4194305-7"));
        for d in [&dead, &alive, &remote] {
            std::fs::create_dir_all(d).unwrap();
            std::fs::write(d.join("frame.exr"), b"x").unwrap();
        }
        sweep_stale_dirs(&base);
        if Path::new("/proc/self").exists() {
            assert!(!dead.exists());
        }
        assert!(alive.exists() && remote.exists());
    }

    #[test]
    fn a_dangling_leftover_symlink_creates_nothing_at_its_target() {
        use std::os::unix::fs::symlink;
        let dir = fresh_dir("dangling");
        let elsewhere = dir.join("elsewhere.usda");
        let tmp = ours(&dir, "t.usdc");
        symlink(&elsewhere, &tmp).unwrap();
        let f = create_registered(&tmp);
        let is_symlink = std::fs::symlink_metadata(&tmp).unwrap().file_type().is_symlink();
        let created = elsewhere.exists();
        discard(&tmp);
        assert!(f.is_ok());
        // Opening through the link creates the file it names (and persist
        // would then rename the link itself onto the target).
        assert!(!created, "created the link's target");
        assert!(!is_symlink);
    }

    #[test]
    fn a_new_file_is_published_only_where_nothing_is() {
        let dir = fresh_dir("create-new");
        let target = dir.join("e.usda");
        write_atomic_as(&target, Publish::CreateNew, |w| w.write_all(b"first")).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"first");
        // Another process created it meanwhile: its file is kept.
        let e = write_atomic_as(&target, Publish::CreateNew, |w| w.write_all(b"second")).unwrap_err();
        assert!(
            e.message.starts_with("another process created this file"),
            "{}",
            e.message
        );
        assert_eq!(std::fs::read(&target).unwrap(), b"first");
        let names: Vec<_> = std::fs::read_dir(&*dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["e.usda"], "the temporary is removed");
    }

    #[test]
    fn a_replacement_is_published_only_if_its_check_passes_at_the_rename() {
        let dir = fresh_dir("replace-if");
        let target = dir.join("e.usda");
        std::fs::write(&target, b"theirs").unwrap();
        let checks = std::cell::Cell::new(0);
        let refuse = |_: &Path| {
            checks.set(checks.get() + 1);
            Err(Error::msg("changed"))
        };
        let e = write_atomic_as(&target, Publish::ReplaceIf(&refuse), |w| w.write_all(b"ours")).unwrap_err();
        assert_eq!((e.message.as_str(), checks.get()), ("changed", 1));
        assert_eq!(std::fs::read(&target).unwrap(), b"theirs");
        // A save between the check and the exchange: the file taken out is
        // not the version read, and goes back.
        let seen = std::cell::RefCell::new(Vec::new());
        let late = |at: &Path| {
            seen.borrow_mut().push(std::fs::read(at).unwrap());
            if seen.borrow().len() == 1 {
                std::fs::write(at, b"saved meanwhile").unwrap();
                Ok(())
            } else {
                Err(Error::msg("changed"))
            }
        };
        let e = write_atomic_as(&target, Publish::ReplaceIf(&late), |w| w.write_all(b"ours")).unwrap_err();
        assert_eq!(e.message, "changed");
        assert_eq!(*seen.borrow(), [b"theirs".to_vec(), b"saved meanwhile".to_vec()]);
        assert_eq!(std::fs::read(&target).unwrap(), b"saved meanwhile");
        let pass = |_: &Path| Ok(());
        write_atomic_as(&target, Publish::ReplaceIf(&pass), |w| w.write_all(b"ours")).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"ours");
        let names: Vec<_> = std::fs::read_dir(&*dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["e.usda"]);
    }

    #[test]
    fn a_new_file_named_by_a_dangling_link_replaces_the_link() {
        let dir = fresh_dir("create-new-link");
        let link = dir.join("latest.usda");
        std::os::unix::fs::symlink("v003/e.usda", &link).unwrap();
        write_atomic_as(&link, Publish::CreateNew, |w| w.write_all(b"new")).unwrap();
        assert!(!is_symlink(&link));
        assert_eq!(std::fs::read(&link).unwrap(), b"new");
    }

    #[test]
    fn rename_no_replace_refuses_an_existing_name() {
        let dir = fresh_dir("noreplace");
        let (a, b) = (dir.join("a"), dir.join("b"));
        std::fs::write(&a, b"a").unwrap();
        std::fs::write(&b, b"b").unwrap();
        let e = rename_no_replace(&a, &b).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::AlreadyExists);
        std::fs::remove_file(&b).unwrap();
        rename_no_replace(&a, &b).unwrap();
        assert!(!a.exists());
        assert_eq!(std::fs::read(&b).unwrap(), b"a");
    }
}
