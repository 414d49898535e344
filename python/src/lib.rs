//! `painterly._painterly`: the Python bindings, thin over the library.
//!
//! Long work runs with the GIL released (`py.detach`): a bake, an
//! inspection, interpolation, and the pure half of a frame evaluation, so
//! Python threads run them at once. A [`Character`] holds a stage, which is
//! single-threaded (`Rc` inside), so it stays on the thread that opened it
//! (`unsendable`); its reads run with the GIL held, its evaluation without.
//!
//! Inputs are a file path or a usd-core `Sdf.Layer`. A saved layer is read
//! from its file, as its path would be. C++ objects cannot cross into Rust,
//! so any other layer (edited, anonymous, inside a package) is taken
//! through its text (`ExportToString()`) and opened as if it were its own
//! file ([`painterly::usd_io::memory`]), so relative asset paths still
//! resolve; its bake is stamped unsaved. Layers it composes are read from
//! their files, so one with unsaved edits is refused.
//!
//! A bake runs on a thread of its own while the calling thread waits and
//! runs Python's signal handlers: Ctrl-C stops the bake, writing nothing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use glam::Vec3;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use painterly::bake::{bake_with, BakeOptions};
use painterly::character::{Character as Inner, Configuration};
use painterly::frames::FrameRange;
use painterly::interp::{Interpolator, Method};
use painterly::rule::Rule;
use painterly::usd_io::atomic::TempDir;
use painterly::usd_io::memory::open_bytes;
use painterly::usd_io::stage::StageReader;

// Declared in `painterly` (which re-exports it), so that pickle finds it
// there: a `ProcessPoolExecutor` job can raise it back to its parent.
create_exception!(
    painterly,
    Error,
    PyException,
    "A painterly error: `.message`, and where: `.file`, `.prim`, `.attribute` (None when unknown), `.rule` (the schema rule broken, for problems inspect reports)."
);

/// What a function was given: a file, or a layer's text standing in for one.
struct Source {
    /// The path the stage is opened at (for a layer: where its text is served).
    path: PathBuf,
    /// The text of a layer that is not its file as saved (edited,
    /// anonymous, inside a package): read as unsaved edits.
    text: Option<Vec<u8>>,
    /// How errors name it: the path, or the layer's identifier.
    name: String,
    /// The file it stands for: the path, or the file of a layer whose text
    /// is served elsewhere (an edited `x.usdc` is read as `x.usdc.usda`).
    /// A bake records it and refuses to write over it.
    stands_for: PathBuf,
}

impl Source {
    fn from_py(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
        if let Ok(p) = obj.extract::<PathBuf>() {
            let name = p.display().to_string();
            return Ok(Source {
                stands_for: p.clone(),
                path: p,
                text: None,
                name,
            });
        }
        // A Stage has ExportToString too (its flattened text), but which
        // of its layers and edits was meant is the caller's to say.
        if obj.hasattr("GetRootLayer")? {
            return Err(PyTypeError::new_err(format!(
                "expected a file path or an Sdf.Layer, got {}: pass stage.GetRootLayer() (read as saved), \
                 or stage.Flatten() to include unsaved edits across its layers",
                obj.get_type().name()?
            )));
        }
        if obj.hasattr("ExportToString")? && obj.hasattr("identifier")? {
            let identifier: String = obj.getattr("identifier")?.extract()?;
            let real: String = obj.getattr("realPath")?.extract().unwrap_or_default();
            let anonymous = obj.getattr("anonymous")?.extract::<bool>().unwrap_or(true);
            let dirty = obj.getattr("dirty")?.extract::<bool>().unwrap_or(true);
            // Format arguments make the layer something other than the file read plainly.
            let format_args = obj.call_method0("GetFileFormatArguments")?.is_truthy()?;
            refuse_unsaved_dependencies(obj, &identifier)?;
            // A saved layer is its file: read it as the path would be (what
            // a farm reads, with the file's stamp), not the layer's text,
            // which may predate the file on disk.
            if !anonymous && !dirty && !format_args && !real.is_empty() && Path::new(&real).is_file() {
                refuse_unsaved_inputs(obj.py(), &identifier, || StageReader::open(Path::new(&real)))?;
                return Ok(Source {
                    path: PathBuf::from(&real),
                    stands_for: PathBuf::from(&real),
                    text: None,
                    name: real,
                });
            }
            // A layer of a package (`pkg.usdz[root.usda]`, or an edited
            // package root) served as text beside the package would resolve
            // its relative assets on disk beside it, not in the package.
            let in_package = [&identifier, &real]
                .iter()
                .any(|p| painterly::usd_io::stage::is_package_relative(p) || p.to_ascii_lowercase().ends_with(".usdz"));
            let dependencies: Vec<String> = if in_package {
                obj.call_method0("GetCompositionAssetDependencies")?.extract()?
            } else {
                Vec::new()
            };
            if !dependencies.is_empty() {
                return Err(to_py(
                    obj.py(),
                    painterly::Error::msg(format!(
                        "{identifier} is a layer of a package with unsaved edits or read from inside it, and it \
                         composes {}: painterly would resolve that beside the package on disk, not inside it; \
                         pass the package's path (saved), or stage.Flatten()",
                        dependencies.join(", ")
                    )),
                ));
            }
            let text: String = obj.call_method0("ExportToString")?.extract()?;
            // Served where the layer lives, so its relative asset paths
            // resolve as they would on disk; named .usda since the text is usda.
            let path = if real.is_empty() {
                std::env::current_dir().unwrap_or_default().join("anonymous.usda")
            } else if real.ends_with(".usda") {
                PathBuf::from(&real)
            } else {
                PathBuf::from(format!("{real}.usda"))
            };
            refuse_unsaved_inputs(obj.py(), &identifier, || Source::open_text(text.as_bytes(), &path))?;
            let stands_for = if real.is_empty() {
                path.clone()
            } else {
                PathBuf::from(&real)
            };
            return Ok(Source {
                path,
                stands_for,
                text: Some(text.into_bytes()),
                name: identifier,
            });
        }
        Err(PyTypeError::new_err(format!(
            "expected a file path or an Sdf.Layer, got {}",
            obj.get_type().name()?
        )))
    }

