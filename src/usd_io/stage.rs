//! A composed stage plus the file it came from, with readers that fail with
//! errors naming the prim and attribute.
//!
//! Everything painterly reads goes through here, so "which file, which prim,
//! which attribute" is attached in one place.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::DMat4;
use openusd::gf;
use openusd::sdf::{self, Value};
use openusd::usd::{self, TimeCode};
use openusd_schemas::geom::{XformCache, Xformable, XformableExt};

use super::compose_watch;
use super::crate_samples::CrateSamples;
use super::guard::Guard;
use super::values;
use crate::error::{Error, Result};

/// A prim of an opened stage (a handle: cheap to clone, tied to its stage's thread).
pub type Prim = usd::Prim;

/// `painterly:` attributes the schema declares `uniform`: painterly reads
/// only their default value (the attributes of Painterly typed prims are
/// all uniform too). Checked against `schemas/painterly/schema.usda`.
pub const PAINTERLY_UNIFORM: [&str; 7] = [
    "painterly:restTime",
    "painterly:restPoints",
    "painterly:bindVertices",
    "painterly:bindWeights",
    "painterly:interpolation",
    "painterly:rbfRadius",
    "painterly:uncovered",
];

/// A read value, unless it is none or a block (which withholds a value).
fn present(v: Option<Value>) -> Option<Value> {
    v.filter(|v| !matches!(v, Value::None | Value::ValueBlock))
}

/// usd-core holds a sample up to a blocked sample after it (a block
/// withholds values from its own time to the next sample, and never
/// interpolates); openusd 0.8 gives no value there. When `t` lies strictly
/// between two of the sorted sample `times`, the lower one's time, whose
/// value then stands (the caller reads it when openusd gave none at `t`).
fn held_before_block(times: &[f64], t: f64) -> Option<f64> {
    let after = times.partition_point(|&s| sdf::compare_sample_times(s, t).is_le());
    match (after.checked_sub(1).map(|i| times[i]), times.get(after)) {
        (Some(lower), Some(_)) if sdf::compare_sample_times(lower, t).is_lt() => Some(lower),
        _ => None,
    }
}

/// `prim`'s local transform at `time` and whether it resets the transform
/// stack, as openusd-schemas' `XformQuery` evaluates it (ops from the back,
/// an op beside its own inverse skipped with it), except that an op whose
/// value openusd withholds between a sample and a block after it is read
/// at that sample ([`held_before_block`]), as usd-core holds it.
fn local_transform_held(prim: &usd::Prim, time: f64) -> std::result::Result<(gf::Matrix4d, bool), String> {
    let Some(x) = Xformable::from_prim(prim.clone()).map_err(|e| e.to_string())? else {
        return Ok((gf::Matrix4d::IDENTITY, false));
    };
    let (ops, resets) = x.ordered_xform_ops().map_err(|e| e.to_string())?;
    let mut m = gf::Matrix4d::IDENTITY;
    let mut rev = ops.iter().rev().peekable();
    while let Some(op) = rev.next() {
        if rev
            .peek()
            .is_some_and(|next| next.attribute() == op.attribute() && next.is_inverse_op() != op.is_inverse_op())
        {
            rev.next();
            continue;
        }
        // An op of no known kind is the identity, its value never read (a
        // damaged file's undecodable samples stay unread, as usd-core's do).
        if op.kind().is_none() {
            continue;
        }
        let attr = op.attribute();
        let value = attr.get_at::<Value>(TimeCode::new(time)).map_err(|e| e.to_string())?;
        let at = match present(value) {
            Some(_) => time,
            None => held_before_block(&attr.time_sample_times().map_err(|e| e.to_string())?, time).unwrap_or(time),
        };
        m = m * op.op_transform(TimeCode::new(at)).map_err(|e| e.to_string())?;
    }
    Ok((m, resets))
}

/// `v` converted by `convert`, or an error naming the type `expected`.
pub(crate) fn convert_typed<T>(
    prim: &usd::Prim,
    name: &str,
    expected: &str,
    v: &Value,
    convert: impl Fn(&Value) -> Option<T>,
) -> Result<T> {
    convert(v).ok_or_else(|| {
        Error::attr(
            prim.path(),
            name,
            format!("expected {expected}, found {}", values::kind_name(v)),
        )
        .rule(crate::rule::Rule::AttributeType)
    })
}

/// An attribute read at many times (per frame): openusd's query, reading
/// as usd-core reads a sample held up to a block ([`held_before_block`]).
/// The sample times are read only when openusd gives no value (asking for
/// them up front decodes a whole point cache).
pub struct HeldQuery {
    query: usd::AttributeQuery,
    times: std::sync::OnceLock<std::result::Result<Vec<f64>, String>>,
}

impl HeldQuery {
    pub fn new(prim: &usd::Prim, name: &str) -> Result<Self> {
        Ok(HeldQuery {
            query: usd::AttributeQuery::new(&prim.attribute(name)),
            times: std::sync::OnceLock::new(),
        })
    }

    /// The value at `t` (`None` where there is none, or a block withholds it).
    pub fn get_at(&self, t: f64) -> std::result::Result<Option<Value>, String> {
        let read = |t: f64| -> std::result::Result<Option<Value>, String> {
            self.query
                .get_at::<Value>(TimeCode::new(t))
                .map(present)
                .map_err(|e| e.to_string())
        };
        match read(t)? {
            None => held_before_block(self.times()?, t).map_or(Ok(None), read),
            v => Ok(v),
        }
    }

    /// The authored sample times.
    pub fn times(&self) -> std::result::Result<&[f64], String> {
        self.times
            .get_or_init(|| self.query.time_sample_times().map_err(|e| e.to_string()))
            .as_deref()
            .map_err(Clone::clone)
    }
}

/// An opened, composed USD stage.
pub struct StageReader {
    /// The composed stage (sublayers, references and payloads resolved).
    pub stage: usd::Stage,
    /// The root layer's path, as given by the user.
    pub file: PathBuf,
    /// Sublayers, references and payloads that did not resolve or could not
    /// be read (usd-core warns and composes without them).
    pub unresolved: Vec<UnresolvedAsset>,
    /// SHA-256 over the stage's layer files, once computed
    /// ([`super::clips::input_hash`]): a chunked bake needs it more than once.
    pub input_hash: std::sync::OnceLock<String>,
    /// Every file the stage reads, once listed ([`super::clips::input_files`]):
    /// the output check and the input's hash both need it.
    pub input_files: std::sync::OnceLock<std::collections::BTreeSet<PathBuf>>,
    /// Each file composition read, as it was just before it was read: what
    /// [`StageReader::check_unchanged`] compares with.
    pub opened: super::guard::OpenedFiles,
    /// Whether the layers are mapped files on disk, unedited, for one
    /// command ([`StageReader::open_mapped`]): only then are time samples read
    /// straight from the files ([`super::crate_samples`]) and fixed world
    /// transforms kept ([`StageReader::local_to_world`]).
    pub mapped: bool,
    /// World transforms of a mapped stage by prim, once computed: `None`
    /// where an op of the prim or an ancestor may vary in time. A bake asks
    /// for every stroke layer's transform every frame.
    pub(crate) fixed_transforms: Mutex<HashMap<sdf::Path, Option<DMat4>>>,
    /// The root layer's text came from memory, with edits not saved to
    /// `file` (the Python package's dirty `Sdf.Layer`): a bake's
    /// `inputStamp` then says so ([`super::clips::input_stamp`]), since the
    /// file on disk is not what was baked.
    pub unsaved: bool,
    /// Whether a layer of the stage may author a spline (its bytes, as the
    /// guard saw them): only then are reads checked for one.
    pub(crate) splines: bool,
    /// Attributes (prim path, name) whose value no spline gives, once
    /// checked ([`StageReader::refuse_spline`]): a bake reads some every frame.
    pub(crate) no_spline: Mutex<std::collections::HashSet<(sdf::Path, String)>>,
}

/// A sublayer, reference or payload whose asset (or target prim) is missing.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnresolvedAsset {
    /// The asset path, anchored at the layer that authors it (the file
    /// that was looked for).
    pub asset: String,
    /// `sublayer`, `reference` or `payload`.
    pub arc: String,
    /// The prim that authors the arc (None for sublayers).
    pub prim: Option<String>,
    /// The layer that authors it.
    pub layer: String,
    /// Why it did not resolve.
    pub reason: String,
}

impl UnresolvedAsset {
    /// One line for messages: `reference @a.usda@ on /Char (in shot.usda): not found`.
    pub fn describe(&self) -> String {
        let on = self.prim.as_deref().map(|p| format!(" on {p}")).unwrap_or_default();
        format!("{} @{}@{on} (in {}): {}", self.arc, self.asset, self.layer, self.reason)
    }

    /// The same without the prim (for messages that name it already).
    pub fn describe_asset(&self) -> String {
        format!("{} @{}@ (in {}): {}", self.arc, self.asset, self.layer, self.reason)
    }
}

/// Stage-level metadata a bake copies into its output layer.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StageMetadata {
    pub start_time_code: Option<f64>,
    pub end_time_code: Option<f64>,
    pub time_codes_per_second: Option<f64>,
    pub frames_per_second: Option<f64>,
    pub up_axis: Option<String>,
    pub meters_per_unit: Option<f64>,
    /// Fields that are authored but are not numbers (their names).
    pub malformed: Vec<String>,
}

impl StageMetadata {
    /// Checks the values painterly uses and copies into what it writes:
    /// finite time codes and rates, positive rates, a finite metersPerUnit.
    /// usd-core cannot open a layer holding `nan` or `inf` there.
    pub fn validate(&self) -> Result<()> {
        if let Some(k) = self.malformed.first() {
            return Err(Error::msg(format!("the stage's {k} is not a number")));
        }
        let finite = [
            ("startTimeCode", self.start_time_code),
            ("endTimeCode", self.end_time_code),
            ("timeCodesPerSecond", self.time_codes_per_second),
            ("framesPerSecond", self.frames_per_second),
            ("metersPerUnit", self.meters_per_unit),
        ];
        for (k, v) in finite {
            if let Some(v) = v {
                if !v.is_finite() {
                    return Err(Error::msg(format!(
                        "the stage's {k} is {v}; it must be a finite number"
                    )));
                }
            }
        }
        for (k, v) in [
            ("timeCodesPerSecond", self.time_codes_per_second),
            ("framesPerSecond", self.frames_per_second),
            ("metersPerUnit", self.meters_per_unit),
        ] {
            if let Some(v) = v {
                if v <= 0.0 {
                    return Err(Error::msg(format!("the stage's {k} is {v}; it must be positive")));
                }
            }
        }
        // UsdGeom's two up axes; a bake would copy any other into its layer.
        if let Some(up) = self.up_axis.as_deref().filter(|u| !matches!(*u, "Y" | "Z")) {
            return Err(Error::msg(format!(
                "the stage's upAxis is {up:?}; it must be \"Y\" or \"Z\""
            )));
        }
        Ok(())
    }
}

/// How many missing assets [`StageReader::require_resolved`]'s error names.
pub const LISTED_MISSING: usize = 10;

/// The default resolver, handing out read-only memory mappings of files
/// instead of reading them (whole buffers, in the Python package: see
/// [`super::regular::read_instead_of_mapping`]). For readers that live for one command (a bake,
/// an assembly, a provenance read): the only ones that may use it.
pub(crate) fn mapped_resolver() -> super::regular::RegularResolver {
    // SAFETY (the promise `map_files` asks for: a mapped file is not modified
    // while mapped): painterly and usd-core replace the files they write by
    // rename, never writing into one (`--in-place` edits too), so a mapping
    // keeps its bytes for the command's duration. A program truncating an
    // input in place under a running bake is the documented exception
    // (README, Limits).
    #[allow(unsafe_code)]
    unsafe {
        super::regular::RegularResolver::mapped()
    }
}

