//! Opening input files only when they are regular files, without ever
//! blocking.
//!
//! `open(2)` of a FIFO for reading waits until some process opens it for
//! writing, possibly for ever; a check of the path before the open
//! (`metadata().is_file()`) leaves a window in which the file can be
//! replaced by one. So every input painterly reads (the layers openusd
//! opens, edit targets, brushes, farm plans) is opened with `O_NONBLOCK`,
//! which never waits, and its type is taken from the opened descriptor:
//! what is checked is what is read.
//!
//! [`RegularResolver`] does this for openusd: the default resolver with its
//! file opens replaced. Its memory mappings are noted ([`mapped_file_at`]),
//! so that the bus error a mapped file truncated under a bake raises can be
//! reported naming the file (`compose_watch`'s crash handler). A process
//! without that handler (the Python package) has files read whole instead
//! ([`read_instead_of_mapping`]).

use std::fs::File;
use std::io;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicUsize, Ordering};

use openusd::ar::{self, Asset, AssetBuffer, DefaultResolver, ResolvedPath, SharedBuffer};

use super::guard::{nanoseconds, FileId};

/// Why a path that is not a regular file is refused, in its error message.
pub const NOT_REGULAR: &str = "not a regular file (a FIFO, device or socket)";

/// The file at `path` (links followed, unless `no_follow`) opened for
/// reading, or an error when it is anything but a regular file. Never
/// blocks.
pub fn open_regular_with(path: &Path, no_follow: bool) -> io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    let flags = libc::O_NONBLOCK | if no_follow { libc::O_NOFOLLOW } else { 0 };
    // O_NONBLOCK changes nothing for a regular file's reads; it is left on.
    regular_only(File::options().read(true).custom_flags(flags).open(path))
}

/// `opened`, a file just opened from a path with `O_NONBLOCK`, when it is a
/// regular file; otherwise the error that says what it is.
pub fn regular_only(opened: io::Result<File>) -> io::Result<File> {
    let file = opened.map_err(|e| {
        // open(2) of a socket (or of a device with no driver) fails so.
        if e.raw_os_error() == Some(libc::ENXIO) {
            io::Error::new(io::ErrorKind::InvalidInput, NOT_REGULAR)
        } else {
            e
        }
    })?;
    match refusal(&file.metadata()?) {
        Some(e) => Err(e),
        None => Ok(file),
    }
}

/// Why a file of this type is not read, or None for a regular file.
pub fn refusal(meta: &std::fs::Metadata) -> Option<io::Error> {
    if meta.is_dir() {
        Some(io::Error::new(
            io::ErrorKind::IsADirectory,
            "it is a folder, not a file",
        ))
    } else if !meta.is_file() {
        Some(io::Error::new(io::ErrorKind::InvalidInput, NOT_REGULAR))
    } else {
        None
    }
}

/// [`open_regular_with`], following links.
pub fn open_regular(path: &Path) -> io::Result<File> {
    open_regular_with(path, false)
}

/// The whole of the regular file at `path` (`std::fs::read` that refuses,
/// instead of waiting on, a FIFO or device).
pub fn read_regular(path: &Path) -> io::Result<Vec<u8>> {
    use std::io::Read;
    let mut file = open_regular(path)?;
    let mut bytes = Vec::with_capacity(file.metadata().map_or(0, |m| m.len() as usize));
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text.
pub fn read_regular_to_string(path: &Path) -> io::Result<String> {
    String::from_utf8(read_regular(path)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "the file is not valid UTF-8 text"))
}

/// The default resolver, whose file opens go through [`open_regular`]: a
/// layer that is a FIFO, a device or a socket (a sublayer, reference,
/// payload or clip naming one, or a root swapped for one after it was
/// checked) fails to open instead of hanging the command. Everything else
/// is the default resolver's.
pub struct RegularResolver {
    /// Resolves, and opens package entries: it opens the package by itself,
    /// so it reads rather than maps (a mapping it made would not be in the
    /// table [`mapped_file_at`] reads).
    inner: DefaultResolver,
    /// How a file's bytes reach openusd.
    files: Files,
}