    fn open(&self) -> painterly::Result<StageReader> {
        match &self.text {
            None => StageReader::open(&self.path),
            Some(t) => Self::open_text(t, &self.path),
        }
    }

    /// A layer's text, served at `path`: never the file as saved, so a
    /// bake of it is stamped unsaved.
    fn open_text(text: &[u8], path: &Path) -> painterly::Result<StageReader> {
        let mut r = open_bytes(text.to_vec(), path)?;
        r.unsaved = true;
        Ok(r)
    }

    /// Like [`Self::open`], but a file is read as the CLI's bake and
    /// inspect read it (the mapped stage's buffers, here read whole rather
    /// than mapped: see the module's init), so that the two front doors read
    /// a file alike: for a reader dropped before the call returns (bake,
    /// inspect).
    fn open_mapped(&self) -> painterly::Result<StageReader> {
        match &self.text {
            None => StageReader::open_mapped(&self.path),
            Some(t) => Self::open_text(t, &self.path),
        }
    }

    /// `text` with the path a layer's text was served at replaced by the
    /// layer's identifier: that path is made up (`anonymous.usda` in the
    /// working directory, `x.usdc.usda`), the identifier is what the caller knows.
    fn rename(&self, text: &str) -> String {
        match &self.text {
            Some(_) => text.replace(&self.path.display().to_string(), &self.name),
            None => text.to_string(),
        }
    }

    /// [`Self::rename`] inside JSON text, where both are escaped.
    fn rename_json(&self, json: &str) -> String {
        let escaped = |s: &str| {
            let quoted = serde_json::Value::from(s).to_string();
            quoted[1..quoted.len() - 1].to_string()
        };
        match &self.text {
            Some(_) => json.replace(&escaped(&self.path.display().to_string()), &escaped(&self.name)),
            None => json.to_string(),
        }
    }

    /// Errors name the layer's identifier, not where its text was served.
    fn name_in(&self, mut e: painterly::Error) -> painterly::Error {
        if self.text.is_some()
            && (e.file.as_deref() == Some(self.path.as_path()) || e.file.as_deref() == Some(self.stands_for.as_path()))
        {
            e.file = Some(PathBuf::from(&self.name));
        }
        e.message = self.rename(&e.message);
        e
    }
}