/// Checks that `path`, the command's `what` ("input", "bake layer"), is a
/// file before anything is read: a missing file, a folder and a device
/// each get their own words.
pub fn require_file(path: &Path, what: &str) -> Result<()> {
    let why = match std::fs::metadata(path) {
        Ok(m) if m.is_file() => return Ok(()),
        Ok(m) if m.is_dir() => "it is a folder, not a USD file".to_string(),
        Ok(_) => super::regular::NOT_REGULAR.to_string(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => "no such file".to_string(),
        Err(e) => e.to_string(),
    };
    Err(Error::msg(format!("cannot open {what}: {why}")).in_file(path))
}

/// [`StageReader::check_unchanged`] over files noted when read (a copy of
/// [`StageReader::opened`], for threads the reader cannot go to).
pub fn check_unchanged(opened: &super::guard::OpenedFiles) -> Result<()> {
    for (file, id) in opened {
        if super::guard::FileId::of(file).as_ref() != Some(id) {
            return Err(Error::msg(
                "changed while painterly read it (saved during this run?): what was read is not what the \
                 file now holds; run again once it is saved",
            )
            .in_file(file));
        }
    }
    Ok(())
}

/// When a file of `opened` has changed since it was read, the error that
/// says so, with `failure` (what reading met) after it: a save in progress
/// reads as a damaged file, and "run again once it is saved" is what helps.
fn changed_while_read(opened: &super::guard::OpenedFiles, failure: &str) -> Option<Error> {
    let mut e = check_unchanged(opened).err()?;
    e.message = format!("{} ({failure})", e.message);
    Some(e)
}

/// Checks that `path`, given by the user as `option` (`--camera`,
/// `--layer`), is an absolute prim path: usd-core's `GetPrimAtPath` finds no
/// prim at a property path (`/Cam.focalLength`), a variant selection
/// (`/Cam{v=x}`) or a relative path, where openusd would give the prim the
/// path ends in. A usage error (exit 2) naming the option and the path.
pub fn check_prim_path(option: &str, path: &str) -> Result<()> {
    let refuse = |what: String| Err(Error::usage(format!("{option} {path} {what}")));
    let p = match sdf::Path::new(path) {
        Ok(p) => p,
        Err(e) => return refuse(format!("is not a prim path: {e}")),
    };
    if p.is_abs_root() {
        refuse("is the pseudo-root, not a prim path".into())
    } else if !p.is_abs() {
        refuse("is a relative path, not an absolute prim path (one starting with /)".into())
    } else if p.is_property_path() {
        refuse("is a property path, not a prim path".into())
    } else if p.contains_prim_variant_selection() {
        refuse("is a variant selection path, not a prim path".into())
    } else if !p.is_prim_path() {
        refuse("is not a prim path".into())
    } else {
        Ok(())
    }
}

/// What keeps usd-core from opening a root layer in a package file.
#[derive(Debug, PartialEq)]
enum PackageFault {
    /// No file header at the start (not a zip archive, or bytes before its
    /// first file): usd-core reads a package's files from its start.
    NoFirstFile,
    /// The first file is no USD layer: why, in words.
    FirstFile(String),
}

/// The name of the first file of the zip archive whose first bytes are
/// `head`: the name in the local file header at offset 0, the file
/// usd-core opens as a package's root layer (it reads a package from its
/// start, not from the central directory at its end). `None` without a
/// header there.
fn first_file_name(head: &[u8]) -> Option<String> {
    let header = head.get(..30).filter(|h| h.starts_with(b"PK\x03\x04"))?;
    let len = usize::from(u16::from_le_bytes([header[26], header[27]]));
    head.get(30..30 + len).map(|n| String::from_utf8_lossy(n).into_owned())
}

/// The file behind a layer identifier: the package for a layer inside one
/// (`pkg.usdz[inner.usda]`, nested `a.usdz[b.usdz[c.usda]]`), else the
/// identifier itself. As usd-core's `Ar.IsPackageRelativePath`, only an
/// identifier ending in `]` is package-relative: a folder `take[2]/` is not.
pub fn package_file(id: &str) -> &str {
    if !id.ends_with(']') {
        return id;
    }
    let mut depth = 0usize;
    for (i, b) in id.bytes().enumerate().rev() {
        match b {
            b']' => depth += 1,
            b'[' => {
                depth -= 1;
                if depth == 0 {
                    return &id[..i];
                }
            }
            _ => {}
        }
    }
    id
}

/// Whether `id` names a layer inside a package ([`package_file`]).
pub fn is_package_relative(id: &str) -> bool {
    package_file(id).len() != id.len()
}

/// Whether `name`'s extension is `ext`, in any case (usd-core finds a file
/// format by its extension without case).
fn has_extension(name: &str, ext: &str) -> bool {
    Path::new(name).extension().is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// What keeps usd-core from opening the package `package` (a `.usdz` file),
/// whose root layer is its first file (Sdf.Layer.FindOrOpen gives None and
/// Usd.Stage.Open fails otherwise), where openusd would open the first USD
/// layer it lists, wherever it is. A package whose first file is a
/// package (usd-core then opens that one's first file) is refused too:
/// openusd would read another layer, and reads the same package through a
/// sublayer or a reference. `None` for a file that is not a `.usdz` or
/// cannot be read (openusd says why).
fn package_fault(package: &Path) -> Option<PackageFault> {
    use std::io::Read;
    if !has_extension(&package.to_string_lossy(), "usdz") {
        return None;
    }
    // A local file header is 30 bytes and a name (at most 65535 bytes).
    let mut head = Vec::new();
    super::regular::open_regular(package)
        .ok()?
        .take(30 + 65535)
        .read_to_end(&mut head)
        .ok()?;
    let Some(first) = first_file_name(&head) else {
        return Some(PackageFault::NoFirstFile);
    };
    let why = if ["usda", "usdc", "usd"].iter().any(|e| has_extension(&first, e)) {
        return None;
    } else if has_extension(&first, "usdz") {
        format!(
            "the package's first file is {first}, another package; usd-core would open that \
             package's first file as the root layer, painterly reads only a package whose first file \
             is a .usda, .usdc or .usd layer"
        )
    } else {
        format!(
            "the package's first file is {first}, not a USD layer; usd-core opens the first file as \
             the package's root layer"
        )
    };
    Some(PackageFault::FirstFile(why))
}

/// Refuses the package `package` when usd-core would open no root layer
/// from it, or another one than openusd ([`package_fault`]). `opened`: the
/// package was read already, so openusd took it for a zip archive (else
/// one that is none is left to openusd to name).
fn check_package(package: &Path, opened: bool) -> Result<()> {
    match package_fault(package) {
        None => Ok(()),
        Some(PackageFault::NoFirstFile) if !opened => Ok(()),
        Some(PackageFault::NoFirstFile) => Err(Error::msg(
            "the package does not begin with a file; usd-core reads a package from its start \
             and opens the first file as its root layer",
        )
        .in_file(package)),
        Some(PackageFault::FirstFile(why)) => Err(Error::msg(why).in_file(package)),
    }
}

/// Whether two paths name one existing file (through links and `..`):
/// how every "would overwrite" check compares an output with what it must
/// not replace.
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b)
}

impl StageReader {
    /// Opens and composes `path` (`.usda`, `.usdc` or `.usdz`), reading
    /// every layer into memory: for readers that live on while the user may
    /// rewrite the files (the preview, the Python API).
    pub fn open(path: &Path) -> Result<Self> {
        let path_str = Self::checked_input(path)?;
        Self::compose(path, path_str, super::regular::RegularResolver::new())
    }

    /// Opens and composes `path` over read-only memory mappings of its
    /// layers, so a bake touches only the pages it reads, and lets time
    /// samples be read straight from the files ([`Self::crate_samples`]).
    /// For one command's duration (a bake, an assembly), as usd-core maps
    /// crate files.
    pub fn open_mapped(path: &Path) -> Result<Self> {
        let path_str = Self::checked_input(path)?;
        Ok(StageReader {
            mapped: true,
            ..Self::compose(path, path_str, mapped_resolver())?
        })
    }

    /// `path` as a string, when it names a regular file.
    fn checked_input(path: &Path) -> Result<&str> {
        require_file(path, "input")?;
        path.to_str()
            .ok_or_else(|| Error::msg("input path is not valid UTF-8").in_file(path))
    }