/// How [`RegularResolver`] hands a file to openusd.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Files {
    /// Read through the descriptor, as openusd asks.
    Descriptor,
    /// A read-only memory mapping ([`RegularResolver::mapped`] in the CLI).
    Mapping,
    /// The whole file read into memory once, shared by every open of the
    /// same unchanged file while one is alive: what a mapping gives openusd
    /// (the same buffer, decoded the same way) without the bus error a
    /// mapping raises when its file is cut short ([`read_instead_of_mapping`]).
    Whole,
}

/// Whether [`RegularResolver::mapped`] maps files. The CLI does: its
/// bus-error handler reports a mapped input cut short under a run. The
/// Python package does not: a library must not take over its host's
/// signal handlers, and without one that bus error ends the host process.
static MAP_FILES: AtomicBool = AtomicBool::new(true);

/// From now on, [`RegularResolver::mapped`] reads each file whole into
/// memory instead of mapping it. For a process with no bus-error handler
/// of painterly's (the Python package calls it when loaded).
pub fn read_instead_of_mapping() {
    MAP_FILES.store(false, Ordering::Relaxed);
}

impl RegularResolver {
    /// Files read through the descriptor.
    pub fn new() -> Self {
        RegularResolver {
            inner: DefaultResolver::new(),
            files: Files::Descriptor,
        }
    }

    /// Files handed out as read-only memory mappings (or, after
    /// [`read_instead_of_mapping`], as buffers read whole).
    ///
    /// # Safety
    /// The promise `DefaultResolver::map_files` asks for: no file opened
    /// through this resolver is modified while anything read from it lives.
    #[allow(unsafe_code)]
    pub unsafe fn mapped() -> Self {
        let files = if MAP_FILES.load(Ordering::Relaxed) {
            Files::Mapping
        } else {
            Files::Whole
        };
        RegularResolver {
            inner: DefaultResolver::new(),
            files,
        }
    }

    fn open_file(&self, path: &Path) -> io::Result<Box<dyn Asset>> {
        let file = open_regular(path)?;
        let meta = file.metadata()?;
        let len = usize::try_from(meta.len()).unwrap_or(0);
        if self.files == Files::Descriptor || len == 0 {
            return Ok(Box::new(file));
        }
        if self.files == Files::Whole {
            let bytes = read_whole(file, &meta, len)?;
            return Ok(Box::new(io::Cursor::new(AssetBuffer::Shared(SharedBuffer::new(bytes)))));
        }
        // SAFETY: read-only mapping of a regular file; that nothing writes
        // into it while mapped is what `mapped`'s caller promised.
        #[allow(unsafe_code)]
        let map = unsafe { memmap2::MmapOptions::new().len(len).map(&file) };
        Ok(match map {
            Ok(map) => {
                note_mapping(map.as_ptr() as usize, map.len(), path);
                Box::new(io::Cursor::new(AssetBuffer::Shared(SharedBuffer::new(map))))
            }
            Err(_) => Box::new(file),
        })
    }
}

/// A file's version, the same key meaning the same bytes: the version a
/// command's check of its inputs compares ([`FileId`]: a save by rename
/// gives a new inode, one in place a new size or modification time), and
/// the status-change time, which a rewrite in place moves even when it
/// sets the modification time back.
type Version = (FileId, i128);

fn version_of(meta: &std::fs::Metadata) -> Version {
    use std::os::unix::fs::MetadataExt;
    (
        FileId::from_metadata(meta),
        nanoseconds(meta.ctime(), meta.ctime_nsec()),
    )
}

/// Files read whole, by version: being read by some open, or read, with a
/// weak reference to their bytes. A bake opens its input once per
/// point-cached attribute, and Python threads may read one file at once:
/// each open shares the first one's bytes while any reader holds them, and
/// waits for a read under way rather than reading a copy of its own. (A
/// weak reference to an `Arc<[u8]>` keeps its allocation:
/// [`forget_unheld_reads`] drops the ones no reader holds.)
static READ_WHOLE: std::sync::Mutex<Vec<(Version, WholeRead)>> = std::sync::Mutex::new(Vec::new());
/// Signalled whenever a read of [`READ_WHOLE`] ends.
static READ_ENDED: std::sync::Condvar = std::sync::Condvar::new();

enum WholeRead {
    Reading,
    Read(std::sync::Weak<[u8]>),
}