/// Fails when a layer that `layer` composes (a sublayer, reference or
/// payload, at any depth, in variants too) is open in this session with
/// unsaved edits, or is anonymous: painterly reads those from their files,
/// so the edits would be silently ignored. Only layers already loaded are
/// looked at (`Sdf.Layer.Find`); nothing new is opened.
fn refuse_unsaved_dependencies(layer: &Bound<'_, PyAny>, identifier: &str) -> PyResult<()> {
    let py = layer.py();
    let sdf = py.import("pxr.Sdf")?;
    let layers = sdf.getattr("Layer")?;
    let mut seen = std::collections::HashSet::from([identifier.to_string()]);
    let mut todo = vec![layer.clone()];
    while let Some(l) = todo.pop() {
        let anchored = !l.getattr("anonymous")?.extract::<bool>().unwrap_or(true);
        let assets: Vec<String> = l.call_method0("GetCompositionAssetDependencies")?.extract()?;
        for asset in assets {
            let mut id: String = sdf
                .call_method1("ComputeAssetPathRelativeToLayer", (&l, &asset))?
                .extract()?;
            // An anonymous layer's text is served in the working directory,
            // so its relative paths resolve from there.
            if !anchored && !id.starts_with("anon:") && Path::new(&id).is_relative() {
                id = std::env::current_dir()
                    .unwrap_or_default()
                    .join(&id)
                    .display()
                    .to_string();
            }
            let found = layers.call_method1("Find", (&id,))?;
            if found.is_none() {
                continue;
            }
            let dep: String = found.getattr("identifier")?.extract()?;
            if !seen.insert(dep.clone()) {
                continue;
            }
            let (what, lost) = if found.getattr("anonymous")?.extract::<bool>().unwrap_or(true) {
                ("an anonymous layer (only in memory)", "it would be missing")
            } else if found.getattr("dirty")?.extract::<bool>().unwrap_or(true) {
                ("a layer with unsaved edits", "the edits would be ignored")
            } else {
                todo.push(found);
                continue;
            };
            let message = format!(
                "{what} that {identifier} composes (a sublayer, reference or payload): painterly reads \
                 composed layers from their files, so {lost}; save it, or pass stage.Flatten() instead"
            );
            return Err(to_py(py, painterly::Error::msg(message).in_file(Path::new(&dep))));
        }
    }
    Ok(())
}

/// Fails when a layer open in this session with unsaved edits is one of the
/// files the input reads (other than the input's own layer, whose text is
/// read): painterly reads it from its file, so the edits would be ignored.
/// [`refuse_unsaved_dependencies`] walks only layers open in the session;
/// this finds one composed through a layer that is not. The input is read
/// (its files listed) only when some layer is dirty.
fn refuse_unsaved_inputs(
    py: Python<'_>,
    identifier: &str,
    open: impl FnOnce() -> painterly::Result<StageReader>,
) -> PyResult<()> {
    let sdf = py.import("pxr.Sdf")?;
    let mut dirty = Vec::new();
    for layer in sdf.getattr("Layer")?.call_method0("GetLoadedLayers")?.try_iter()? {
        let layer = layer?;
        let anonymous = layer.getattr("anonymous")?.extract::<bool>().unwrap_or(true);
        if anonymous || !layer.getattr("dirty")?.extract::<bool>().unwrap_or(false) {
            continue;
        }
        let id: String = layer.getattr("identifier")?.extract()?;
        let file: String = layer.getattr("realPath")?.extract().unwrap_or_default();
        if id == identifier || file.is_empty() {
            continue;
        }
        if let Ok(canonical) = Path::new(&file).canonicalize() {
            dirty.push((canonical, id));
        }
    }
    if dirty.is_empty() {
        return Ok(());
    }
    let reader = open().map_err(|e| to_py(py, e))?;
    let files = painterly::usd_io::clips::input_files(&reader);
    match dirty.into_iter().find(|(f, _)| files.contains(f)) {
        None => Ok(()),
        Some((_, dep)) => Err(to_py(
            py,
            painterly::Error::msg(format!(
                "a layer with unsaved edits that {identifier} composes (through layers not open here): painterly \
                 reads composed layers from their files, so the edits would be ignored; save it, or pass \
                 stage.Flatten() instead"
            ))
            .in_file(Path::new(&dep)),
        )),
    }
}

/// This process's thread pool for the library's parallel work (binding,
/// skinning, blends). rayon's global pool does not survive `fork()`: a
/// child forked after any painterly call (multiprocessing's default start
/// method on Linux) waited forever on workers it does not have (a review,
/// 2026-12-07). A pool made per process id is made again in a child.
fn pool() -> Option<Arc<rayon::ThreadPool>> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut slot = POOL.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((p, pool)) = &*slot {
        if *p == pid {
            return Some(pool.clone());
        }
    }
    // The parent's pool: its threads are not in this process, so it is
    // never dropped here (that would signal them).
    if let Some(parent) = slot.take() {
        std::mem::forget(parent);
    }
    // A pool that cannot be made (no threads to spare) leaves the work to
    // the global pool, as before.
    let pool = Arc::new(rayon::ThreadPoolBuilder::new().build().ok()?);
    *slot = Some((pid, pool.clone()));
    Some(pool)
}