    /// Opens and composes the layer `identifier` through `resolver` (see
    /// [`super::memory`]), with the checks of [`StageReader::open`]; errors
    /// name `path`.
    pub fn compose<R: openusd::ar::Resolver + 'static>(path: &Path, identifier: &str, resolver: R) -> Result<Self> {
        // A package's root layer is its first file, for usd-core.
        check_package(Path::new(identifier), false)?;
        // Every layer passes the composition guard (nesting, namespace depth,
        // inherit cycles) before openusd parses or composes it, and openusd
        // runs under watch (panics, crashes, time limit).
        let guard = Guard::default();
        let first_problem = |e: Error| guard.problems().into_iter().next().unwrap_or(e).in_file(path);
        // A file saved while it was read reads as damaged: say so.
        let unreadable = |e: String| {
            // An empty root has nothing else to fail on; openusd's words for
            // it are about the first structure it could not read.
            let e = match is_empty_file(path) {
                true => format!("cannot read USD file: {EMPTY_FILE}"),
                false => format!("cannot read USD file: {e}"),
            };
            changed_while_read(&guard.opened_files(), &e).unwrap_or_else(|| first_problem(Error::msg(e)))
        };
        let stage = compose_watch::watched(path, || {
            let stage = usd::Stage::builder()
                .schema_registry(openusd_schemas::schema_registry())
                .resolver(guard.resolver_over(resolver))
                .open(identifier)
                .map_err(|e| unreadable(with_causes(&e)))?;
            // The root layer stack is parsed but nothing is composed yet.
            for id in stage.layer_identifiers() {
                if let Some(layer) = stage.layer(&id) {
                    guard.check_layer(&id, layer.data()).map_err(|e| e.in_file(path))?;
                }
            }
            guard.start_composing();
            // Compose every prim now (inactive and abstract ones too), so every
            // referenced layer is loaded, and checked, here. The pseudo-root must
            // be readable; a truncated crate file can open lazily and only fail here.
            stage
                .traverse(usd::PrimPredicate::ALL, |_| {})
                .map_err(|e| unreadable(with_causes(&e)))?;
            Ok(stage)
        })?;
        if let Some(e) = guard.problems().into_iter().next() {
            return Err(e.in_file(path));
        }
        // Every package the stage reads as a whole (the input, or one
        // sublayered or referenced by its bare path): `pkg.usdz[inner.usda]`
        // names a layer inside a package, which is no package's root.
        for id in stage.layer_identifiers() {
            if has_extension(&id, "usdz") && !is_package_relative(&id) {
                let id = Path::new(&id);
                check_package(if same_file(id, path) { path } else { id }, true)?;
            }
        }
        let unresolved = unresolved_assets(&stage);
        Ok(StageReader {
            splines: guard.may_hold_splines(),
            no_spline: Mutex::default(),
            stage,
            file: path.to_path_buf(),
            unresolved,
            input_hash: std::sync::OnceLock::new(),
            input_files: std::sync::OnceLock::new(),
            opened: guard.opened_files(),
            mapped: false,
            fixed_transforms: Mutex::default(),
            unsaved: false,
        })
    }

    /// Fails naming the first file composition read that has changed since
    /// (saved while this command ran): a bake's provenance, a chunk's input
    /// hash or a second open of the input would describe another version
    /// than the one read.
    pub fn check_unchanged(&self) -> Result<()> {
        check_unchanged(&self.opened)
    }

    /// Fails naming the missing sublayers, references and payloads (the
    /// first [`LISTED_MISSING`], and how many more): a bake
    /// or edit of a stage with a missing asset would silently differ from
    /// what its author sees.
    /// A file that exists but lacks the referenced prim contributes
    /// nothing, for usd-core too: that is not refused here (inspect lists it).
    pub fn require_resolved(&self) -> Result<()> {
        let missing: Vec<UnresolvedAsset> = self
            .unresolved
            .iter()
            .filter(|u| u.reason == "not found" || u.reason.starts_with("cannot be read"))
            .cloned()
            .collect();
        match missing.as_slice() {
            [] => Ok(()),
            [one] => Err(Error::msg(format!("missing asset: {}", one.describe()))),
            all => {
                // A stage naming thousands of missing files would make a
                // message of megabytes, on one line: the first few say
                // what is wrong, inspect lists every one.
                let listed: Vec<String> = all.iter().take(LISTED_MISSING).map(UnresolvedAsset::describe).collect();
                let more = match all.len() - listed.len() {
                    0 => String::new(),
                    n => format!("; and {n} more (inspect lists every one)"),
                };
                Err(Error::msg(format!(
                    "{} missing assets: {}{more}",
                    all.len(),
                    listed.join("; ")
                )))
            }
        }
    }

    /// Every prim path in namespace (depth-first) order.
    pub fn prim_paths(&self) -> Result<Vec<String>> {
        let mut out = Vec::new();
        self.stage
            .traverse(usd::PrimPredicate::DEFAULT, |p| out.push(p.as_str().to_string()))
            .map_err(|e| Error::msg(format!("cannot traverse stage: {e}")))?;
        Ok(out)
    }

    /// The prim at `path`, if the stage composes one.
    pub fn prim(&self, path: &str) -> Result<Option<usd::Prim>> {
        let prim = self
            .stage
            .prim(path)
            .map_err(|e| Error::prim(path, format!("invalid prim path: {e}")))?;
        match prim.is_valid() {
            Ok(true) => Ok(Some(prim)),
            Ok(false) => Ok(None),
            Err(e) => Err(Error::prim(path, format!("cannot read prim: {e}"))),
        }
    }

    /// The prim at `path`, a path the user gave as `option` (see
    /// [`check_prim_path`]), if the stage composes one: every prim path the
    /// command line or the Python API names is resolved here, paths read
    /// from the file through [`Self::prim`].
    pub fn user_prim(&self, option: &str, path: &str) -> Result<Option<usd::Prim>> {
        check_prim_path(option, path)?;
        self.prim(path)
    }

    /// The prim at `path`, or an error saying it is missing.
    pub fn require_prim(&self, path: &str) -> Result<usd::Prim> {
        self.prim(path)?.ok_or_else(|| Error::prim(path, "prim does not exist"))
    }

    /// Whether `prim` (a mesh) is authored `orientation = "leftHanded"`: its
    /// clockwise polygons face outwards. Brushes and render both ask.
    pub fn left_handed(&self, prim: &usd::Prim) -> Result<bool> {
        let orientation = self.typed(prim, "orientation", None, "token", super::values::token)?;
        Ok(orientation.as_deref() == Some("leftHanded"))
    }

    /// Checks that `path` names a `Camera` prim (the `--camera` of bake,
    /// render and key): a Mesh or an Xform there is a mistake, not a camera.
    pub fn require_camera(&self, path: &str, origin: &str) -> Result<()> {
        let prim = self
            .user_prim(origin, path)?
            .ok_or_else(|| Error::prim(path, format!("the camera named by {origin} does not exist")))?;
        match self.type_name(&prim)?.as_str() {
            "Camera" => Ok(()),
            ty => Err(Error::prim(
                path,
                format!("{origin} names {}, not a Camera", crate::words::prim_of_type(ty)),
            )),
        }
    }

    /// Why a bake does not read `prim` (a child of a prim it reads), as
    /// usd-core's `GetChildren()` leaves it out: deactivated, only an `over`
    /// (no `def`), or abstract (a `class`). `None` when it is read.
    pub fn unread_reason(&self, prim: &usd::Prim) -> Result<Option<&'static str>> {
        let fail = |e: &dyn std::fmt::Display| Error::prim(prim.path(), format!("cannot read prim status: {e}"));
        Ok(if !prim.is_active().map_err(|e| fail(&e))? {
            Some("deactivated (active = false)")
        } else if prim.is_abstract().map_err(|e| fail(&e))? {
            Some("abstract (a class)")
        } else if !prim.is_defined().map_err(|e| fail(&e))? {
            Some("only an over (no def)")
        } else {
            None
        })
    }

    /// The children of `prim` that a bake reads (see [`Self::unread_reason`]),
    /// in namespace order.
    pub fn read_children(&self, prim: &usd::Prim) -> Result<Vec<usd::Prim>> {
        let children = prim
            .children()
            .map_err(|e| Error::prim(prim.path(), format!("cannot list children: {e}")))?;
        let mut read = Vec::with_capacity(children.len());
        for c in children {
            if self.unread_reason(&c)?.is_none() {
                read.push(c);
            }
        }
        Ok(read)
    }

    /// The composed type name ("" when untyped).
    pub fn type_name(&self, prim: &usd::Prim) -> Result<String> {
        prim.type_name()
            .map(|t| t.map(|t| t.as_str().to_string()).unwrap_or_default())
            .map_err(|e| Error::prim(prim.path(), format!("cannot read type name: {e}")))
    }

    /// The composed `apiSchemas` of a prim. Read from metadata, so it works
    /// whether or not the painterly schema plugin is registered.
    pub fn api_schemas(&self, prim: &usd::Prim) -> Result<Vec<String>> {
        prim.api_schemas()
            .map(|v| v.iter().map(|t| t.as_str().to_string()).collect())
            .map_err(|e| Error::prim(prim.path(), format!("cannot read apiSchemas: {e}")))
    }

    /// Whether the attribute has any authored opinion (default or samples;
    /// a spline that would give its value is refused, as by [`Self::value`]).
    pub fn has_authored(&self, prim: &usd::Prim, name: &str) -> Result<bool> {
        self.refuse_spline(prim, name)?;
        prim.attribute(name)
            .has_authored_value()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read: {e}")))
    }

    /// The layer offset (offset, scale) from the layer holding the strongest
    /// opinion of `name` to the stage, and that layer's identifier, when the
    /// offset is not the identity (a sublayer or reference offset). USD
    /// retimes time samples and `timecode` values through it, never a
    /// `double`, so a `double` time authored there is read unretimed.
    pub fn value_offset(&self, prim: &usd::Prim, name: &str) -> Result<Option<(f64, f64, String)>> {
        let info = prim
            .attribute(name)
            .resolve_info()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot resolve: {e}")))?;
        Ok(info.spec_site().and_then(|site| {
            let o = site.offset;
            (o.offset != 0.0 || o.scale != 1.0).then(|| (o.offset, o.scale, site.layer.clone()))
        }))
    }

    /// The attribute's resolved value at `time` (None = default value).
    pub fn value(&self, prim: &usd::Prim, name: &str, time: Option<f64>) -> Result<Option<Value>> {
        self.refuse_spline(prim, name)?;
        let attr = prim.attribute(name);
        let read = |t: Option<f64>| -> Result<Option<Value>> {
            attr.get_at::<Value>(t.map(TimeCode::new))
                .map(present)
                .map_err(|e| Error::attr(prim.path(), name, format!("cannot read: {e}")))
        };
        match (read(time)?, time) {
            (None, Some(t)) => match held_before_block(&self.sample_times(prim, name)?, t) {
                Some(lower) => read(Some(lower)),
                None => Ok(None),
            },
            (v, _) => Ok(v),
        }
    }

    /// The stage times of the `timeSamples` that win over any default of
    /// `prim.name` (the strongest spec with samples, not below one with a
    /// default), blocks included; empty when a default or nothing wins.
    fn winning_sample_times_with_blocks(&self, prim: &usd::Prim, name: &str) -> Vec<f64> {
        let samples = |data: &dyn sdf::AbstractData, path: &sdf::Path| match data.try_field(path, "timeSamples") {
            Ok(Some(v)) => match v.as_ref() {
                Value::TimeSamples(map) => map.iter().map(|(t, _)| *t).collect(),
                _ => Vec::new(),
            },
            _ => Vec::new(),
        };
        let site = super::crate_samples::strongest_samples_site(&self.stage, prim, name, |data, path| {
            !samples(data, path).is_empty()
        });
        let Some(site) = site else { return Vec::new() };
        let Some(layer) = self.stage.layer(&site.layer) else {
            return Vec::new();
        };
        let times = samples(layer.data(), &site.path);
        times.into_iter().map(|t| site.offset.apply(t)).collect()
    }

    /// The layer whose opinion gives `prim.name` its value at `time` (None =
    /// the default), by its identifier (a file's path); None when no layer
    /// does. On a stage of several files, this is the file to name for a bad
    /// value.
    pub fn value_source(&self, prim: &str, name: &str, time: Option<f64>) -> Option<PathBuf> {
        let prim = self.prim(prim).ok()??;
        let info = prim.attribute(name).resolve_info_at(time.map(TimeCode::new)).ok()?;
        Some(PathBuf::from(&info.spec_site()?.layer))
    }

    /// An attribute's time samples read one at a time from the crate file
    /// that authors them, where that is exact (see [`CrateSamples`]).
    pub fn crate_samples(&self, prim: &usd::Prim, name: &str) -> Option<CrateSamples> {
        if !self.mapped {
            return None;
        }
        CrateSamples::open(&self.stage, prim, name)
    }

    /// Every time sample of an attribute with its value at that time, in
    /// stage time, from one read of the `timeSamples` that answer. Reading
    /// sample by sample decodes the whole map at each read, which made an
    /// exporter's sample per frame cost the square of the frames. `None`
    /// when the samples cannot be read in one go (value clips; a block,
    /// which [`Self::value`] reads as usd-core does): read them by time.
    pub fn sample_values(&self, prim: &usd::Prim, name: &str) -> Result<Option<sdf::TimeSampleMap>> {
        let map = prim
            .attribute(name)
            .time_samples()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read time samples: {e}")))?;
        Ok(map.filter(|m| !m.iter().any(|(_, v)| matches!(v, Value::None | Value::ValueBlock))))
    }

    /// Authored time-sample times of an attribute (empty when none).
    pub fn sample_times(&self, prim: &usd::Prim, name: &str) -> Result<Vec<f64>> {
        prim.attribute(name)
            .time_sample_times()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read time samples: {e}")))
    }

    /// The names of the value-clip sets on a prim: in its composed `clips`
    /// (reaching it through references and payloads too) and in every layer
    /// of the stage's layer stack that authors `clips` on it.
    pub fn prim_clip_set_names(&self, prim: &usd::Prim) -> Result<Vec<String>> {
        let path = prim.path();
        let mut names = Vec::new();
        if let Ok(Some(Value::Dictionary(sets))) = prim.get_metadata::<Value>("clips") {
            names.extend(sets.keys().cloned());
        }
        for id in self.stage.layer_stack() {
            let Some(layer) = self.stage.layer(&id) else { continue };
            if let Ok(Some(clips)) = layer.data().try_field(path, "clips") {
                if let Value::Dictionary(sets) = clips.as_ref() {
                    names.extend(sets.keys().cloned());
                }
            }
        }
        Ok(names)
    }

    /// An attribute's metadata field (e.g. a primvar's `interpolation` or
    /// `elementSize`), undecoded; None when not authored.
    pub fn attr_metadata(&self, prim: &usd::Prim, name: &str, key: &str) -> Result<Option<Value>> {
        prim.attribute(name)
            .get_metadata::<Value>(key)
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read {key}: {e}")))
    }

    /// A primvar's `interpolation`, or `default` when not authored.
    pub fn primvar_interpolation(&self, prim: &usd::Prim, name: &str, default: &str) -> Result<String> {
        Ok(self
            .attr_metadata(prim, name, "interpolation")?
            .and_then(|v| values::token(&v))
            .unwrap_or_else(|| default.to_string()))
    }

    /// Refuses a primvar whose `elementSize` is not 1: painterly reads one
    /// value per element (curve, point, span end) of widths, colours and
    /// opacities, where usd-core reads `elementSize` values each.
    pub fn require_element_size_one(&self, prim: &usd::Prim, name: &str) -> Result<()> {
        match self.attr_metadata(prim, name, "elementSize")? {
            None => Ok(()),
            Some(v) => match values::scalar(&v) {
                Some(1.0) => Ok(()),
                n => Err(Error::attr(
                    prim.path(),
                    name,
                    format!(
                        "elementSize {}: painterly reads one value per element of this primvar (elementSize 1)",
                        n.map_or_else(|| values::kind_name(&v), |n| n.to_string())
                    ),
                )),
            },
        }
    }

    /// Relationship targets (forwarded targets are not followed).
    pub fn targets(&self, prim: &usd::Prim, name: &str) -> Result<Vec<String>> {
        prim.relationship(name)
            .targets()
            .map(|v| v.iter().map(|p| p.as_str().to_string()).collect())
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read relationship: {e}")))
    }

    /// The one target of a relationship that takes one (None when it has
    /// none): a second target would be silently ignored, so it is refused.
    pub fn one_target(&self, prim: &usd::Prim, name: &str) -> Result<Option<String>> {
        let mut targets = self.targets(prim, name)?;
        if targets.len() > 1 {
            return Err(Error::attr(
                prim.path(),
                name,
                format!(
                    "has {} targets ({}); painterly reads one",
                    targets.len(),
                    targets.join(", ")
                ),
            ));
        }
        Ok(targets.pop())
    }

    /// Whether `name` is uniform in painterly's schema: a `painterly:`
    /// attribute in [`PAINTERLY_UNIFORM`], or any attribute of a Painterly
    /// typed prim.
    fn schema_uniform(&self, prim: &usd::Prim, name: &str) -> Result<bool> {
        Ok(PAINTERLY_UNIFORM.contains(&name) || self.type_name(prim)?.starts_with("Painterly"))
    }

    /// Fails when `name` is uniform in painterly's schema (a `painterly:`
    /// attribute in [`PAINTERLY_UNIFORM`], or any attribute of a Painterly
    /// typed prim) and has time samples. Alone, its default, the only value
    /// painterly reads, would be absent and the bake would go on without it
    /// (rest points from `points`, a key without its points); beside a
    /// default, usd-core's reads at a frame would see another value than
    /// painterly's.
    fn refuse_samples(&self, prim: &usd::Prim, name: &str, has_default: bool) -> Result<()> {
        if !self.schema_uniform(prim, name)? {
            return Ok(());
        }
        // Beside a default, the specs down to it (blocks included: openusd
        // lists no times for a map of blocks alone, which usd-core reads as
        // no value at a frame); alone, the composed sample times (clips too).
        let times = if has_default {
            self.winning_sample_times_with_blocks(prim, name)
        } else {
            self.sample_times(prim, name)?
        };
        let Some(first) = times.first() else {
            return Ok(());
        };
        let samples = crate::words::plural(times.len(), "sample");
        let message = if has_default {
            // usd-core's Get() reads the default but Get(frame) the samples:
            // which one the author meant cannot be told.
            format!(
                "has time samples ({samples}, first at {first}) beside its default, but the schema makes it \
                 uniform: painterly reads only the default, where usd-core's Get at a frame reads the samples; \
                 remove the samples or the default"
            )
        } else {
            format!(
                "authored only as time samples ({samples}, first at {first}), but the schema makes it uniform: \
                 painterly reads its default value; author it without a time"
            )
        };
        Err(Error::attr(prim.path(), name, message).rule(crate::rule::Rule::AttributeType))
    }

    /// Fails when a spline gives `prim.name` its value over time: openusd
    /// 0.8 reads past splines (USD 25.05's `.spline`), so painterly would
    /// read the default (or nothing) where usd-core evaluates the curve.
    /// Found as usd-core's value resolution finds a value: strongest spec
    /// first; in one spec time samples (a map that is not empty), then a
    /// spline, then a default; then the value clips anchored in that layer.
    pub(crate) fn refuse_spline(&self, prim: &usd::Prim, name: &str) -> Result<()> {
        self.once_without_spline(prim, name, || {
            let Some(layer) = self.spline_source(prim, name) else {
                return Ok(());
            };
            let advice = match self.schema_uniform(prim, name)? {
                true => "the schema makes it uniform: remove the spline and keep a default",
                false => {
                    "bake it to time samples first, e.g. in usd-core read attr.Get(t) at each frame, \
                     attr.Clear(), then attr.Set(value, t)"
                }
            };
            let message = format!(
                "is animated by a spline (`.spline` in {layer}), which painterly cannot evaluate (usd-core \
                 does; openusd 0.8 reads past splines): {advice}"
            );
            Err(Error::attr(prim.path(), name, message).rule(crate::rule::Rule::Unreadable))
        })
    }

    /// Runs `check` for `prim.name` on a stage that may hold a spline,
    /// unless it passed before, and remembers a pass ([`Self::no_spline`]).
    fn once_without_spline(&self, prim: &usd::Prim, name: &str, check: impl FnOnce() -> Result<()>) -> Result<()> {
        if !self.splines {
            return Ok(());
        }
        let key = (prim.path().clone(), name.to_string());
        let lock = || self.no_spline.lock().unwrap_or_else(|e| e.into_inner());
        if lock().contains(&key) {
            return Ok(());
        }
        check()?;
        lock().insert(key);
        Ok(())
    }

    /// The layer whose spline gives `prim.name` its value ([`Self::refuse_spline`]).
    fn spline_source(&self, prim: &usd::Prim, name: &str) -> Option<String> {
        let stack = prim.attribute(name).property_stack().ok()?;
        let specs: Vec<_> = stack
            .into_iter()
            .map_while(|site| self.stage.layer(&site.layer).map(|layer| (site, layer)))
            .collect();
        // Most attributes have no spline anywhere: only then are sample maps read.
        if !specs
            .iter()
            .any(|(site, layer)| layer.data().has_field(&site.path, "spline"))
        {
            return None;
        }
        for (site, layer) in specs {
            let data = layer.data();
            let samples = match data.try_field(&site.path, "timeSamples") {
                Ok(Some(v)) => !matches!(v.as_ref(), Value::TimeSamples(map) if map.is_empty()),
                _ => false,
            };
            if samples {
                return None;
            }
            if data.has_field(&site.path, "spline") {
                return (!self.clips_answer_first(prim, &site.layer)).then_some(site.layer);
            }
            if data.has_field(&site.path, "default") {
                return None;
            }
        }
        None
    }

    /// Whether value clips on `prim` or an ancestor, anchored in a layer of
    /// the root layer stack stronger than `layer`, answer before `layer`'s
    /// opinions (usd-core resolves a layer's own opinions, then the clips
    /// anchored in it, then weaker layers). openusd resolves the clips
    /// themselves, from layers the stage does not list: a spline inside a
    /// clip's own layer is not seen (README, Limits).
    fn clips_answer_first(&self, prim: &usd::Prim, layer: &str) -> bool {
        let stack = self.stage.layer_stack();
        let rank = |id: &str| stack.iter().position(|l| l == id);
        let Some(spline_rank) = rank(layer) else {
            return false;
        };
        std::iter::successors(Some(prim.clone()), |p| p.parent()).any(|p| {
            p.prim_stack().unwrap_or_default().iter().any(|site| {
                let anchors = self.stage.layer(&site.layer).is_some_and(|l| {
                    let data = l.data();
                    data.has_field(&site.path, "clips") || data.has_field(&site.path, "clipSets")
                });
                anchors && rank(&site.layer).is_some_and(|r| r < spline_rank)
            })
        })
    }

    /// [`Self::refuse_spline`] for every transform op of `prim` (once: the
    /// ops are those `xformOpOrder` names, which stands in for them all).
    fn refuse_transform_splines(&self, prim: &usd::Prim) -> Result<()> {
        self.once_without_spline(prim, "xformOpOrder", || {
            let Ok(Some(x)) = Xformable::from_prim(prim.clone()) else {
                return Ok(());
            };
            let Ok((ops, _)) = x.ordered_xform_ops() else {
                return Ok(());
            };
            ops.iter()
                .try_for_each(|op| self.refuse_spline(prim, op.attribute().name()))
        })
    }

    /// How many layers the stage opened (root, sublayers, references, ...).
    pub fn layer_count(&self) -> usize {
        self.stage.layer_identifiers().len()
    }

    /// The one value of an attribute usd-core reads anew at every time (a
    /// skinning input: joint influences, geomBindTransform, a skinned
    /// mesh's points): its time samples when it has any (they are stronger
    /// than a default, and exporters often write every value as one), else
    /// its default. Samples that differ are refused: painterly poses a mesh
    /// with one value of each.
    pub fn value_over_time(&self, prim: &usd::Prim, name: &str) -> Result<Option<Value>> {
        let times = self.sample_times(prim, name)?;
        let Some((&first, rest)) = times.split_first() else {
            return self.value(prim, name, None);
        };
        let differ = |first: f64, t: f64| {
            Error::attr(
                prim.path(),
                name,
                format!(
                    "changes over time (its samples at {first} and {t} differ): painterly poses the mesh with one value of it (usd-core would read it anew at every frame); author a single value"
                ),
            )
        };
        if let Some(samples) = self.sample_values(prim, name)? {
            if let Some(((first, v), rest)) = samples.split_first() {
                if let Some((t, _)) = rest.iter().find(|(_, w)| w != v) {
                    return Err(differ(*first, *t));
                }
                return Ok(Some(v.clone()));
            }
        }
        let v = self.value(prim, name, Some(first))?;
        for &t in rest {
            if self.value(prim, name, Some(t))? != v {
                return Err(differ(first, t));
            }
        }
        Ok(v)
    }

    /// [`Self::value_over_time`], typed as [`Self::typed`] types a value.
    pub fn typed_over_time<T>(
        &self,
        prim: &usd::Prim,
        name: &str,
        expected: &str,
        convert: impl Fn(&Value) -> Option<T>,
    ) -> Result<Option<T>> {
        self.value_over_time(prim, name)?
            .map(|v| convert_typed(prim, name, expected, &v, &convert))
            .transpose()
    }

    /// Reads a typed value, failing with a message naming the expected type.
    pub fn typed<T>(
        &self,
        prim: &usd::Prim,
        name: &str,
        time: Option<f64>,
        expected: &str,
        convert: impl Fn(&Value) -> Option<T>,
    ) -> Result<Option<T>> {
        let value = self.value(prim, name, time)?;
        if time.is_none() {
            self.refuse_samples(prim, name, value.is_some())?;
        }
        value
            .map(|v| convert_typed(prim, name, expected, &v, &convert))
            .transpose()
    }

    /// Local-to-world transform of a prim at `time`, in glam column form.
    ///
    /// On a mapped stage a transform that cannot vary in time is computed
    /// once and kept.
    pub fn local_to_world(&self, prim: &usd::Prim, time: f64) -> Result<DMat4> {
        if !self.mapped {
            return self.compute_local_to_world(prim, time);
        }
        let lock = || self.fixed_transforms.lock().unwrap_or_else(|e| e.into_inner());
        let kept = lock().get(prim.path()).copied();
        if let Some(kept) = kept {
            return match kept {
                Some(m) => Ok(m),
                None => self.compute_local_to_world(prim, time),
            };
        }
        let varies = self.transform_might_vary(prim);
        let m = self.compute_local_to_world(prim, time)?;
        lock().insert(prim.path().clone(), (!varies).then_some(m));
        Ok(m)
    }

    /// Whether an op of `prim` or of an ancestor up to the nearest
    /// `!resetXformStack!` may vary in time (C++
    /// `UsdGeomXformCache::TransformMightBeTimeVarying`, up the chain).
    ///
    /// Only decides whether the transform is kept, so a probe that fails
    /// answers yes and each frame computes the transform as an unmapped
    /// stage does. openusd's probe can fail on an op the transform itself
    /// skips (seen: samples that cannot be decoded under an unknown op
    /// name), and a bake must not fail on what its transforms do not read.
    fn transform_might_vary(&self, prim: &usd::Prim) -> bool {
        let mut cache = XformCache::new(None::<TimeCode>);
        let mut at = Some(prim.clone());
        while let Some(p) = at {
            if cache.transform_might_be_time_varying(&p).unwrap_or(true) {
                return true;
            }
            match cache.resets_xform_stack(&p) {
                Ok(false) => at = p.parent(),
                Ok(true) => return false,
                Err(_) => return true,
            }
        }
        false
    }

    fn compute_local_to_world(&self, prim: &usd::Prim, time: f64) -> Result<DMat4> {
        // openusd-schemas' XformCache, climbing the same way, except that
        // each op is read as usd-core reads it (held up to a block).
        let mut chain = Vec::new();
        let mut current = Some(prim.clone());
        while let Some(p) = current.filter(|p| !p.path().is_abs_root()) {
            self.refuse_transform_splines(&p)?;
            let (local, resets) = local_transform_held(&p, time)
                .map_err(|e| Error::prim(p.path(), format!("cannot compute transform: {e}")))?;
            current = if resets { None } else { p.parent() };
            chain.push(local);
        }
        let m = chain
            .into_iter()
            .rev()
            .fold(gf::Matrix4d::IDENTITY, |base, local| local * base);
        let m = values::usd_matrix(&m);
        if !m.is_finite() {
            return Err(Error::prim(
                prim.path(),
                format!("transform at time {time} is not finite"),
            ));
        }
        Ok(m)
    }

    /// Stage metadata that bakes copy.
    pub fn metadata(&self) -> StageMetadata {
        let get = |k: &str| self.stage.stage_metadata(k).ok().flatten();
        // openusd answers the schema's fallback (0.01, "Y") for units and up
        // axis the root layer leaves unauthored: copied into a bake or an
        // edit layer, it would outlive a later value authored on the shot.
        let authored = |k: &str| self.stage.root_layer().data().has_field(&sdf::Path::abs_root(), k);
        let mut malformed = Vec::new();
        let mut num = |k: &str| {
            let v = get(k)?;
            let x = values::scalar(&v);
            if x.is_none() && !matches!(v, Value::None | Value::ValueBlock) {
                malformed.push(k.to_string());
            }
            x
        };
        StageMetadata {
            start_time_code: num("startTimeCode"),
            end_time_code: num("endTimeCode"),
            time_codes_per_second: num("timeCodesPerSecond"),
            frames_per_second: num("framesPerSecond"),
            meters_per_unit: authored("metersPerUnit").then(|| num("metersPerUnit")).flatten(),
            up_axis: authored("upAxis")
                .then(|| get("upAxis"))
                .flatten()
                .as_ref()
                .and_then(values::token),
            malformed,
        }
    }
}

