//! A composed stage plus the file it came from, with readers that fail with
//! errors naming the prim and attribute.
//!
//! Everything painterly reads goes through here, so "which file, which prim,
//! which attribute" is attached in one place.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::DMat4;
use openusd::sdf::{self, Value};
use openusd::usd::{self, TimeCode};
use openusd_schemas::geom::XformCache;

use super::compose_watch;
use super::crate_samples::CrateSamples;
use super::guard::Guard;
use super::values;
use crate::error::{Error, Result};

/// A prim of an opened stage (a handle: cheap to clone, tied to its stage's thread).
pub type Prim = usd::Prim;

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
    /// Whether the layers are mapped files on disk, unedited, for one
    /// command ([`StageReader::open_mapped`]): only then are time samples read
    /// straight from the files ([`super::crate_samples`]) and fixed world
    /// transforms kept ([`StageReader::local_to_world`]).
    pub mapped: bool,
    /// World transforms of a mapped stage by prim, once computed: `None`
    /// where an op of the prim or an ancestor may vary in time. A bake asks
    /// for every stroke layer's transform every frame.
    pub(crate) fixed_transforms: Mutex<HashMap<sdf::Path, Option<DMat4>>>,
}

/// A sublayer, reference or payload whose asset (or target prim) is missing.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnresolvedAsset {
    /// The asset path as authored.
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
        Ok(())
    }
}

/// The default resolver, handing out read-only memory mappings of files
/// instead of reading them. For readers that live for one command (a bake,
/// an assembly, a provenance read): the only ones that may use it.
pub(crate) fn mapped_resolver() -> openusd::ar::DefaultResolver {
    // SAFETY (the promise `map_files` asks for: a mapped file is not modified
    // while mapped): painterly and usd-core replace the files they write by
    // rename, never writing into one (`--in-place` edits too), so a mapping
    // keeps its bytes for the command's duration. A program truncating an
    // input in place under a running bake is the documented exception
    // (README, Limits).
    #[allow(unsafe_code)]
    unsafe {
        openusd::ar::DefaultResolver::new().map_files()
    }
}

impl StageReader {
    /// Opens and composes `path` (`.usda`, `.usdc` or `.usdz`), reading
    /// every layer into memory: for readers that live on while the user may
    /// rewrite the files (the preview, the Python API).
    pub fn open(path: &Path) -> Result<Self> {
        let path_str = Self::checked_input(path)?;
        Self::compose(path, path_str, openusd::ar::DefaultResolver::new())
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
        let meta = std::fs::metadata(path).map_err(|e| Error::msg(format!("cannot open input: {e}")).in_file(path))?;
        if !meta.is_file() {
            return Err(Error::msg("cannot open input: not a regular file").in_file(path));
        }
        path.to_str()
            .ok_or_else(|| Error::msg("input path is not valid UTF-8").in_file(path))
    }