/// Runs `f` on this process's [`pool`] and waits for it: for work that
/// only computes (a character's binding, a frame). `f` must not touch
/// Python: it runs on a pool thread while the caller waits.
fn in_pool<R>(f: impl FnOnce() -> R) -> R {
    match pool() {
        Some(pool) => install(&pool, f),
        None => f(),
    }
}

/// Runs `f` on a pool of its own, one thread more than the shared
/// [`pool`] (rayon's default: `RAYON_NUM_THREADS`, else the cores), dropped
/// after: for bakes and inspections, whose thread waits on frames the
/// others evaluate. In the shared pool, as many of them at once as it has
/// threads would each hold one thread waiting, and none would be left to
/// evaluate (a deadlock).
fn in_own_pool<R>(f: impl FnOnce() -> R) -> R {
    let threads = pool().map_or(1, |p| p.current_num_threads());
    match rayon::ThreadPoolBuilder::new().num_threads(threads + 1).build() {
        Ok(pool) => install(&pool, f),
        Err(_) => f(),
    }
}

/// `pool.install(f)` for an `f` whose captures and result need not be Send.
fn install<R>(pool: &rayon::ThreadPool, f: impl FnOnce() -> R) -> R {
    // What `f` holds or returns (a stage: `Rc` inside) is not Send; it is
    // still used by one thread at a time: the caller waits, blocked, until
    // the pool thread has finished with it, and takes it back after.
    struct Handover<T>(T);
    // SAFETY: see above: `install` returns only after `f` has run and its
    // result has been moved out of the pool thread, so no value crosses
    // while another thread can reach it.
    unsafe impl<T> Send for Handover<T> {}
    let f = Handover(f);
    let out = pool.install(move || {
        let f = f;
        Handover((f.0)())
    });
    out.0
}

/// How the library's messages name a CLI option, and how Python names it
/// (most specific first): a TD calling `painterly.bake(frames=...)` should
/// not be told to pass `--frames`.
const PYTHON_WORDS: [(&str, &str); 7] = [
    ("`--camera PRIM`", "`camera=PRIM`"),
    ("`--camera`", "`camera=`"),
    ("pass --frames A:B", "pass frames=(A, B)"),
    ("its own --frames A:B", "its own frames=(A, B)"),
    ("--frames", "frames"),
    ("--camera", "`camera`"),
    ("--chunk", "`chunk`"),
];

/// `message` with the CLI's option names in their Python spelling (errors,
/// and the problems `inspect` reports).
fn python_words(message: &str) -> String {
    PYTHON_WORDS
        .iter()
        .fold(message.to_string(), |m, (cli, python)| m.replace(cli, python))
}

/// A painterly error as `painterly.Error`, with its fields as attributes;
/// its message names options as Python spells them.
fn to_py(py: Python<'_>, mut e: painterly::Error) -> PyErr {
    e.message = python_words(&e.message);
    let err = Error::new_err(e.to_string());
    let v = err.value(py);
    let file = e.file.as_ref().map(|f| f.display().to_string());
    // Setting plain attributes on a fresh exception cannot fail.
    let _ = v.setattr("message", &e.message);
    let _ = v.setattr("file", file);
    let _ = v.setattr("prim", e.prim);
    let _ = v.setattr("attribute", e.attribute);
    let _ = v.setattr("rule", e.rule.map(|r| r.id()));
    err
}

fn msg_err(py: Python<'_>, m: impl Into<String>) -> PyErr {
    to_py(py, painterly::Error::msg(m))
}

/// `v` as the dict `json.loads` makes of what the CLI's `--json` prints
/// (straight to text: f32 fields keep their shortest form, as in the CLI).
fn json_to_py<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (json_text(py, v)?,))
}

fn json_text(py: Python<'_>, v: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| msg_err(py, format!("cannot encode the result: {e}")))
}

/// `frames`: None, "A:B:STEP" (as `--frames`), a number, or (start, end[, step]).
fn frames_from_py(py: Python<'_>, frames: Option<&Bound<'_, PyAny>>) -> PyResult<Option<FrameRange>> {
    let Some(f) = frames else { return Ok(None) };
    if f.is_none() {
        return Ok(None);
    }
    // bytes and bytearray extract as sequences of numbers: b"12" read as
    // frames 49:50.
    if f.is_instance_of::<pyo3::types::PyBytes>() || f.is_instance_of::<pyo3::types::PyByteArray>() {
        return Err(PyTypeError::new_err(
            "frames: expected \"A:B:STEP\", a number or (start, end[, step]), not bytes (decode them first)",
        ));
    }
    let text = if let Ok(s) = f.extract::<String>() {
        s
    } else if let Ok(x) = f.extract::<f64>() {
        format!("{x}")
    } else if let Ok(v) = f.extract::<Vec<f64>>() {
        // Not a list of frames: [1, 2, 3] would read as 1:2 step 3.
        if !(2..=3).contains(&v.len()) {
            return Err(msg_err(
                py,
                format!(
                    "frames: a sequence is (start, end) or (start, end, step), not {} numbers; for frames 1, 2 and 3 give (1, 3)",
                    v.len()
                ),
            ));
        }
        v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(":")
    } else {
        return Err(PyTypeError::new_err(
            "frames: expected \"A:B:STEP\", a number or (start, end[, step])",
        ));
    };
    // Named as the caller wrote it: `frames=(5, 1)`, not the CLI's "5:1".
    let written = f.repr().map(|r| r.to_string()).unwrap_or_else(|_| format!("{text:?}"));
    text.parse::<FrameRange>()
        .map(Some)
        .map_err(|e| msg_err(py, format!("frames={written}: {e}")))
}