/// `e` with the errors that caused it, as openusd words a sublayer it
/// cannot read: its own text names only the step that failed ("failed to
/// read pod …"), a cause says what was wrong with the bytes.
pub(crate) fn with_causes(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let said = c.to_string();
        // A transparent wrapper's text is its cause's.
        if !text.ends_with(&said) {
            text = format!("{text}: {said}");
        }
        cause = c.source();
    }
    text
}

/// Why the asset `asset_path`, written in layer `introduced_by`, did not
/// resolve: "not found", unless its file (a package's, for an entry) is
/// there but no regular file, which the resolver refuses to open.
fn not_found(asset_path: &str, introduced_by: &str) -> String {
    let file = file_of(asset_path, introduced_by);
    match std::fs::metadata(file).ok().as_ref().and_then(super::regular::refusal) {
        Some(why) => format!("cannot be read: {why}"),
        None => "not found".into(),
    }
}

/// Why the asset `asset_path`, written in layer `introduced_by`, could not
/// be read, openusd's `reason` unless its file is empty (openusd's words
/// for that are about the first structure it could not read).
fn unreadable_reason(asset_path: &str, introduced_by: &str, reason: String) -> String {
    match !is_package_relative(asset_path) && is_empty_file(&file_of(asset_path, introduced_by)) {
        true => format!("cannot be read: {EMPTY_FILE}"),
        false => format!("cannot be read: {reason}"),
    }
}