impl WholeRead {
    /// Whether nothing holds the bytes any more (a read under way is held).
    fn unheld(&self) -> bool {
        matches!(self, WholeRead::Read(bytes) if bytes.strong_count() == 0)
    }
}

/// Frees the bytes of files read whole that no reader holds any more (the
/// Python package calls it as each call returns, so a long-lived host does
/// not keep its last input in memory).
pub fn forget_unheld_reads() {
    let mut reads = READ_WHOLE.lock().unwrap_or_else(|e| e.into_inner());
    reads.retain(|(_, read)| !read.unheld());
}

/// Ends this open's read of `version`, whatever happens to it (a panic
/// too): the entry leaves the list, for `bytes` when the read succeeded,
/// and the opens waiting on it go on.
struct ReadUnderWay {
    version: Version,
    bytes: Option<std::sync::Weak<[u8]>>,
}

impl Drop for ReadUnderWay {
    fn drop(&mut self) {
        let mut reads = READ_WHOLE.lock().unwrap_or_else(|e| e.into_inner());
        reads.retain(|(v, read)| !(*v == self.version && matches!(read, WholeRead::Reading)));
        if let Some(bytes) = self.bytes.take() {
            reads.push((self.version, WholeRead::Read(bytes)));
        }
        READ_ENDED.notify_all();
    }
}

/// The `len` bytes of `file` (whose metadata is `meta`), read now or
/// shared with a reader of the same version.
fn read_whole(mut file: File, meta: &std::fs::Metadata, len: usize) -> io::Result<std::sync::Arc<[u8]>> {
    use std::io::Read;
    let version = version_of(meta);
    let mut reads = READ_WHOLE.lock().unwrap_or_else(|e| e.into_inner());
    loop {
        reads.retain(|(_, read)| !read.unheld());
        match reads.iter().find(|(v, _)| *v == version).map(|(_, read)| read) {
            Some(WholeRead::Reading) => reads = READ_ENDED.wait(reads).unwrap_or_else(|e| e.into_inner()),
            Some(WholeRead::Read(bytes)) => match bytes.upgrade() {
                Some(bytes) => return Ok(bytes),
                None => break,
            },
            None => break,
        }
    }
    reads.push((version, WholeRead::Reading));
    drop(reads);
    let mut under_way = ReadUnderWay { version, bytes: None };
    // Read straight into the shared allocation (a Vec made into an
    // `Arc<[u8]>` is copied: twice the file at the peak), outside the lock.
    // A file that shrank meanwhile fails the read; one that grew is read to
    // its old length: either way it changed, which the command's check of
    // its inputs says.
    let mut bytes: std::sync::Arc<[u8]> = std::iter::repeat_n(0u8, len).collect();
    let buffer = std::sync::Arc::get_mut(&mut bytes).ok_or_else(|| io::Error::other("shared before it was read"))?;
    file.read_exact(buffer)?;
    #[cfg(test)]
    tests::READS.lock().unwrap().push(version);
    under_way.bytes = Some(std::sync::Arc::downgrade(&bytes));
    Ok(bytes)
}

/// Mapped files noted at once (each point-cached attribute maps its file
/// once more): past this, a bus error in a mapping is reported without
/// its file's name.
const MAPPINGS: usize = 4096;

/// One noted mapping: written under [`MAPPING_WRITES`], read by a signal
/// handler with atomic loads only (`len` 0: an empty slot).
struct Mapping {
    start: AtomicUsize,
    len: AtomicUsize,
    /// The file's path, NUL-terminated, leaked: a handler may read it at
    /// any time, so it is never freed (a few hundred bytes a mapping).
    path: AtomicPtr<libc::c_char>,
}

static MAPPED: [Mapping; MAPPINGS] = [const {
    Mapping {
        start: AtomicUsize::new(0),
        len: AtomicUsize::new(0),
        path: AtomicPtr::new(std::ptr::null_mut()),
    }
}; MAPPINGS];
/// Guards writes to [`MAPPED`]; holds how many slots were ever used (the
/// rest are empty).
static MAPPING_WRITES: std::sync::Mutex<usize> = std::sync::Mutex::new(0);