/// The cancel flags of the bakes running, each with its process id (a
/// forked child inherits the list, not the bakes), for
/// [`_stop_bakes_at_exit`].
static RUNNING: Mutex<Vec<(u32, Arc<AtomicBool>)>> = Mutex::new(Vec::new());

/// A bake's entry in [`RUNNING`], removed when the bake returns (on the
/// calling thread, holding the GIL: past that point the call only returns
/// to Python).
struct Running(Arc<AtomicBool>);

impl Running {
    fn register(cancel: &Arc<AtomicBool>) -> Running {
        RUNNING
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push((std::process::id(), cancel.clone()));
        Running(cancel.clone())
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        RUNNING
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .retain(|(_, c)| !Arc::ptr_eq(c, &self.0));
    }
}

/// Registered with `atexit`: at interpreter exit, a bake still running in
/// a daemon thread (with a progress callback) was cut off inside its call
/// when the interpreter finalized, and the process aborted (a review,
/// 2026-12-07). Every running bake is cancelled, as Ctrl-C cancels it (it
/// stops before its next frame and writes nothing), and waited for, at
/// most 30 s, without the GIL, so that its thread leaves the call first.
#[pyfunction]
fn _stop_bakes_at_exit(py: Python<'_>) {
    // Only this process's: a forked child's copy of its parent's entries
    // names bakes that run in the parent (a review, 2026-12-07: the child
    // waited the whole 30 s).
    let pid = std::process::id();
    let ours = || {
        RUNNING
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .filter(|(p, _)| *p == pid)
            .map(|(_, c)| c.clone())
            .collect::<Vec<_>>()
    };
    for c in ours() {
        c.store(true, Ordering::Relaxed);
    }
    py.detach(|| {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
        while !ours().is_empty() && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    });
}

