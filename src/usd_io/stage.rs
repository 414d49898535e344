//! A composed stage plus the file it came from, with readers that fail with
//! errors naming the prim and attribute.
//!
//! Everything painterly reads goes through here, so "which file, which prim,
//! which attribute" is attached in one place.

use std::path::{Path, PathBuf};

use glam::DMat4;
use openusd::sdf::Value;
use openusd::usd::{self, TimeCode};
use openusd_schemas::geom::XformCache;

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
}

/// Stage-level metadata a bake copies into its output layer.
#[derive(Debug, Clone, PartialEq)]
pub struct StageMetadata {
    pub start_time_code: Option<f64>,
    pub end_time_code: Option<f64>,
    pub time_codes_per_second: Option<f64>,
    pub frames_per_second: Option<f64>,
    pub up_axis: Option<String>,
    pub meters_per_unit: Option<f64>,
}

impl StageReader {
    /// Opens and composes `path` (`.usda`, `.usdc` or `.usdz`).
    pub fn open(path: &Path) -> Result<Self> {
        let meta = std::fs::metadata(path).map_err(|e| Error::msg(format!("cannot open input: {e}")).in_file(path))?;
        if !meta.is_file() {
            return Err(Error::msg("cannot open input: not a regular file").in_file(path));
        }
        let path_str = path
            .to_str()
            .ok_or_else(|| Error::msg("input path is not valid UTF-8").in_file(path))?;
        let stage = usd::Stage::builder()
            .schema_registry(openusd_schemas::schema_registry())
            .open(path_str)
            .map_err(|e| Error::msg(format!("cannot read USD file: {e}")).in_file(path))?;
        let reader = StageReader {
            stage,
            file: path.to_path_buf(),
        };
        // The pseudo-root must be readable; a truncated crate file can open
        // lazily and only fail here.
        reader
            .stage
            .traverse(usd::PrimPredicate::DEFAULT, |_| {})
            .map_err(|e| Error::msg(format!("cannot read USD file: {e}")).in_file(path))?;
        Ok(reader)
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
    pub fn local_to_world(&self, prim: &usd::Prim, time: f64) -> Result<DMat4> {
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
        StageMetadata {
            start_time_code: get("startTimeCode").as_ref().and_then(values::scalar),
            end_time_code: get("endTimeCode").as_ref().and_then(values::scalar),
            time_codes_per_second: get("timeCodesPerSecond").as_ref().and_then(values::scalar),
            frames_per_second: get("framesPerSecond").as_ref().and_then(values::scalar),
            up_axis: get("upAxis").as_ref().and_then(values::token),
            meters_per_unit: get("metersPerUnit").as_ref().and_then(values::scalar),
        }
    }
}