/// Notes that `path` is mapped at `start..start + len`. A slot whose range
/// overlaps belongs to a mapping since unmapped (the system reused its
/// addresses), and is taken over.
fn note_mapping(start: usize, len: usize, path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let Ok(c_path) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
        return;
    };
    let mut used = MAPPING_WRITES.lock().unwrap_or_else(|e| e.into_inner());
    let overlaps = |m: &Mapping| {
        let (s, l) = (m.start.load(Ordering::Relaxed), m.len.load(Ordering::Relaxed));
        l > 0 && s < start + len && start < s + l
    };
    let seen = &MAPPED[..*used];
    let slot = match seen.iter().find(|m| overlaps(m)) {
        Some(slot) => slot,
        None if *used < MAPPINGS => {
            *used += 1;
            &MAPPED[*used - 1]
        }
        None => return,
    };
    // Emptied first, so a handler never pairs one mapping's range with
    // another's path.
    slot.len.store(0, Ordering::Release);
    slot.path.store(c_path.into_raw(), Ordering::Release);
    slot.start.store(start, Ordering::Release);
    slot.len.store(len, Ordering::Release);
}

/// The NUL-terminated path of the noted mapped file holding address
/// `addr`, if any. Async-signal-safe: atomic loads only.
pub fn mapped_file_at(addr: usize) -> Option<*const libc::c_char> {
    MAPPED.iter().find_map(|m| {
        let len = m.len.load(Ordering::Acquire);
        let start = m.start.load(Ordering::Acquire);
        let path = m.path.load(Ordering::Acquire);
        (len > 0 && start <= addr && addr - start < len && !path.is_null()).then_some(path as *const _)
    })
}

impl Default for RegularResolver {
    fn default() -> Self {
        Self::new()
    }
}

impl ar::Resolver for RegularResolver {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ResolvedPath>) -> String {
        self.inner.create_identifier(asset_path, anchor)
    }

    fn resolve(&self, asset_path: &str) -> Option<ResolvedPath> {
        // The default resolver opens a package to look for the entry,
        // with a blocking open: a package that is not a regular file
        // resolves to nothing instead (an unresolved asset, reported).
        let package = super::stage::package_file(asset_path);
        if package != asset_path && std::fs::metadata(package).is_ok_and(|m| !m.is_file()) {
            return None;
        }
        self.inner.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ResolvedPath> {
        self.inner.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved_path: &ResolvedPath) -> io::Result<Box<dyn Asset>> {
        let text = resolved_path.to_str().unwrap_or_default();
        let package = super::stage::package_file(text);
        if package != text {
            // An entry of a package: the default resolver opens the package
            // by path, so its type is checked first (a swap in between is
            // the one window left, for packages only).
            open_regular(Path::new(package))?;
            return self.inner.open_asset(resolved_path);
        }
        self.open_file(resolved_path)
    }

    forward_to_inner!();
}

/// The [`ar::Resolver`] methods a resolver wrapping another (`self.inner`)
/// passes on unchanged, written once: a method left out would answer the
/// trait's default instead of the wrapped resolver's.
macro_rules! forward_to_inner {
    () => {
        fn get_extension<'a>(&self, asset_path: &'a str) -> &'a str {
            self.inner.get_extension(asset_path)
        }

        fn is_context_dependent_path(&self, asset_path: &str) -> bool {
            self.inner.is_context_dependent_path(asset_path)
        }

        fn in_memory_identifier<'a>(&self, asset_path: &'a str) -> std::borrow::Cow<'a, str> {
            self.inner.in_memory_identifier(asset_path)
        }

        fn get_asset_info(
            &self,
            asset_path: &str,
            resolved_path: &openusd::ar::ResolvedPath,
        ) -> openusd::ar::AssetInfo {
            self.inner.get_asset_info(asset_path, resolved_path)
        }

        fn get_modification_timestamp(
            &self,
            asset_path: &str,
            resolved_path: &openusd::ar::ResolvedPath,
        ) -> Option<std::time::SystemTime> {
            self.inner.get_modification_timestamp(asset_path, resolved_path)
        }

        fn identity(&self) -> String {
            self.inner.identity()
        }

        fn cache_id(&self) -> Option<u64> {
            self.inner.cache_id()
        }
    };
}
pub(crate) use forward_to_inner;

#[cfg(test)]
mod tests {
    use super::*;
    use ar::Resolver;
    use std::os::unix::fs::OpenOptionsExt;