/// Bakes `input` (a path or an `Sdf.Layer`) and returns the `--json` summary
/// as a dict; without `output`, bakes in memory and the summary's "layer"
/// holds the baked layer's usda text.
#[pyfunction]
#[pyo3(signature = (input, output=None, frames=None, chunk=None, camera=None, bake_proxy=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn bake(
    py: Python<'_>,
    input: &Bound<'_, PyAny>,
    output: Option<PathBuf>,
    frames: Option<&Bound<'_, PyAny>>,
    chunk: Option<i64>,
    camera: Option<String>,
    bake_proxy: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Py<PyAny>> {
    let _freed = ForgetUnheldReads;
    if let Some(cb) = &progress {
        if !cb.bind(py).is_callable() {
            return Err(PyTypeError::new_err(format!(
                "progress must be callable (done, total), got {}",
                cb.bind(py).get_type().name()?
            )));
        }
    }
    // A negative chunk is refused as 0 is ("must be at least 1"), not with
    // the OverflowError an unsigned parameter would raise.
    let chunk = chunk.map(|c| usize::try_from(c).unwrap_or(0));
    let src = Source::from_py(input)?;
    // Set when Ctrl-C reaches the waiting thread: the bake stops before its
    // next frame and before replacing the output, and writes nothing.
    let cancel = Arc::new(AtomicBool::new(false));
    let _running = Running::register(&cancel);
    let opts = BakeOptions {
        frames: frames_from_py(py, frames)?,
        bake_proxy,
        camera,
        chunk,
        cancel: Some(cancel.clone()),
        ..Default::default()
    };
    if chunk.is_some() && output.is_none() {
        return Err(msg_err(py, "a chunked bake writes files: give an output path"));
    }
    // The summary names the output as a str: refuse before baking a name
    // that cannot be one, rather than after writing it.
    if let Some(o) = output.as_deref().filter(|o| o.to_str().is_none()) {
        return Err(to_py(
            py,
            painterly::Error::msg("the output's name is not UTF-8, and the summary names it as text: rename it")
                .in_file(o),
        ));
    }
    // Without an output the bake goes to a temporary folder (removed when
    // dropped, or by the next process if this one dies) and is read back.
    let temp = match &output {
        Some(_) => None,
        None => Some(TempDir::new().map_err(|e| to_py(py, e))?),
    };
    let out_path = match (&output, &temp) {
        (Some(o), _) => o.clone(),
        (None, Some(dir)) => dir.path().join("bake.usda"),
        (None, None) => unreachable!("a temporary folder is made when there is no output"),
    };
    // The first exception a progress callback raised, re-raised after the bake.
    let callback_error: Mutex<Option<PyErr>> = Mutex::new(None);
    let report = |done: usize, total: usize| {
        if let Some(cb) = &progress {
            // Not while the interpreter shuts down (a bake in a daemon
            // thread at exit): attaching then aborted the process.
            let _ = Python::try_attach(|py| {
                if let Err(e) = cb.call1(py, (done, total)) {
                    let mut slot = callback_error.lock().unwrap_or_else(|p| p.into_inner());
                    slot.get_or_insert(e);
                }
            });
        }
    };
    let run = || {
        let summary = bake_with(&src.stands_for, &out_path, &opts, &report, || src.open_mapped())?;
        let text = match &temp {
            Some(_) => Some(
                std::fs::read_to_string(&out_path)
                    .map_err(|e| painterly::Error::msg(format!("cannot read the bake back: {e}")).in_file(&out_path))?,
            ),
            None => None,
        };
        Ok::<_, painterly::Error>((summary, text))
    };
    // The bake runs on its own thread; this one waits without the GIL in
    // short slices and, between them, runs Python's signal handlers, which
    // only the main thread can: Ctrl-C then stops the bake, not only the
    // script after it.
    let result = std::thread::scope(|scope| {
        let (done_tx, mut done_rx) = std::sync::mpsc::channel();
        let worker = scope.spawn(move || {
            let r = in_own_pool(run);
            let _ = done_tx.send(());
            r
        });
        loop {
            // The receiver is moved in and back out: it is not Sync.
            let (rx, waited) = py.detach(move || {
                let w = done_rx.recv_timeout(std::time::Duration::from_millis(50));
                (done_rx, w)
            });
            done_rx = rx;
            if !matches!(waited, Err(std::sync::mpsc::RecvTimeoutError::Timeout)) {
                break;
            }
            if let Err(interrupt) = py.check_signals() {
                cancel.store(true, Ordering::Relaxed);
                // Joined without the GIL: the progress callback may need it.
                let _ = py.detach(move || worker.join());
                return Err(interrupt);
            }
        }
        match py.detach(move || worker.join()) {
            Ok(r) => Ok(r),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    });
    drop(temp);
    let result = result?;
    if let Some(e) = callback_error.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(e);
    }
    let (mut summary, text) = result.map_err(|e| to_py(py, src.name_in(e)))?;
    if src.text.is_some() {
        summary.input = PathBuf::from(&src.name);
    }
    let value = json_to_py(py, &summary)?;
    if let Some(text) = text {
        value.set_item("output", py.None())?;
        value.set_item("layer", text)?;
    }
    Ok(value.unbind())
}