    /// Opens and composes the layer `identifier` through `resolver` (see
    /// [`super::memory`]), with the checks of [`StageReader::open`]; errors
    /// name `path`.
    pub fn compose<R: openusd::ar::Resolver + 'static>(path: &Path, identifier: &str, resolver: R) -> Result<Self> {
        // Every layer passes the composition guard (nesting, namespace depth,
        // inherit cycles) before openusd parses or composes it, and openusd
        // runs under watch (panics, crashes, time limit).
        let guard = Guard::default();
        let first_problem = |e: Error| guard.problems().into_iter().next().unwrap_or(e).in_file(path);
        let stage = compose_watch::watched(path, || {
            let stage = usd::Stage::builder()
                .schema_registry(openusd_schemas::schema_registry())
                .resolver(guard.resolver_over(resolver))
                .open(identifier)
                .map_err(|e| first_problem(Error::msg(format!("cannot read USD file: {e}"))))?;
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
                .map_err(|e| first_problem(Error::msg(format!("cannot read USD file: {e}"))))?;
            Ok(stage)
        })?;
        if let Some(e) = guard.problems().into_iter().next() {
            return Err(e.in_file(path));
        }
        let unresolved = unresolved_assets(&stage);
        Ok(StageReader {
            stage,
            file: path.to_path_buf(),
            unresolved,
            input_hash: std::sync::OnceLock::new(),
            mapped: false,
            fixed_transforms: Mutex::default(),
        })
    }

    /// Fails naming every missing sublayer, reference and payload: a bake
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
            all => Err(Error::msg(format!(
                "{} missing assets: {}",
                all.len(),
                all.iter().map(UnresolvedAsset::describe).collect::<Vec<_>>().join("; ")
            ))),
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

    /// The prim at `path`, or an error saying it is missing.
    pub fn require_prim(&self, path: &str) -> Result<usd::Prim> {
        self.prim(path)?.ok_or_else(|| Error::prim(path, "prim does not exist"))
    }

    /// Checks that `path` names a `Camera` prim (the `--camera` of bake,
    /// render and key): a Mesh or an Xform there is a mistake, not a camera.
    pub fn require_camera(&self, path: &str, origin: &str) -> Result<()> {
        let prim = self
            .prim(path)?
            .ok_or_else(|| Error::prim(path, format!("the camera named by {origin} does not exist")))?;
        match self.type_name(&prim)?.as_str() {
            "Camera" => Ok(()),
            "" => Err(Error::prim(
                path,
                format!("{origin} names an untyped prim, not a Camera"),
            )),
            ty => Err(Error::prim(path, format!("{origin} names a {ty} prim, not a Camera"))),
        }
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

    /// Whether the attribute has any authored opinion (default or samples).
    pub fn has_authored(&self, prim: &usd::Prim, name: &str) -> Result<bool> {
        prim.attribute(name)
            .has_authored_value()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read: {e}")))
    }

    /// The attribute's resolved value at `time` (None = default value).
    pub fn value(&self, prim: &usd::Prim, name: &str, time: Option<f64>) -> Result<Option<Value>> {
        let attr = prim.attribute(name);
        let v = attr
            .get_at::<Value>(time.map(TimeCode::new))
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read: {e}")))?;
        Ok(v.filter(|v| !matches!(v, Value::None | Value::ValueBlock)))
    }

    /// An attribute's time samples read one at a time from the crate file
    /// that authors them, where that is exact (see [`CrateSamples`]).
    pub fn crate_samples(&self, prim: &usd::Prim, name: &str) -> Option<CrateSamples> {
        if !self.mapped {
            return None;
        }
        CrateSamples::open(&self.stage, prim, name)
    }

    /// Authored time-sample times of an attribute (empty when none).
    pub fn sample_times(&self, prim: &usd::Prim, name: &str) -> Result<Vec<f64>> {
        prim.attribute(name)
            .time_sample_times()
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read time samples: {e}")))
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

    /// Relationship targets (forwarded targets are not followed).
    pub fn targets(&self, prim: &usd::Prim, name: &str) -> Result<Vec<String>> {
        prim.relationship(name)
            .targets()
            .map(|v| v.iter().map(|p| p.as_str().to_string()).collect())
            .map_err(|e| Error::attr(prim.path(), name, format!("cannot read relationship: {e}")))
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
        match self.value(prim, name, time)? {
            None => Ok(None),
            Some(v) => convert(&v).map(Some).ok_or_else(|| {
                Error::attr(
                    prim.path(),
                    name,
                    format!("expected {expected}, found {}", values::kind_name(&v)),
                )
                .rule(crate::rule::Rule::AttributeType)
            }),
        }
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
        let varies = self.transform_might_vary(prim)?;
        let m = self.compute_local_to_world(prim, time)?;
        lock().insert(prim.path().clone(), (!varies).then_some(m));
        Ok(m)
    }

    /// Whether an op of `prim` or of an ancestor up to the nearest
    /// `!resetXformStack!` may vary in time (C++
    /// `UsdGeomXformCache::TransformMightBeTimeVarying`, up the chain).
    fn transform_might_vary(&self, prim: &usd::Prim) -> Result<bool> {
        let mut cache = XformCache::new(None::<TimeCode>);
        let mut at = Some(prim.clone());
        while let Some(p) = at {
            let fail = |e: openusd_schemas::SchemaError| Error::prim(p.path(), format!("cannot read transform: {e}"));
            if cache.transform_might_be_time_varying(&p).map_err(fail)? {
                return Ok(true);
            }
            if cache.resets_xform_stack(&p).map_err(fail)? {
                break;
            }
            at = p.parent();
        }
        Ok(false)
    }

    fn compute_local_to_world(&self, prim: &usd::Prim, time: f64) -> Result<DMat4> {
        let mut cache = XformCache::new(TimeCode::new(time));
        let m = cache
            .local_to_world_transform(prim)
            .map_err(|e| Error::prim(prim.path(), format!("cannot compute transform: {e}")))?;
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
            meters_per_unit: num("metersPerUnit"),
            up_axis: get("upAxis").as_ref().and_then(values::token),
            malformed,
        }
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
                asset: asset_path,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: introduced_by,
                reason: "not found".into(),
            },
            D::MalformedLayer {
                asset_path,
                arc: a,
                introduced_by,
                site_path,
                reason,
            } => UnresolvedAsset {
                asset: asset_path,
                arc: arc(&a),
                prim: Some(site_path.as_str().to_string()),
                layer: introduced_by,
                reason: format!("cannot be read: {reason}"),
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
                asset: asset_path,
                arc: "sublayer".into(),
                prim: None,
                layer: introduced_by,
                reason: "not found".into(),
            },
            D::MalformedSublayer {
                asset_path,
                introduced_by,
                reason,
            } => UnresolvedAsset {
                asset: asset_path,
                arc: "sublayer".into(),
                prim: None,
                layer: introduced_by,
                reason: format!("cannot be read: {reason}"),
            },
            _ => continue,
        };
        if !out.contains(&item) {
            out.push(item);
        }
    }
    // Composition reports them in hash order.
    out.sort_by(|a, b| (&a.layer, &a.prim, &a.asset).cmp(&(&b.layer, &b.prim, &b.asset)));
    out
}

#[cfg(test)]
mod tests {
    use super::super::atomic::TempDir;
    use super::*;
    use glam::DVec3;

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
}