/// What an empty layer is said to be, root or not.
const EMPTY_FILE: &str = "the file is empty (0 bytes)";

/// Whether `path` is a regular file of 0 bytes.
fn is_empty_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == 0)
}

/// The file holding the asset `asset_path` (a package's, for an entry),
/// a relative path taken from the folder of `introduced_by`.
fn file_of(asset_path: &str, introduced_by: &str) -> std::path::PathBuf {
    let file = Path::new(package_file(asset_path));
    match Path::new(package_file(introduced_by)).parent() {
        Some(dir) if file.is_relative() => dir.join(file),
        _ => file.to_path_buf(),
    }
}

/// The stage's missing sublayers, references and payloads, from
/// composition's diagnostics.
fn unresolved_assets(stage: &usd::Stage) -> Vec<UnresolvedAsset> {
    use openusd::pcp::CompositionDiagnostic as D;
    let arc = |a: &dyn std::fmt::Debug| format!("{a:?}").to_lowercase();
    let mut out: Vec<UnresolvedAsset> = Vec::new();
    for d in stage.composition_errors() {
        let item = match d {
            D::UnresolvedLayer {
                asset_path,
                arc: a,
                introduced_by,
                site_path,
            } => UnresolvedAsset {
                // First: the fields below take the strings it reads.
                reason: not_found(&asset_path, &introduced_by),
                asset: asset_path,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: introduced_by,
            },
            D::MalformedLayer {
                asset_path,
                arc: a,
                introduced_by,
                site_path,
                reason,
            } => UnresolvedAsset {
                // First: the fields below take the strings it reads.
                reason: unreadable_reason(&asset_path, &introduced_by, reason),
                asset: asset_path,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: introduced_by,
            },
            D::UnresolvedPrimPath {
                arc: a,
                target_layer,
                prim_path,
                introduced_by,
                site_path,
            } => UnresolvedAsset {
                asset: target_layer,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: introduced_by,
                reason: format!("it has no prim <{}>", prim_path.as_str()),
            },
            D::UnresolvedDefaultPrim {
                layer_id,
                arc: a,
                site_path,
            } => UnresolvedAsset {
                asset: layer_id,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: String::new(),
                reason: "its defaultPrim does not name a prim".into(),
            },
            D::UnresolvedSublayer {
                asset_path,
                introduced_by,
            } => UnresolvedAsset {
                reason: not_found(&asset_path, &introduced_by),
                asset: asset_path,
                arc: "sublayer".into(),
                prim: None,
                layer: introduced_by,
            },
            D::MalformedSublayer {
                asset_path,
                introduced_by,
                reason,
            } => UnresolvedAsset {
                reason: unreadable_reason(&asset_path, &introduced_by, reason),
                asset: asset_path,
                arc: "sublayer".into(),
                prim: None,
                layer: introduced_by,
            },
            _ => continue,
        };
        if !out.contains(&item) {
            out.push(item);
        }
    }
    for item in &mut out {
        // openusd names the root layer as the introducer of every arc of the
        // root layer stack: the layer whose opinion authors it is the one to fix.
        if let (Some(prim), "reference" | "payload") = (&item.prim, item.arc.as_str()) {
            if let Some(layer) = authoring_layer(stage, prim, &item.arc, &item.asset) {
                item.layer = layer;
            }
        }
        // A relative path is shown anchored at the layer that authors it.
        if !item.layer.is_empty() && !is_package_relative(&item.asset) && !item.asset.contains(':') {
            let anchor = Path::new(&item.layer).parent().unwrap_or(Path::new("/"));
            item.asset = lexically_normal(&anchor.join(&item.asset));
        }
    }
    // Composition reports them in hash order.
    out.sort_by(|a, b| (&a.layer, &a.prim, &a.asset).cmp(&(&b.layer, &b.prim, &b.asset)));
    out
}

/// The strongest layer of the stage's layer stack whose `references` (or
/// `payload`) on `prim` names `asset` (by file name), if any.
fn authoring_layer(stage: &usd::Stage, prim: &str, arc: &str, asset: &str) -> Option<String> {
    let path = openusd::sdf::Path::new(prim).ok()?;
    let field = if arc == "payload" { "payload" } else { "references" };
    let name = Path::new(asset).file_name()?.to_string_lossy().into_owned();
    stage.layer_stack().into_iter().find(|id| {
        stage.layer(id).is_some_and(
            |layer| matches!(layer.data().try_field(&path, field), Ok(Some(v)) if format!("{v:?}").contains(&name)),
        )
    })
}

/// `path` with `.` and `..` components resolved by text (the file need not
/// exist, so it cannot be canonicalised).
fn lexically_normal(path: &Path) -> String {
    use std::path::Component;
    let mut out = std::path::PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            other => out.push(other),
        }
    }
    out.to_string_lossy().into_owned()
}

#[cfg(test)]
mod tests {
    use super::super::atomic::TempDir;
    use super::*;
    use glam::DVec3;

    /// A file that fails to read because it was being saved says so, with
    /// what reading met: before, only "failed to read PATHS section".
    #[test]
    fn a_read_failure_of_a_file_changed_meanwhile_says_it_changed() {
        let dir = crate::test_dir::ScratchDir::new("changed-while-read");
        let f = dir.join("a.usdc");
        std::fs::write(&f, b"PXR-USDC half").unwrap();
        let opened: super::super::guard::OpenedFiles =
            [(f.clone(), super::super::guard::FileId::of(&f).unwrap())].into();
        assert!(changed_while_read(&opened, "cannot read USD file: x").is_none());
        std::fs::write(&f, b"PXR-USDC the whole file").unwrap();
        let e = changed_while_read(&opened, "cannot read USD file: failed to read PATHS section").unwrap();
        assert_eq!(e.file.as_deref(), Some(f.as_path()));
        assert_eq!(
            e.message,
            "changed while painterly read it (saved during this run?): what was read is not what the file now \
             holds; run again once it is saved (cannot read USD file: failed to read PATHS section)"
        );
    }

    /// `PAINTERLY_UNIFORM` is the schema's uniform `painterly:` attributes,
    /// and every attribute of a Painterly typed prim (the other half of the
    /// rule `refuse_samples` applies) is uniform.
    #[test]
    fn painterly_uniform_is_the_schema_s() {
        let schema = include_str!("../../schemas/painterly/schema.usda");
        let mut uniform = Vec::new();
        let mut class = "";
        for line in schema.lines() {
            if let Some(rest) = line.strip_prefix("class ") {
                class = rest.split('"').nth(1).unwrap_or("");
                continue;
            }
            // Attribute declarations open their metadata: `    [uniform] type name [= value] (`.
            let Some(decl) = line
                .strip_prefix("    ")
                .filter(|d| !d.starts_with(' ') && d.ends_with(" ("))
            else {
                continue;
            };
            let (is_uniform, name) = match decl.split_whitespace().collect::<Vec<_>>().as_slice() {
                ["rel", ..] => continue,
                ["uniform", _, name, ..] => (true, *name),
                [_, name, ..] => (false, *name),
                _ => continue,
            };
            if class.starts_with("Painterly") && !class.ends_with("API") {
                assert!(is_uniform, "{class}.{name} is not uniform");
            } else if is_uniform {
                uniform.push(name);
            }
        }
        assert_eq!(uniform, PAINTERLY_UNIFORM);
    }