/// The `inspect --json` report of `input` (a path or an `Sdf.Layer`) as a dict.
#[pyfunction]
#[pyo3(signature = (input, camera=None, frames=None))]
fn inspect(
    py: Python<'_>,
    input: &Bound<'_, PyAny>,
    camera: Option<String>,
    frames: Option<&Bound<'_, PyAny>>,
) -> PyResult<Py<PyAny>> {
    let _freed = ForgetUnheldReads;
    let src = Source::from_py(input)?;
    let frames = frames_from_py(py, frames)?;
    let report = py.detach(|| {
        // As the CLI: passing means a bake with the same camera and frames succeeds.
        let mut rep = in_own_pool(|| {
            painterly::inspect::inspect_reader(src.open_mapped()?, camera.as_deref(), frames, &|_, _| {})
        })?;
        if src.text.is_some() {
            rep.file = PathBuf::from(&src.name);
        }
        for p in &mut rep.problems {
            p.message = python_words(&p.message);
        }
        Ok(rep)
    });
    let report = report.map_err(|e| to_py(py, src.name_in(e)))?;
    // Problems and unresolved assets name the layer, not where its text was served.
    let text = src.rename_json(&json_text(py, &report)?);
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

/// Blends `values` (n × k) with the basis weights of `keys` (n × d) at each
/// of `queries` (m × d): out[q] = Σ_i w_i(q) · values[i], summed in key order.
#[pyfunction]
#[pyo3(signature = (keys, values, queries, method="smooth_voronoi", radius=1.0))]
fn _interpolate<'py>(
    py: Python<'py>,
    keys: PyReadonlyArray2<'py, f64>,
    values: PyReadonlyArray2<'py, f64>,
    queries: PyReadonlyArray2<'py, f64>,
    method: &str,
    radius: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let token = match method {
        "smooth_voronoi" | "smoothVoronoi" => "smoothVoronoi",
        "rbf" => "rbf",
        "shepard" => "shepard",
        other => {
            return Err(msg_err(
                py,
                format!("unknown method {other:?} (expected \"smooth_voronoi\", \"rbf\" or \"shepard\")"),
            ))
        }
    };
    let method = Method::from_token(token, radius).ok_or_else(|| msg_err(py, format!("unknown method {token:?}")))?;
    let [n, d] = [keys.shape()[0], keys.shape()[1]];
    let [nv, k] = [values.shape()[0], values.shape()[1]];
    let [m, dq] = [queries.shape()[0], queries.shape()[1]];
    if nv != n {
        return Err(msg_err(py, format!("{n} keys but {nv} values: one value per key")));
    }
    if dq != d {
        return Err(msg_err(py, format!("queries have {dq} coordinates, the keys have {d}")));
    }
    if n > 0 && d == 0 {
        return Err(msg_err(py, "the keys have no coordinates"));
    }
    // As numpy: an answer that cannot be allocated is a MemoryError, not an
    // abort of the interpreter.
    let mut out = Vec::new();
    if m.checked_mul(k).is_none_or(|len| out.try_reserve_exact(len).is_err()) {
        return Err(pyo3::exceptions::PyMemoryError::new_err(format!(
            "cannot allocate the answer: {m} queries × {k} values per key"
        )));
    }
    out.resize(m * k, 0.0);
    let keys = keys.as_slice()?.to_vec();
    let values = values.as_slice()?.to_vec();
    let queries = queries.as_slice()?.to_vec();
    let out = py.detach(move || -> Result<Vec<f64>, String> {
        let interp = Interpolator::new(method, d, &keys).map_err(|e| e.to_string())?;
        let mut w = vec![0.0; n];
        let mut out = out;
        for q in 0..m {
            let x = &queries[q * d..(q + 1) * d];
            interp.weights(x, &mut w);
            if let Some(problem) = painterly::interp::query_problem(x, &w) {
                return Err(format!("query {q} {problem}"));
            }
            let row = &mut out[q * k..(q + 1) * k];
            for (i, &wi) in w.iter().enumerate() {
                for (o, &v) in row.iter_mut().zip(&values[i * k..(i + 1) * k]) {
                    *o += wi * v;
                }
            }
        }
        Ok(out)
    });
    let out = out.map_err(|e| msg_err(py, e))?;
    PyArray1::from_vec(py, out).reshape([m, k])
}

/// The schema rules inspect checks: (id, validator name, doc).
#[pyfunction]
fn _rules() -> Vec<(&'static str, &'static str, &'static str)> {
    Rule::ALL.iter().map(|r| (r.id(), r.validator(), r.doc())).collect()
}

/// A painted character opened once for evaluation (rigs, bindings,
/// cameras, view meshes resolved); frames are read and evaluated on demand.
#[pyclass(unsendable, module = "painterly")]
struct Character {
    inner: Inner,
    /// What its input was, without a layer's text: errors of later frames
    /// name the layer, as the constructor's do.
    source: Source,
}

/// A time code must be a number: NaN would read every sample as held.
fn finite_time(py: Python<'_>, t: f64) -> PyResult<()> {
    if t.is_finite() {
        Ok(())
    } else {
        Err(msg_err(py, format!("time {t} is not a finite number")))
    }
}

fn points_array<'py>(py: Python<'py>, points: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = points.iter().flat_map(|p| p.to_array()).collect();
    PyArray1::from_vec(py, flat).reshape([points.len(), 3])
}

impl Character {
    fn overrides(configuration: Option<BTreeMap<String, f64>>) -> Configuration {
        configuration.unwrap_or_default()
    }

    fn frame(
        &self,
        py: Python<'_>,
        t: f64,
        configuration: Option<BTreeMap<String, f64>>,
    ) -> PyResult<painterly::character::FrameOutput> {
        finite_time(py, t)?;
        let overrides = Self::overrides(configuration);
        let input = in_pool(|| self.inner.read_frame_with(t, &overrides)).map_err(|e| self.error(py, e))?;
        let model = &self.inner.model;
        py.detach(|| in_pool(|| model.evaluate(input, false)))
            .map_err(|e| self.error(py, e))
    }

