//! `painterly._painterly`: the Python bindings, thin over the library.
//!
//! Long work runs with the GIL released (`py.detach`): a bake, an
//! inspection, interpolation, and the pure half of a frame evaluation, so
//! Python threads run them at once. A [`Character`] holds a stage, which is
//! single-threaded (`Rc` inside), so it stays on the thread that opened it
//! (`unsendable`); its reads run with the GIL held, its evaluation without.
//!
//! Inputs are a file path or a usd-core `Sdf.Layer`: C++ objects cannot
//! cross into Rust, so a layer is taken through its text
//! (`ExportToString()`) and opened as if it were its own file
//! ([`painterly::usd_io::memory`]), so relative asset paths still resolve.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Mutex;

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
    /// A layer's text, when given an `Sdf.Layer`.
    text: Option<Vec<u8>>,
    /// How errors name it: the path, or the layer's identifier.
    name: String,
    /// A layer with edits not saved to `path` (`Sdf.Layer.dirty`).
    dirty: bool,
}

impl Source {
    fn from_py(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
        if let Ok(p) = obj.extract::<PathBuf>() {
            let name = p.display().to_string();
            return Ok(Source {
                path: p,
                text: None,
                name,
                dirty: false,
            });
        }
        if obj.hasattr("ExportToString")? {
            let text: String = obj.call_method0("ExportToString")?.extract()?;
            let identifier: String = obj.getattr("identifier")?.extract()?;
            let real: String = obj.getattr("realPath")?.extract().unwrap_or_default();
            // An anonymous layer has no file a bake could be checked against.
            let dirty = real.is_empty() || obj.getattr("dirty")?.extract::<bool>().unwrap_or(true);
            // Served where the layer lives, so its relative asset paths
            // resolve as they would on disk; named .usda since the text is usda.
            let path = if real.is_empty() {
                std::env::current_dir().unwrap_or_default().join("anonymous.usda")
            } else if real.ends_with(".usda") {
                PathBuf::from(&real)
            } else {
                PathBuf::from(format!("{real}.usda"))
            };
            return Ok(Source {
                path,
                text: Some(text.into_bytes()),
                name: identifier,
                dirty,
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
            Some(t) => self.open_text(t),
        }
    }

    /// The layer's text, served at `path`, marked unsaved when it is.
    fn open_text(&self, text: &[u8]) -> painterly::Result<StageReader> {
        let mut r = open_bytes(text.to_vec(), &self.path)?;
        r.unsaved = self.dirty;
        Ok(r)
    }

    /// Like [`Self::open`], but a file is mapped, as the CLI's bake and
    /// inspect read it, so that the two front doors read a file alike: for
    /// a reader dropped before the call returns (bake, inspect).
    fn open_mapped(&self) -> painterly::Result<StageReader> {
        match &self.text {
            None => StageReader::open_mapped(&self.path),
            Some(t) => self.open_text(t),
        }
    }

    /// Errors name the layer's identifier, not where its text was served.
    fn name_in(&self, mut e: painterly::Error) -> painterly::Error {
        if self.text.is_some() && e.file.as_deref() == Some(self.path.as_path()) {
            e.file = Some(PathBuf::from(&self.name));
        }
        e
    }
}

/// How the library's messages name a CLI option, and how Python names it
/// (most specific first): a TD calling `painterly.bake(frames=...)` should
/// not be told to pass `--frames`.
const PYTHON_WORDS: [(&str, &str); 6] = [
    ("`painterly bake --camera PRIM`", "`camera=PRIM`"),
    ("`painterly bake --camera`", "`camera=`"),
    ("pass --frames A:B", "pass frames=(A, B)"),
    ("--frames", "frames"),
    ("--camera", "`camera`"),
    ("--chunk", "`chunk`"),
];

/// `message` with the CLI's option names in their Python spelling.
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
    let text = serde_json::to_string(v).map_err(|e| msg_err(py, format!("cannot encode the result: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// `frames`: None, "A:B:STEP" (as `--frames`), a number, or (start, end[, step]).
fn frames_from_py(py: Python<'_>, frames: Option<&Bound<'_, PyAny>>) -> PyResult<Option<FrameRange>> {
    let Some(f) = frames else { return Ok(None) };
    if f.is_none() {
        return Ok(None);
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
    chunk: Option<usize>,
    camera: Option<String>,
    bake_proxy: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Py<PyAny>> {
    let src = Source::from_py(input)?;
    let opts = BakeOptions {
        frames: frames_from_py(py, frames)?,
        bake_proxy,
        camera,
        chunk,
        ..Default::default()
    };
    if chunk.is_some() && output.is_none() {
        return Err(msg_err(py, "a chunked bake writes files: give an output path"));
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
            Python::attach(|py| {
                if let Err(e) = cb.call1(py, (done, total)) {
                    let mut slot = callback_error.lock().unwrap_or_else(|p| p.into_inner());
                    slot.get_or_insert(e);
                }
            });
        }
    };
    let result = py.detach(|| {
        let summary = bake_with(&src.path, &out_path, &opts, &report, || src.open_mapped())?;
        let text = match &temp {
            Some(_) => Some(
                std::fs::read_to_string(&out_path)
                    .map_err(|e| painterly::Error::msg(format!("cannot read the bake back: {e}")).in_file(&out_path))?,
            ),
            None => None,
        };
        Ok::<_, painterly::Error>((summary, text))
    });
    drop(temp);
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
    let src = Source::from_py(input)?;
    let frames = frames_from_py(py, frames)?;
    let report = py.detach(|| {
        // As the CLI: passing means a bake with the same camera and frames succeeds.
        let mut rep = painterly::inspect::inspect_reader(src.open_mapped()?, camera.as_deref(), frames, &|_, _| {})?;
        if src.text.is_some() {
            rep.file = PathBuf::from(&src.name);
        }
        Ok(rep)
    });
    let report = report.map_err(|e| to_py(py, src.name_in(e)))?;
    Ok(json_to_py(py, &report)?.unbind())
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
    let keys = keys.as_slice()?.to_vec();
    let values = values.as_slice()?.to_vec();
    let queries = queries.as_slice()?.to_vec();
    let out = py.detach(|| -> Result<Vec<f64>, String> {
        let interp = Interpolator::new(method, d, &keys).map_err(|e| e.to_string())?;
        let mut w = vec![0.0; n];
        let mut out = vec![0.0; m * k];
        for q in 0..m {
            interp.weights(&queries[q * d..(q + 1) * d], &mut w);
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
    name: String,
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
        let input = self
            .inner
            .read_frame_with(t, &Self::overrides(configuration))
            .map_err(|e| to_py(py, e))?;
        let model = &self.inner.model;
        py.detach(|| model.evaluate(input, false)).map_err(|e| to_py(py, e))
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
        let inner = src
            .open()
            .and_then(|r| Inner::from_reader(r, camera.as_deref()))
            .map_err(|e| to_py(py, src.name_in(e.in_file(&src.path))))?;
        Ok(Character { inner, name: src.name })
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
        self.inner.configuration(t).map_err(|e| to_py(py, e))
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
            self.name,
            self.inner.model.num_layers(),
            self.inner.axes().len(),
            self.inner.model.views.len()
        )
    }
}

#[pymodule]
fn _painterly(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Character>()?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(inspect, m)?)?;
    m.add_function(wrap_pyfunction!(_interpolate, m)?)?;
    m.add_function(wrap_pyfunction!(_rules, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