    /// The version of each file read whole, in order.
    pub(super) static READS: std::sync::Mutex<Vec<Version>> = std::sync::Mutex::new(Vec::new());

    /// How many times a file with the inode of `p` was read whole: count
    /// from a first call made once `p` exists (an inode is reused after a
    /// file is deleted, but no two files share one at once).
    fn reads_of(p: &Path) -> usize {
        let file = FileId::of(p).unwrap();
        READS.lock().unwrap().iter().filter(|(v, _)| v.same_file(&file)).count()
    }

    fn fifo(dir: &Path) -> std::path::PathBuf {
        let p = dir.join("pipe.usda");
        let c = std::ffi::CString::new(p.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: mkfifo with a NUL-terminated path.
        #[allow(unsafe_code)]
        let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o600) };
        assert_eq!(rc, 0);
        p
    }

    #[test]
    fn a_fifo_is_refused_without_waiting_for_a_writer() {
        let dir = crate::test_dir::ScratchDir::new("regular-fifo");
        let p = fifo(&dir);
        let e = open_regular(&p).unwrap_err();
        assert_eq!(e.to_string(), NOT_REGULAR);
        assert_eq!(read_regular(&p).unwrap_err().kind(), io::ErrorKind::InvalidInput);
        let e = RegularResolver::new().open_asset(&ResolvedPath::new(&p)).err().unwrap();
        assert_eq!(e.to_string(), NOT_REGULAR);
        #[allow(unsafe_code)]
        let mapped = unsafe { RegularResolver::mapped() };
        assert!(mapped.open_asset(&ResolvedPath::new(&p)).is_err());
        assert_eq!(open_regular(&dir).unwrap_err().kind(), io::ErrorKind::IsADirectory);
        // open(2) of a socket fails with ENXIO: the same words.
        let socket = dir.join("s.usda");
        let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
        assert_eq!(open_regular(&socket).unwrap_err().to_string(), NOT_REGULAR);
        let lock = File::options().write(true).custom_flags(libc::O_NONBLOCK).open(&p);
        assert_eq!(regular_only(lock).unwrap_err().to_string(), NOT_REGULAR);
        assert_eq!(
            open_regular(&dir.join("none")).unwrap_err().kind(),
            io::ErrorKind::NotFound
        );
    }

    #[test]
    fn a_file_read_whole_is_shared_while_held_and_outlives_a_cut_in_place() {
        let dir = crate::test_dir::ScratchDir::new("regular-whole");
        let p = dir.join("a.usda");
        std::fs::write(&p, "#usda 1.0\n").unwrap();
        let before = reads_of(&p);
        let whole = RegularResolver {
            inner: DefaultResolver::new(),
            files: Files::Whole,
        };
        let bytes = |r: &RegularResolver| r.open_asset(&ResolvedPath::new(&p)).unwrap().into_buffer().unwrap();
        let first = bytes(&whole);
        let second = bytes(&whole);
        assert_eq!(&first[..], b"#usda 1.0\n");
        assert_eq!(first.as_ptr(), second.as_ptr(), "the second open copied the file again");
        let reads = || reads_of(&p) - before;
        assert_eq!(reads(), 1);
        // Freeing what nobody holds keeps what somebody does.
        forget_unheld_reads();
        assert_eq!(bytes(&whole).as_ptr(), first.as_ptr());
        assert_eq!(reads(), 1);
        // Cut short and rewritten in place (as `cp` does): what was read stays
        // whole, and the next open reads the new version.
        let f = File::options().write(true).truncate(true).open(&p).unwrap();
        drop(f);
        std::fs::write(&p, "#usda 1.0\n# changed\n").unwrap();
        assert_eq!(&first[..], b"#usda 1.0\n");
        assert_eq!(&bytes(&whole)[..], b"#usda 1.0\n# changed\n");
        assert_eq!(reads(), 2);
        // Once every reader let go, the bytes are freed (the weak
        // reference alone kept the allocation).
        drop((first, second));
        forget_unheld_reads();
        let file = FileId::of(&p).unwrap();
        assert!(READ_WHOLE.lock().unwrap().iter().all(|((v, _), _)| !v.same_file(&file)));
    }

    #[test]
    fn opens_of_one_file_at_once_read_it_once() {
        // Two files of different sizes, each opened by 8 threads at once:
        // the end of one file's read must not end the other's.
        let dir = crate::test_dir::ScratchDir::new("regular-whole-threads");
        let files = [dir.join("a.usda"), dir.join("b.usda")];
        std::fs::write(&files[0], vec![b'#'; 8 << 20]).unwrap();
        std::fs::write(&files[1], vec![b'#'; 32 << 20]).unwrap();
        let before: Vec<usize> = files.iter().map(|p| reads_of(p)).collect();
        let whole = RegularResolver {
            inner: DefaultResolver::new(),
            files: Files::Whole,
        };
        let start = std::sync::Barrier::new(16);
        let opened: Vec<(usize, AssetBuffer)> = std::thread::scope(|s| {
            let reads: Vec<_> = (0..16)
                .map(|k| {
                    let (whole, start, p) = (&whole, &start, &files[k % 2]);
                    s.spawn(move || {
                        start.wait();
                        (
                            k % 2,
                            whole.open_asset(&ResolvedPath::new(p)).unwrap().into_buffer().unwrap(),
                        )
                    })
                })
                .collect();
            reads.into_iter().map(|r| r.join().unwrap()).collect()
        });
        // One read each: every open shares the first one's bytes.
        for (f, p) in files.iter().enumerate() {
            let of_f: Vec<&AssetBuffer> = opened.iter().filter(|(g, _)| *g == f).map(|(_, b)| b).collect();
            assert!(of_f.iter().all(|b| b.as_ptr() == of_f[0].as_ptr()));
            assert_eq!(reads_of(p) - before[f], 1, "{}", p.display());
        }
    }

    #[test]
    fn a_mapped_address_names_its_file_until_another_mapping_takes_its_place() {
        let name = |p: *const libc::c_char| {
            // SAFETY: a NUL-terminated path noted by `note_mapping`.
            #[allow(unsafe_code)]
            unsafe { std::ffi::CStr::from_ptr(p) }.to_str().unwrap().to_string()
        };
        // Addresses no real mapping has (the kernel never maps page 1).
        let base = 0x1000;
        note_mapping(base, 100, Path::new("/a.usdc"));
        assert_eq!(mapped_file_at(base).map(name).as_deref(), Some("/a.usdc"));
        assert_eq!(mapped_file_at(base + 99).map(name).as_deref(), Some("/a.usdc"));
        assert!(mapped_file_at(base + 100).is_none());
        assert!(mapped_file_at(base - 1).is_none());
        note_mapping(base + 50, 100, Path::new("/b.usdc"));
        assert_eq!(mapped_file_at(base + 10).map(name), None);
        assert_eq!(mapped_file_at(base + 149).map(name).as_deref(), Some("/b.usdc"));
        let taken = MAPPED
            .iter()
            .filter(|m| m.start.load(Ordering::Relaxed) == base + 50)
            .count();
        assert_eq!(taken, 1);
    }

    #[test]
    fn regular_files_read_whole_mapped_or_not() {
        let dir = crate::test_dir::ScratchDir::new("regular-file");
        let p = dir.join("a.usda");
        std::fs::write(&p, b"#usda 1.0\n").unwrap();
        assert_eq!(read_regular(&p).unwrap(), b"#usda 1.0\n");
        assert_eq!(read_regular_to_string(&p).unwrap(), "#usda 1.0\n");
        #[allow(unsafe_code)]
        let mapped = unsafe { RegularResolver::mapped() };
        for r in [RegularResolver::new(), mapped] {
            let asset = r.open_asset(&ResolvedPath::new(&p)).unwrap();
            assert_eq!(&*asset.into_buffer().unwrap(), b"#usda 1.0\n");
        }
        let empty = dir.join("e.usda");
        std::fs::write(&empty, b"").unwrap();
        let asset = RegularResolver::new().open_asset(&ResolvedPath::new(&empty)).unwrap();
        assert!(asset.into_buffer().unwrap().is_empty());
        // A link to a regular file is followed, unless asked not to.
        let link = dir.join("l.usda");
        std::os::unix::fs::symlink(&p, &link).unwrap();
        assert_eq!(read_regular(&link).unwrap(), b"#usda 1.0\n");
        assert!(open_regular_with(&link, true).is_err());
    }
}