    /// A library error as `painterly.Error`, naming this character's file
    /// when the error names none (an override, a frame that fails).
    fn error(&self, py: Python<'_>, e: painterly::Error) -> PyErr {
        to_py(py, self.source.name_in(e.in_file(&self.source.path)))
    }

    fn layer_paths(&self) -> Vec<String> {
        self.inner
            .model
            .rigs
            .iter()
            .flat_map(|r| r.layers.iter().map(|l| l.path.clone()))
            .collect()
    }
}

#[pymethods]
impl Character {
    #[new]
    #[pyo3(signature = (input, camera=None))]
    fn new(py: Python<'_>, input: &Bound<'_, PyAny>, camera: Option<String>) -> PyResult<Self> {
        let src = Source::from_py(input)?;
        let inner = in_pool(|| src.open().and_then(|r| Inner::from_reader(r, camera.as_deref())))
            .map_err(|e| to_py(py, src.name_in(e.in_file(&src.path))))?;
        // The text is no longer needed, only that there was one.
        let source = Source {
            text: src.text.as_ref().map(|_| Vec::new()),
            ..src
        };
        Ok(Character { inner, source })
    }

    /// Stroke layer prim paths, in bake order.
    #[getter]
    fn layers(&self) -> Vec<String> {
        self.layer_paths()
    }

    /// Axis prim paths (the keys of `configuration(t)`).
    #[getter]
    fn axes(&self) -> Vec<String> {
        self.inner.axes()
    }

    /// View-dependent mesh prim paths.
    #[getter]
    fn view_meshes(&self) -> Vec<String> {
        self.inner.model.views.iter().map(|v| v.path.clone()).collect()
    }

    /// Every axis's value at `t` (axis path → value, in axis units).
    fn configuration(&self, py: Python<'_>, t: f64) -> PyResult<BTreeMap<String, f64>> {
        finite_time(py, t)?;
        in_pool(|| self.inner.configuration(t)).map_err(|e| self.error(py, e))
    }

    /// Points at `t` (prim path → float32 (N, 3)): every stroke layer in its
    /// prim's local space and every view-dependent mesh; exactly what a bake
    /// writes. `configuration` overrides axis values (axis path → value).
    #[pyo3(signature = (t, configuration=None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        t: f64,
        configuration: Option<BTreeMap<String, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let out = self.frame(py, t, configuration)?;
        let d = PyDict::new(py);
        for (path, layer) in self.layer_paths().into_iter().zip(&out.layers) {
            d.set_item(path, points_array(py, &layer.points)?)?;
        }
        for (view, points) in self.inner.model.views.iter().zip(&out.views) {
            d.set_item(&view.path, points_array(py, points)?)?;
        }
        Ok(d)
    }

    /// Per-curve opacities at `t` (layer path → float32 (curves,)): what a
    /// bake writes as `primvars:displayOpacity`.
    #[pyo3(signature = (t, configuration=None))]
    fn opacities<'py>(
        &self,
        py: Python<'py>,
        t: f64,
        configuration: Option<BTreeMap<String, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let out = self.frame(py, t, configuration)?;
        let d = PyDict::new(py);
        for (path, layer) in self.layer_paths().into_iter().zip(out.layers) {
            d.set_item(path, PyArray1::from_vec(py, layer.opacity))?;
        }
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "painterly.Character({:?}: {} layers, {} axes, {} view-dependent meshes)",
            self.source.name,
            self.inner.model.num_layers(),
            self.inner.axes().len(),
            self.inner.model.views.len()
        )
    }
}

/// As a call returns (or raises), frees the files it read whole that
/// nothing holds any more: a long-lived host would otherwise keep its last
/// input in memory until its next call.
struct ForgetUnheldReads;

impl Drop for ForgetUnheldReads {
    fn drop(&mut self) {
        painterly::usd_io::regular::forget_unheld_reads();
    }
}

#[pymodule]
fn _painterly(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A mapped input cut short under a bake raises a bus error, which ends
    // the host process: the CLI reports it from its own handler, a library
    // must not install one, so files are read whole instead.
    painterly::usd_io::regular::read_instead_of_mapping();
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Character>()?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(inspect, m)?)?;
    m.add_function(wrap_pyfunction!(_interpolate, m)?)?;
    m.add_function(wrap_pyfunction!(_rules, m)?)?;
    let stop = wrap_pyfunction!(_stop_bakes_at_exit, m)?;
    m.py().import("atexit")?.call_method1("register", (stop,))?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