    /// The file named for a value is the layer whose opinion wins at that
    /// time: a stronger sublayer's samples at a time, the weaker one's
    /// default at the default time; no layer for an attribute nobody authors.
    #[test]
    fn a_value_s_source_is_the_layer_that_wins_at_its_time() {
        let dir = TempDir::new().unwrap();
        let file = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, format!("#usda 1.0\n{text}")).unwrap();
            p.canonicalize().unwrap()
        };
        let input = file(
            "input.usda",
            "def Xform \"A\" {\n    double x = 1\n    double y = 2\n}\n",
        );
        let bake = file("bake.usda", "over \"A\" {\n    double x.timeSamples = { 1: 5 }\n}\n");
        let root = file(
            "root.usda",
            &format!("(\n    subLayers = [@{}@, @{}@]\n)\n", bake.display(), input.display()),
        );
        let r = StageReader::open(&root).unwrap();
        let source = |attr: &str, t: Option<f64>| r.value_source("/A", attr, t).map(|p| p.canonicalize().unwrap());
        assert_eq!(source("x", Some(1.0)), Some(bake.clone()));
        assert_eq!(source("x", None), Some(input.clone()));
        assert_eq!(source("y", Some(1.0)), Some(input));
        assert_eq!(source("z", Some(1.0)), None);
        assert_eq!(r.value_source("/B", "x", None), None);
    }

    #[test]
    fn a_spline_is_refused_where_usd_reads_it_and_nowhere_else() {
        // Value resolution as usd-core 26.11 resolves it (checked with its
        // GetResolveInfo): strongest spec first; in one spec time samples,
        // then a spline, then a default.
        let dir = TempDir::new().unwrap();
        let weak = dir.path().join("weak.usda");
        std::fs::write(
            &weak,
            r#"#usda 1.0
over "P" {
    double underDefault.spline = { 1: 0; post linear, 9: 8; post linear, }
    double underSpline.timeSamples = { 1: 5 }
    double underEmpty.spline = { 1: 0; post linear, 9: 8; post linear, }
}
over "Clipped" {
    double underClips.spline = { 1: 0; post linear, 9: 8; post linear, }
}
def "WeakClips" (
    clips = {
        dictionary default = {
            double2[] active = [(1, 0)]
            asset[] assetPaths = [@./clip.usda@]
            string primPath = "/Clipped"
            double2[] times = [(1, 1), (9, 9)]
        }
    }
) {
}
"#,
        )
        .unwrap();
        let strong = dir.path().join("strong.usda");
        std::fs::write(
            &strong,
            r#"#usda 1.0
(
    subLayers = [@./weak.usda@]
)
def Xform "P" {
    double alone.spline = { 1: 0; post linear, 9: 8; post linear, }
    double besideDefault = 3
    double besideDefault.spline = { 1: 0; post linear, 9: 8; post linear, }
    double besideSamples.timeSamples = { 1: 5 }
    double besideSamples.spline = { 1: 0; post linear, 9: 8; post linear, }
    double underDefault = 3
    double underSpline.spline = { 1: 0; post linear, 9: 8; post linear, }
    double plain = 3
    double emptyBeside.timeSamples = { }
    double emptyBeside.spline = { 1: 0; post linear, 9: 8; post linear, }
    double underEmpty.timeSamples = { }
    double painterly:rbfRadius.spline = { 1: 0; post linear, 9: 8; post linear, }
    float xformOp:rotateY.spline = { 1: 0; post linear, 9: 80; post linear, }
    uniform token[] xformOpOrder = ["xformOp:rotateY"]
    def Xform "Child" {
    }
}
def Xform "Still" {
    double3 xformOp:translate = (1, 2, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def "Clipped" (
    clips = {
        dictionary default = {
            double2[] active = [(1, 0)]
            asset[] assetPaths = [@./clip.usda@]
            string primPath = "/Clipped"
            double2[] times = [(1, 1), (9, 9)]
        }
    }
) {
    double sameLayer.spline = { 1: 0; post linear, 9: 8; post linear, }
}
over "WeakClips" {
    double underClips.spline = { 1: 0; post linear, 9: 8; post linear, }
}
"#,
        )
        .unwrap();
        std::fs::write(
            dir.path().join("clip.usda"),
            "#usda 1.0\nover \"Clipped\" {\n    double underClips.timeSamples = { 1: 7, 9: 7 }\n}\n",
        )
        .unwrap();
        let r = StageReader::open(&strong).unwrap();
        assert!(r.splines);
        let p = r.require_prim("/P").unwrap();
        let (strong_id, weak_id) = (strong.to_str().unwrap(), weak.to_str().unwrap());
        for (name, layer) in [
            ("alone", strong_id),
            ("besideDefault", strong_id),
            ("underSpline", strong_id),
            ("emptyBeside", strong_id),
            ("underEmpty", weak_id),
            ("painterly:rbfRadius", strong_id),
        ] {
            let e = r.value(&p, name, Some(5.0)).unwrap_err();
            assert_eq!(e.prim.as_deref(), Some("/P"), "{name}");
            assert_eq!(e.attribute.as_deref(), Some(name));
            assert_eq!(e.rule, Some(crate::rule::Rule::Unreadable));
            let head = format!("is animated by a spline (`.spline` in {layer})");
            assert!(e.message.starts_with(&head), "{}", e.message);
            // A uniform attribute cannot take time samples instead.
            let uniform = name == "painterly:rbfRadius";
            let keep_default = e.message.ends_with("remove the spline and keep a default");
            assert_eq!(keep_default, uniform, "{}", e.message);
            assert_eq!(e.message.contains("attr.Set(value, t)"), !uniform, "{}", e.message);
        }
        // Clips anchored in a stronger layer give the value over a weaker
        // spline.
        let clipped = r.require_prim("/Clipped").unwrap();
        let clip_value = r.value(&clipped, "underClips", Some(5.0)).unwrap();
        assert_eq!(clip_value, Some(Value::Double(7.0)));
        // A spline in the clips' own layer answers before them, and so does
        // one in a layer stronger than the clips'.
        let e = r.value(&clipped, "sameLayer", Some(5.0)).unwrap_err();
        assert!(e.message.contains(strong_id), "{}", e.message);
        let weak_clips = r.require_prim("/WeakClips").unwrap();
        let e = r.value(&weak_clips, "underClips", Some(5.0)).unwrap_err();
        assert!(e.message.contains(strong_id), "{}", e.message);
        for (name, at_5) in [("besideSamples", 5.0), ("underDefault", 3.0), ("plain", 3.0)] {
            assert_eq!(
                r.value(&p, name, Some(5.0)).unwrap(),
                Some(Value::Double(at_5)),
                "{name}"
            );
        }
        // A transform op, and so every prim below it.
        let child = r.require_prim("/P/Child").unwrap();
        let e = r.local_to_world(&child, 5.0).unwrap_err();
        assert_eq!(
            (e.prim.as_deref(), e.attribute.as_deref()),
            (Some("/P"), Some("xformOp:rotateY"))
        );
        let still = r.require_prim("/Still").unwrap();
        assert_eq!(
            r.local_to_world(&still, 5.0).unwrap().w_axis.truncate(),
            glam::DVec3::new(1.0, 2.0, 3.0)
        );

        // What passed is remembered; what failed fails again.
        let passed = r.no_spline.lock().unwrap().clone();
        assert!(passed.contains(&(sdf::Path::new("/P").unwrap(), "plain".to_string())));
        assert!(passed.contains(&(sdf::Path::new("/Still").unwrap(), "xformOpOrder".to_string())));
        assert!(!passed.contains(&(sdf::Path::new("/P").unwrap(), "alone".to_string())));
        assert!(!passed.contains(&(sdf::Path::new("/P").unwrap(), "xformOpOrder".to_string())));
        assert!(r.value(&p, "alone", Some(5.0)).is_err());

        // A stage whose layers cannot hold a spline does not look for one.
        let none = dir.path().join("none.usda");
        std::fs::write(&none, "#usda 1.0\n(\n    subLayers = [@./clip.usda@]\n)\n").unwrap();
        let r = StageReader::open(&none).unwrap();
        assert!(!r.splines);
        let clipped = r.require_prim("/Clipped").unwrap();
        assert!(r.value(&clipped, "underClips", Some(5.0)).is_ok());
        assert!(r.no_spline.lock().unwrap().is_empty());
    }

    /// A mapped reader keeps exactly the transforms nothing can vary (a
    /// one-sample op is fixed; an animated parent is not, unless the child
    /// resets the stack); an in-memory reader keeps none. Answers are
    /// usd-core's either way (python_tests: test_one_sample_values_hold_at_every_frame).
    #[test]
    fn fixed_transforms_are_kept_only_where_nothing_varies() {
        let dir = TempDir::new().unwrap();
        let path = dir.path().join("xf.usda");
        std::fs::write(
            &path,
            r#"#usda 1.0
def Xform "Moving" {
    double3 xformOp:translate.timeSamples = { 1: (0, 0, 0), 5: (4, 0, 0) }
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def Xform "Child" {
        double3 xformOp:translate = (0, 1, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Xform "Reset" {
        double3 xformOp:translate = (0, 0, 0)
        double3 xformOp:translate.timeSamples = { 3: (0, 0, 2) }
        uniform token[] xformOpOrder = ["!resetXformStack!", "xformOp:translate"]
    }
}
"#,
        )
        .unwrap();
        let kept = |r: &StageReader, p: &str| {
            r.fixed_transforms
                .lock()
                .unwrap()
                .get(&sdf::Path::new(p).unwrap())
                .copied()
        };
        let r = StageReader::open_mapped(&path).unwrap();
        for t in [1.0, 3.0, 5.0] {
            for p in ["/Moving", "/Moving/Child", "/Moving/Reset"] {
                let m = r.local_to_world(&r.require_prim(p).unwrap(), t).unwrap();
                let want = match p {
                    "/Moving" => DVec3::new(t - 1.0, 0.0, 0.0),
                    "/Moving/Child" => DVec3::new(t - 1.0, 1.0, 0.0),
                    _ => DVec3::new(0.0, 0.0, 2.0),
                };
                assert_eq!(m.w_axis.truncate(), want, "{p} at {t}");
            }
        }
        assert_eq!(kept(&r, "/Moving"), Some(None));
        assert_eq!(kept(&r, "/Moving/Child"), Some(None));
        let reset = kept(&r, "/Moving/Reset").expect("asked for").expect("kept");
        assert_eq!(reset.w_axis.truncate(), DVec3::new(0.0, 0.0, 2.0));
        let r = StageReader::open(&path).unwrap();
        r.local_to_world(&r.require_prim("/Moving/Reset").unwrap(), 1.0)
            .unwrap();
        assert_eq!(kept(&r, "/Moving/Reset"), None);
    }

    /// The one-line forms their doc comments give:
    /// `reference @a.usda@ on /Char (in shot.usda): not found`, and the same
    /// without ` on /Char`; a sublayer (no prim) has no ` on` part either way.
    #[test]
    fn unresolved_assets_describe_themselves_as_documented() {
        let reference = UnresolvedAsset {
            asset: "a.usda".into(),
            arc: "reference".into(),
            prim: Some("/Char".into()),
            layer: "shot.usda".into(),
            reason: "not found".into(),
        };
        assert_eq!(
            reference.describe(),
            "reference @a.usda@ on /Char (in shot.usda): not found"
        );
        assert_eq!(
            reference.describe_asset(),
            "reference @a.usda@ (in shot.usda): not found"
        );
        let sublayer = UnresolvedAsset {
            arc: "sublayer".into(),
            prim: None,
            ..reference
        };
        assert_eq!(sublayer.describe(), "sublayer @a.usda@ (in shot.usda): not found");
    }

    /// Stage metadata usd-core can hold (positive rates, any finite time
    /// codes, negative ones included) passes; NaN, infinities, a rate or
    /// metersPerUnit of zero or below, and a field that is not a number fail,
    /// each naming the field.
    #[test]
    fn metadata_validation_accepts_usable_values_only() {
        let good = StageMetadata {
            start_time_code: Some(-3.0),
            end_time_code: Some(10.0),
            time_codes_per_second: Some(24.0),
            frames_per_second: Some(12.0),
            up_axis: Some("Z".into()),
            meters_per_unit: Some(0.01),
            malformed: Vec::new(),
        };
        assert_eq!(good.validate(), Ok(()));
        assert_eq!(StageMetadata::default().validate(), Ok(()));
        let field = |m: StageMetadata, name: &str, why: &str| {
            let e = m.validate().expect_err(name);
            assert!(e.message.contains(name) && e.message.contains(why), "{name}: {e}");
        };
        field(
            StageMetadata {
                start_time_code: Some(f64::NAN),
                ..good.clone()
            },
            "startTimeCode",
            "finite",
        );
        field(
            StageMetadata {
                end_time_code: Some(f64::INFINITY),
                ..good.clone()
            },
            "endTimeCode",
            "finite",
        );
        field(
            StageMetadata {
                meters_per_unit: Some(f64::NEG_INFINITY),
                ..good.clone()
            },
            "metersPerUnit",
            "finite",
        );
        field(
            StageMetadata {
                time_codes_per_second: Some(0.0),
                ..good.clone()
            },
            "timeCodesPerSecond",
            "positive",
        );
        field(
            StageMetadata {
                frames_per_second: Some(-24.0),
                ..good.clone()
            },
            "framesPerSecond",
            "positive",
        );
        field(
            StageMetadata {
                meters_per_unit: Some(0.0),
                ..good.clone()
            },
            "metersPerUnit",
            "positive",
        );
        field(
            StageMetadata {
                malformed: vec!["endTimeCode".into()],
                ..good.clone()
            },
            "endTimeCode",
            "not a number",
        );
    }

    /// Numeric stage metadata is read as authored; a field that holds no
    /// number is named as malformed, never taken as absent. The text format
    /// cannot hold one (usd-core and openusd both refuse `startTimeCode =
    /// "abc"` as a parse error), but a crate file's fields are untyped: the
    /// file here holds the string "abc" as startTimeCode. usd-core 26.11
    /// opens it and reads the field back as that string
    /// (`pseudoRoot.GetInfo("startTimeCode")` is 'abc'), and its stage then
    /// fails to use it (`GetStartTimeCode()`: "Attempted to get value of
    /// type 'double' from VtValue holding 'string'").
    #[test]
    fn stage_metadata_that_is_not_a_number_is_named() {
        use openusd::sdf::{FieldKey, SpecType};
        let dir = crate::test_dir::ScratchDir::new("stage-meta");
        let good = dir.join("good.usda");
        std::fs::write(
            &good,
            "#usda 1.0\n(\n    startTimeCode = 2\n    endTimeCode = 9\n    timeCodesPerSecond = 30\n    framesPerSecond = 15\n    metersPerUnit = 0.5\n    upAxis = \"Z\"\n)\ndef Xform \"A\" {}\n",
        )
        .unwrap();
        let m = StageReader::open(&good).unwrap().metadata();
        let want = StageMetadata {
            start_time_code: Some(2.0),
            end_time_code: Some(9.0),
            time_codes_per_second: Some(30.0),
            frames_per_second: Some(15.0),
            up_axis: Some("Z".into()),
            meters_per_unit: Some(0.5),
            malformed: Vec::new(),
        };
        assert_eq!(m, want);
        let mut data = sdf::Data::new();
        let root = data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
        root.add(FieldKey::StartTimeCode, Value::String("abc".into()));
        root.add(FieldKey::EndTimeCode, Value::Double(9.0));
        let bad = dir.join("bad.usdc");
        let bytes = super::super::usdc::write_layer(&data, std::io::Cursor::new(Vec::new()))
            .unwrap()
            .into_inner();
        std::fs::write(&bad, bytes).unwrap();
        let m = StageReader::open(&bad).unwrap().metadata();
        assert_eq!(m.start_time_code, None);
        assert_eq!(m.end_time_code, Some(9.0));
        assert_eq!(m.malformed, vec!["startTimeCode".to_string()]);
        let e = m.validate().unwrap_err();
        assert!(e.message.contains("startTimeCode is not a number"), "{e}");
    }

    /// Each kind of unresolved asset usd-core reports as a composition error
    /// for the same files (checked with `Usd.Stage.Open(f).GetCompositionErrors()`):
    /// a missing or unreadable sublayer (ErrorInvalidSublayerPath, no prim),
    /// a missing or unreadable referenced file (ErrorInvalidAssetPath on
    /// /Char), a referenced file without the named prim or without a
    /// defaultPrim (ErrorUnresolvedPrimPath on /Char). Only the first four
    /// are refused: the last two contribute nothing, for usd-core too.
    #[test]
    fn every_kind_of_unresolved_asset_is_listed_and_only_missing_files_refused() {
        let dir = crate::test_dir::ScratchDir::new("stage-unresolved");
        std::fs::write(dir.join("asset.usda"), "#usda 1.0\ndef Xform \"Thing\" {}\n").unwrap();
        std::fs::write(
            dir.join("bad.usda"),
            "#usda 1.0\ndef Xform \"Broken\" {\n    double x = (1, 2\n",
        )
        .unwrap();
        let sub = |name: &str, asset: &str| {
            let p = dir.join(name);
            std::fs::write(
                &p,
                format!("#usda 1.0\n(\n    subLayers = [@./{asset}@]\n)\ndef Xform \"Char\" {{}}\n"),
            )
            .unwrap();
            p
        };
        let reference = |name: &str, arc: &str| {
            let p = dir.join(name);
            std::fs::write(
                &p,
                format!("#usda 1.0\ndef Xform \"Char\" (\n    prepend references = {arc}\n)\n{{\n}}\n"),
            )
            .unwrap();
            p
        };
        // (root, asset file, arc, prim, reason starts with, refused)
        let cases = [
            (
                sub("sub_missing.usda", "missing.usda"),
                "missing.usda",
                "sublayer",
                None,
                "not found",
                true,
            ),
            (
                sub("sub_bad.usda", "bad.usda"),
                "bad.usda",
                "sublayer",
                None,
                "cannot be read",
                true,
            ),
            (
                reference("ref_missing.usda", "@./missing.usda@"),
                "missing.usda",
                "reference",
                Some("/Char"),
                "not found",
                true,
            ),
            (
                reference("ref_bad.usda", "@./bad.usda@"),
                "bad.usda",
                "reference",
                Some("/Char"),
                "cannot be read",
                true,
            ),
            (
                reference("ref_noprim.usda", "@./asset.usda@</Nope>"),
                "asset.usda",
                "reference",
                Some("/Char"),
                "it has no prim </Nope>",
                false,
            ),
            (
                reference("ref_nodefault.usda", "@./asset.usda@"),
                "asset.usda",
                "reference",
                Some("/Char"),
                "its defaultPrim does not name a prim",
                false,
            ),
        ];
        for (root, asset, arc, prim, reason, refused) in cases {
            let name = root.file_name().unwrap().to_str().unwrap().to_string();
            let r = StageReader::open(&root).unwrap();
            assert_eq!(r.unresolved.len(), 1, "{name}: {:?}", r.unresolved);
            let u = &r.unresolved[0];
            assert!(u.asset.contains(asset), "{name}: {u:?}");
            assert_eq!(u.arc, arc, "{name}");
            assert_eq!(u.prim.as_deref(), prim, "{name}");
            assert!(u.reason.starts_with(reason), "{name}: {u:?}");
            match r.require_resolved() {
                Ok(()) => assert!(!refused, "{name} was not refused"),
                Err(e) => {
                    assert!(refused, "{name} was refused: {e}");
                    assert!(e.message.starts_with(&format!("missing asset: {arc} @")), "{name}: {e}");
                    assert!(e.message.contains(asset), "{name}: {e}");
                }
            }
        }
        // Two missing sublayers: both named, in one message.
        let two = dir.join("two.usda");
        std::fs::write(
            &two,
            "#usda 1.0\n(\n    subLayers = [@./gone1.usda@, @./gone2.usda@]\n)\n",
        )
        .unwrap();
        let r = StageReader::open(&two).unwrap();
        let e = r.require_resolved().unwrap_err();
        assert!(e.message.starts_with("2 missing assets: sublayer @"), "{e}");
        assert!(
            e.message.contains("gone1.usda") && e.message.contains("gone2.usda"),
            "{e}"
        );
        // Many: the first ten, then how many more (a message of 70 KB before).
        let many = dir.join("many.usda");
        let subs: Vec<String> = (0..1100).map(|i| format!("@./m{i:04}.usda@")).collect();
        std::fs::write(
            &many,
            format!("#usda 1.0\n(\n    subLayers = [{}]\n)\n", subs.join(", ")),
        )
        .unwrap();
        let e = StageReader::open(&many).unwrap().require_resolved().unwrap_err();
        let one = |i: usize| {
            format!(
                "sublayer @{}@ (in {}): not found",
                dir.join(format!("m{i:04}.usda")).display(),
                many.display()
            )
        };
        let first: Vec<String> = (0..10).map(one).collect();
        let said = format!(
            "1100 missing assets: {}; and 1090 more (inspect lists every one)",
            first.join("; ")
        );
        assert_eq!(e.message, said);
    }

    /// `require_camera` accepts a prim usd-core types `Camera` and names
    /// what else is there: a Mesh, an untyped prim (`over` or typeless
    /// `def`), no prim at all.
    /// A uniform attribute (a listed `painterly:` one on any prim, or any
    /// attribute of a Painterly typed prim) with only time samples is an
    /// error naming it; one with a default beside samples reads the default;
    /// a varying attribute with only samples reads as absent at the default
    /// time, as usd-core's Get() gives.
    #[test]
    fn a_uniform_attribute_with_time_samples_is_refused() {
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def BasisCurves "L" {
    point3f[] painterly:restPoints.timeSamples = { 1: [(0, 0, 0)] }
    point3f[] points.timeSamples = { 1: [(0, 0, 0)] }
    float painterly:opacity.timeSamples = { 1: 0.5 }
    token painterly:interpolation = "rbf"
    token painterly:interpolation.timeSamples = { 1: "shepard" }
    uniform float painterly:rbfRadius = 0.5
    def PainterlyPoseKey "k" {
        float[] coordinates.timeSamples = { 2: [0.5] }
    }
    def PainterlyPoseKey "j" {
        float opacity = 0.5
        float opacity.timeSamples = { 3: None, 4: None }
    }
}
"#,
        );
        let read = |prim: &str, name: &str| {
            let p = r.require_prim(prim).unwrap();
            r.typed(&p, name, None, "any", |v| Some(v.clone()))
        };
        let e = read("/L", "painterly:restPoints").unwrap_err();
        assert_eq!(
            (e.prim.as_deref(), e.attribute.as_deref()),
            (Some("/L"), Some("painterly:restPoints"))
        );
        assert_eq!(
            e.message,
            "authored only as time samples (1 sample, first at 1), but the schema makes it uniform: \
             painterly reads its default value; author it without a time"
        );
        assert_eq!(e.rule, Some(crate::rule::Rule::AttributeType));
        let e = read("/L/k", "coordinates").unwrap_err();
        assert!(
            e.message
                .starts_with("authored only as time samples (1 sample, first at 2)"),
            "{}",
            e.message
        );
        assert_eq!(read("/L", "points").unwrap(), None);
        assert_eq!(read("/L", "painterly:opacity").unwrap(), None);
        // Beside a default, usd-core's Get at a frame reads the samples.
        let e = read("/L", "painterly:interpolation").unwrap_err();
        assert_eq!(
            (e.attribute.as_deref(), e.message.as_str()),
            (
                Some("painterly:interpolation"),
                "has time samples (1 sample, first at 1) beside its default, but the schema makes it uniform: \
                 painterly reads only the default, where usd-core's Get at a frame reads the samples; remove \
                 the samples or the default"
            )
        );
        assert_eq!(e.rule, Some(crate::rule::Rule::AttributeType));
        assert_eq!(read("/L", "painterly:rbfRadius").unwrap(), Some(Value::Float(0.5)));
        // Samples that are all blocks: usd-core reads no value at a frame
        // (openusd lists no times for them).
        let e = read("/L/j", "opacity").unwrap_err();
        assert!(
            e.message
                .starts_with("has time samples (2 samples, first at 3) beside its default"),
            "{}",
            e.message
        );
        assert_eq!(read("/L/k", "opacity").unwrap(), None);
    }

    #[test]
    fn require_camera_accepts_only_a_camera() {
        let dir = crate::test_dir::ScratchDir::new("stage-camera");
        let path = dir.join("cams.usda");
        std::fs::write(
            &path,
            "#usda 1.0\ndef Camera \"Cam\" {}\ndef Mesh \"Box\" {}\ndef \"Bare\" {}\n",
        )
        .unwrap();
        let r = StageReader::open(&path).unwrap();
        assert_eq!(r.require_camera("/Cam", "--camera"), Ok(()));
        let why = |p: &str| r.require_camera(p, "--camera").unwrap_err().message;
        assert_eq!(why("/Box"), "--camera names a Mesh prim, not a Camera");
        assert_eq!(why("/Bare"), "--camera names an untyped prim, not a Camera");
        assert_eq!(why("/Nowhere"), "the camera named by --camera does not exist");
        // A path naming something other than a prim is the command line's
        // fault (exit 2), though openusd finds /Cam at the end of each.
        for (p, what) in [
            ("/Cam.focalLength", "is a property path, not a prim path"),
            ("/Cam.no:such:attr", "is a property path, not a prim path"),
            ("/Cam{v=x}", "is a variant selection path, not a prim path"),
            ("/Cam{v=x}Inner", "is a variant selection path, not a prim path"),
            (
                "Cam",
                "is a relative path, not an absolute prim path (one starting with /)",
            ),
            ("/", "is the pseudo-root, not a prim path"),
        ] {
            let e = r.require_camera(p, "--camera").unwrap_err();
            assert_eq!((e.message, e.usage), (format!("--camera {p} {what}"), true));
        }
        let e = r.user_prim("--layer", "/Cam[").unwrap_err();
        assert!(
            e.usage && e.message.starts_with("--layer /Cam[ is not a prim path: "),
            "{e}"
        );
        assert!(r.user_prim("--layer", "/Cam").unwrap().is_some());
    }

    /// A package's root layer is its first file for usd-core: a .usda,
    /// .usdc or .usd (in any case) there is read, anything else refused, a
    /// package first too (usd-core would open its first file, openusd
    /// another layer); only a file that is not a .usdz is not looked into.
    #[test]
    fn a_package_s_first_file_must_be_a_usd_layer() {
        let dir = crate::test_dir::ScratchDir::new("stage-package");
        // A local file header: signature, 22 bytes (flags, sizes...), name
        // length, extra length, name; nothing after it is read.
        let package = |file: &str, first: &str| {
            let mut b = b"PK\x03\x04".to_vec();
            b.extend([0; 22]);
            b.extend((first.len() as u16).to_le_bytes());
            b.extend([0, 0]);
            b.extend(first.as_bytes());
            let p = dir.join(file);
            std::fs::write(&p, b).unwrap();
            p
        };
        for first in ["a.usda", "sub/a.usdc", "A.USD", "a.Usda"] {
            assert_eq!(package_fault(&package("ok.usdz", first)), None, "{first}");
        }
        assert_eq!(package_fault(&package("not_a_package.usda", "tex.png")), None);
        let fault = |first: &str| match package_fault(&package("p.usdz", first)) {
            Some(PackageFault::FirstFile(why)) => why,
            other => panic!("{first}: {other:?}"),
        };
        assert_eq!(
            fault("tex.png"),
            "the package's first file is tex.png, not a USD layer; usd-core opens the first file as \
             the package's root layer"
        );
        assert!(fault("sub/").starts_with("the package's first file is sub/, not a USD layer"));
        assert!(fault("a.usda.png").starts_with("the package's first file is a.usda.png, not"));
        assert!(fault("inner.USDZ").starts_with("the package's first file is inner.USDZ, another package"));
        // Bytes before the first file header, or no zip at all.
        let junk = dir.join("junk.usdz");
        std::fs::write(&junk, b"JUNKPK\x03\x04").unwrap();
        assert_eq!(package_fault(&junk), Some(PackageFault::NoFirstFile));
        assert_eq!(check_package(&junk, false), Ok(()));
        let e = check_package(&junk, true).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(junk.as_path()));
        assert!(e.message.starts_with("the package does not begin with a file"), "{e}");
        assert_eq!(package_fault(&dir.join("missing.usdz")), None);
    }

    /// `open_mapped` serves the layers from read-only memory mappings (as
    /// usd-core maps crate files), `open` reads them into memory: while a
    /// mapped reader of a crate file lives, the kernel lists the file among
    /// the process's mappings (`/proc/self/maps`, proc(5)); an in-memory
    /// reader's file is not there.
    #[cfg(target_os = "linux")]
    #[test]
    fn open_mapped_maps_crate_files_and_open_does_not() {
        use super::super::layer::{Format, OverLayer};
        let dir = crate::test_dir::ScratchDir::new("stage-maps");
        let mapped_in = |path: &Path| {
            let maps = std::fs::read_to_string("/proc/self/maps").unwrap();
            let name = path.to_str().unwrap();
            maps.lines().any(|l| l.ends_with(name))
        };
        let write = |name: &str| {
            let mut layer = OverLayer::new(StageMetadata::default());
            layer.set_default("/M", "radius", "double", Value::Double(2.0));
            let path = dir.join(name);
            std::fs::write(&path, layer.into_bytes(Format::Usdc).unwrap()).unwrap();
            path
        };
        let (a, b) = (write("mapped.usdc"), write("read.usdc"));
        let mapped = StageReader::open_mapped(&a).unwrap();
        let read = StageReader::open(&b).unwrap();
        // Both compose the same layer.
        for r in [&mapped, &read] {
            let m = r.require_prim("/M").unwrap();
            assert_eq!(r.value(&m, "radius", None).unwrap(), Some(Value::Double(2.0)));
        }
        assert!(mapped_in(&a), "{} is not mapped", a.display());
        assert!(!mapped_in(&b), "{} is mapped", b.display());
        drop(mapped);
        assert!(!mapped_in(&a), "{} is still mapped", a.display());
    }

    #[test]
    fn only_an_identifier_ending_in_a_bracket_is_inside_a_package() {
        // As usd-core's Ar.IsPackageRelativePath: a folder named `take[2]`
        // is a folder. Splitting at the first `[` emptied the list of input
        // files there (an output over a sublayer was not refused) and noted
        // no file versions.
        assert_eq!(package_file("/a/pkg.usdz[inner.usda]"), "/a/pkg.usdz");
        assert_eq!(package_file("/a/b.usdz[c.usdz[d.usda]]"), "/a/b.usdz");
        assert_eq!(package_file("/take[2]/pkg.usdz[x.usda]"), "/take[2]/pkg.usdz");
        assert_eq!(package_file("/take[2]/shot.usda"), "/take[2]/shot.usda");
        assert_eq!(package_file("/odd]"), "/odd]");
        assert!(is_package_relative("p.usdz[a.usda]") && !is_package_relative("/t[1]/a.usda"));
        let dir = crate::test_dir::ScratchDir::new("stage-bracket");
        let take = dir.join("take[2]");
        std::fs::create_dir(&take).unwrap();
        std::fs::write(take.join("body.usda"), "#usda 1.0\ndef Xform \"B\"\n{\n}\n").unwrap();
        let root = take.join("shot.usda");
        std::fs::write(&root, "#usda 1.0\n(\n    subLayers = [@./body.usda@]\n)\n").unwrap();
        let r = StageReader::open_mapped(&root).unwrap();
        assert_eq!(r.opened.len(), 2, "{:?}", r.opened.keys());
        let e = crate::usd_io::clips::check_not_an_input_file(&r, &take.join("body.usda")).unwrap_err();
        assert!(e.to_string().contains("body.usda"), "{e}");
    }

    #[test]
    fn a_file_saved_after_it_was_read_is_named_by_the_check() {
        // An input saved while a bake ran: its provenance (hash or stamp)
        // described the new file, its data the old one.
        let dir = crate::test_dir::ScratchDir::new("stage-unchanged");
        let sub = dir.join("sub.usda");
        let root = dir.join("root.usda");
        std::fs::write(&sub, "#usda 1.0\ndef Xform \"S\"\n{\n}\n").unwrap();
        std::fs::write(&root, "#usda 1.0\n(\n    subLayers = [@./sub.usda@]\n)\n").unwrap();
        let r = StageReader::open_mapped(&root).unwrap();
        assert_eq!(r.opened.len(), 2, "{:?}", r.opened.keys());
        r.check_unchanged().unwrap();
        crate::usd_io::clips::input_stamp(&r).unwrap();
        // Saved by rename (as painterly and most tools save): a new inode.
        let next = dir.join("sub.next");
        std::fs::write(&next, "#usda 1.0\ndef Xform \"S\"\n{\n}\n").unwrap();
        std::fs::rename(&next, &sub).unwrap();
        let e = r.check_unchanged().unwrap_err();
        assert_eq!(e.file.as_deref(), Some(sub.as_path()), "{e}");
        assert!(
            e.message
                .starts_with("changed while painterly read it (saved during this run?)"),
            "{e}"
        );
        for digest in [crate::usd_io::clips::input_stamp, crate::usd_io::clips::input_hash] {
            assert_eq!(digest(&r).unwrap_err().file.as_deref(), Some(sub.as_path()));
        }
        // Saved in place, a byte longer: the same inode, another size.
        let r = StageReader::open_mapped(&root).unwrap();
        std::fs::write(&root, "#usda 1.0\n(\n    subLayers = [@./sub.usda@]\n)\n\n").unwrap();
        assert_eq!(r.check_unchanged().unwrap_err().file.as_deref(), Some(root.as_path()));
    }

    #[test]
    fn read_children_are_the_children_usd_core_lists() {
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def Xform "L"
{
    def Xform "on" {}
    def Xform "off" (active = false) {}
    over "ghost" {}
    class Xform "abstract" {}
}
"#,
        );
        let l = r.require_prim("/L").unwrap();
        let names = |v: Vec<usd::Prim>| {
            v.iter()
                .map(|p| p.path().name().unwrap().to_string())
                .collect::<Vec<_>>()
        };
        assert_eq!(names(r.read_children(&l).unwrap()), ["on"]);
        let reasons: Vec<_> = l
            .children()
            .unwrap()
            .iter()
            .map(|c| r.unread_reason(c).unwrap())
            .collect();
        assert_eq!(
            reasons,
            [
                None,
                Some("deactivated (active = false)"),
                Some("only an over (no def)"),
                Some("abstract (a class)")
            ]
        );
    }

    #[test]
    fn value_offset_is_the_offset_that_reaches_the_strongest_opinion() {
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def Xform "Src"
{
    double time = 2
}
def Xform "Shifted" (references = </Src> (offset = 10; scale = 2))
{
}
def Xform "Plain" (references = </Src>)
{
}
def Xform "Over" (references = </Src> (offset = 10; scale = 2))
{
    double time = 3
}
"#,
        );
        let at = |p: &str| {
            let prim = r.require_prim(p).unwrap();
            r.value_offset(&prim, "time").unwrap().map(|(o, s, _)| (o, s))
        };
        assert_eq!(at("/Src"), None);
        assert_eq!(at("/Shifted"), Some((10.0, 2.0)));
        assert_eq!(at("/Plain"), None);
        // A local opinion wins, and it is not behind the reference's offset.
        assert_eq!(at("/Over"), None);
    }

    #[test]
    fn a_sample_holds_up_to_a_block_after_it() {
        // usd-core 26.11 on these samples, at t = 0, 1, 2, 2.9, 3, 4, 5, 6, 7, 8:
        // 1, 1, 1, 1, None, None, 5, 6, 7, 7.
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def Xform "P"
{
    double x.timeSamples = {1: 1, 3: None, 5: 5, 7: 7}
    double y.timeSamples = {1: None, 2: 4}
}
"#,
        );
        let p = r.require_prim("/P").unwrap();
        let at = |name: &str, t: f64| r.typed(&p, name, Some(t), "double", values::scalar).unwrap();
        let got: Vec<_> = [0.0, 1.0, 2.0, 2.9, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
            .map(|t| at("x", t))
            .to_vec();
        let want = [1.0, 1.0, 1.0, 1.0]
            .map(Some)
            .into_iter()
            .chain([None, None])
            .chain([5.0, 6.0, 7.0, 7.0].map(Some));
        assert_eq!(got, want.collect::<Vec<_>>());
        // A block first: nothing before the next sample.
        assert_eq!(
            [0.0, 1.0, 1.5, 2.0, 3.0].map(|t| at("y", t)),
            [None, None, None, Some(4.0), Some(4.0)]
        );
    }

    #[test]
    fn transforms_hold_an_op_up_to_a_block_and_skip_inverse_pairs() {
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def Xform "Held"
{
    double3 xformOp:translate.timeSamples = {1: (1, 2, 3), 6: None, 12: (3, 2, 1)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Xform "Pair"
{
    matrix4d xformOp:transform = ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 0, 0), (0, 0, 0, 1))
    double3 xformOp:scale = (2, 2, 2)
    uniform token[] xformOpOrder = ["xformOp:transform", "!invert!xformOp:transform", "xformOp:scale"]
}
def Xform "Two"
{
    double3 xformOp:translate:a = (1, 0, 0)
    double3 xformOp:translate:b = (0, 1, 0)
    uniform token[] xformOpOrder = ["xformOp:translate:a", "!invert!xformOp:translate:b"]
}
"#,
        );
        let origin = |path: &str, t: f64| {
            let m = r.local_to_world(&r.require_prim(path).unwrap(), t).unwrap();
            m.transform_point3(glam::DVec3::ZERO).to_array()
        };
        // usd-core 26.11 on this text gives every value below. The sample at
        // 1 holds to the block at 6; none from 6 to 12.
        assert_eq!(origin("/Held", 3.0), [1.0, 2.0, 3.0]);
        assert_eq!(origin("/Held", 5.5), [1.0, 2.0, 3.0]);
        assert_eq!(origin("/Held", 6.0), [0.0, 0.0, 0.0]);
        assert_eq!(origin("/Held", 9.0), [0.0, 0.0, 0.0]);
        assert_eq!(origin("/Held", 12.0), [3.0, 2.0, 1.0]);
        // A singular transform beside its own inverse cancels (no error).
        let pair = r.local_to_world(&r.require_prim("/Pair").unwrap(), 1.0).unwrap();
        assert_eq!(pair, DMat4::from_scale(glam::DVec3::splat(2.0)));
        // Two ops of different attributes never cancel: a, then b inverted.
        assert_eq!(origin("/Two", 1.0), [1.0, -1.0, 0.0]);
    }
}
