//! A layer of `over` specs with time samples (SPEC §7), held in memory and
//! written whole: the binding cache, and the specs a streamed bake
//! ([`super::bake_layer`]) writes around its samples.
//!
//! The layer is written to a temporary file beside the target, which is
//! then renamed, so a failed write never leaves a partial file. `.usdc` goes through painterly's own crate writer ([`super::usdc`]),
//! buffered.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use openusd::sdf::{self, ChildrenKey, FieldKey, SpecType, Specifier, Value, Variability};

pub use super::atomic::{write_atomic, write_atomic_with};
use super::stage::StageMetadata;
use super::usdc::{self, CrateStream, Stored};
use crate::error::{Error, Result};

/// One attribute to author.
struct AttrOut {
    type_name: &'static str,
    samples: Samples,
    metadata: Vec<(&'static str, Value)>,
}

/// An attribute's time samples: values in memory, or values a crate stream
/// already wrote, whose handles the writer asks for by this number when it
/// writes the attribute (a streamed bake keeps them out of memory).
enum Samples {
    Values(Vec<(f64, Value)>),
    Streamed(usize),
    /// A default value and no samples (what a binding cache holds).
    Default(Value),
}

/// Streamed samples' numbers by attribute path, for [`usdc::add_layer_specs`].
type StreamedSamples = std::collections::HashMap<String, usize>;

#[derive(Default)]
struct PrimOut {
    attrs: BTreeMap<String, AttrOut>,
    blocked_rels: Vec<String>,
}

/// An override layer under construction.
pub struct OverLayer {
    meta: StageMetadata,
    prims: BTreeMap<String, PrimOut>,
    custom_layer_data: Vec<(String, Value)>,
}

/// Output formats, chosen by the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Usda,
    Usdc,
}

impl Format {
    /// `.usda` or `.usdc` (`.usd` is written as crate).
    pub fn from_path(path: &Path) -> Result<Format> {
        // In any case, as usd-core's Sdf.FileFormat.FindByExtension.
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        match ext.as_str() {
            "usda" => Ok(Format::Usda),
            "usdc" | "usd" => Ok(Format::Usdc),
            _ => Err(Error::usage("output must end in .usdc, .usd or .usda").in_file(path)),
        }
    }
}

impl OverLayer {
    /// An empty layer carrying the input's stage metadata.
    pub fn new(meta: StageMetadata) -> Self {
        OverLayer {
            meta,
            prims: BTreeMap::new(),
            custom_layer_data: Vec::new(),
        }
    }

    /// Records where a bake came from in `customLayerData["painterly"]`.
    pub fn set_provenance(&mut self, p: &super::bake_layer::Provenance) {
        use super::bake_layer::DataValue;
        let dict = p
            .fields()
            .into_iter()
            .map(|(k, v)| {
                let v = match v {
                    DataValue::Str(s) => Value::String(s),
                    DataValue::Int(i) => Value::Int(i as i32),
                    DataValue::Strs(v) => Value::StringVec(v),
                };
                (k.to_string(), v)
            })
            .collect();
        self.custom_layer_data
            .push(("painterly".to_string(), Value::Dictionary(dict)));
    }

    /// Authors time samples of an attribute (replacing earlier ones).
    pub fn set_samples(
        &mut self,
        prim: &str,
        attr: &str,
        type_name: &'static str,
        samples: Vec<(f64, Value)>,
        metadata: Vec<(&'static str, Value)>,
    ) {
        self.prims.entry(prim.to_string()).or_default().attrs.insert(
            attr.to_string(),
            AttrOut {
                type_name,
                samples: Samples::Values(samples),
                metadata,
            },
        );
    }

    /// Authors an attribute's default value (no time samples).
    pub fn set_default(&mut self, prim: &str, attr: &str, type_name: &'static str, value: Value) {
        self.prims.entry(prim.to_string()).or_default().attrs.insert(
            attr.to_string(),
            AttrOut {
                type_name,
                samples: Samples::Default(value),
                metadata: Vec::new(),
            },
        );
    }

    /// Authors time samples whose values a crate stream already wrote; `key`
    /// is what [`write_to_stream`](Self::write_to_stream) asks for their
    /// handles by.
    pub fn set_streamed_samples(
        &mut self,
        prim: &str,
        attr: &str,
        type_name: &'static str,
        key: usize,
        metadata: Vec<(&'static str, Value)>,
    ) {
        self.prims.entry(prim.to_string()).or_default().attrs.insert(
            attr.to_string(),
            AttrOut {
                type_name,
                samples: Samples::Streamed(key),
                metadata,
            },
        );
    }

    /// Blocks a relationship (explicitly empty targets), e.g. `skel:skeleton`
    /// on a baked skinned mesh so viewers do not deform it twice.
    pub fn block_relationship(&mut self, prim: &str, rel: &str) {
        let p = self.prims.entry(prim.to_string()).or_default();
        if !p.blocked_rels.iter().any(|r| r == rel) {
            p.blocked_rels.push(rel.to_string());
        }
    }

    /// Builds the Sdf data: over specs for every authored prim and its ancestors.
    fn into_data(self) -> Result<sdf::Data> {
        let (data, streamed) = self.into_parts()?;
        match streamed.keys().next() {
            Some(attr) => Err(Error::msg(format!(
                "internal: {attr} holds samples of a crate stream; write the layer to that stream"
            ))),
            None => Ok(data),
        }
    }

    /// Writes the layer's specs to the crate stream that stored its samples;
    /// `samples(key)` gives the handles of the samples set with `key`, one
    /// attribute at a time. The caller finishes the stream.
    pub fn write_to_stream<W: std::io::Write + std::io::Seek>(
        self,
        stream: &mut CrateStream<W>,
        samples: &mut dyn FnMut(usize) -> Result<Stored>,
    ) -> Result<()> {
        let (data, streamed) = self.into_parts()?;
        usdc::add_layer_specs(stream, &data, &mut |p| {
            streamed.get(p.as_str()).map(|&key| samples(key)).transpose()
        })
    }

    /// The Sdf data, and the streamed samples it leaves out (by attribute path).
    fn into_parts(self) -> Result<(sdf::Data, StreamedSamples)> {
        let mut streamed = StreamedSamples::new();
        let mut data = sdf::Data::new();
        // Every prim path that needs a spec, with its children names in order.
        let mut children: BTreeMap<String, Vec<String>> = BTreeMap::new();
        children.insert("/".to_string(), Vec::new());
        for path in self.prims.keys() {
            let mut cur = path.as_str();
            loop {
                let (parent, name) = match cur.rsplit_once('/') {
                    Some(("", name)) => ("/", name),
                    Some((parent, name)) => (parent, name),
                    None => break,
                };
                let kids = children.entry(parent.to_string()).or_default();
                let first = !kids.iter().any(|k| k == name);
                if first {
                    kids.push(name.to_string());
                }
                children.entry(cur.to_string()).or_default();
                if parent == "/" || !first {
                    break;
                }
                cur = parent;
            }
        }
        let path = |p: &str| sdf::Path::new(p).map_err(|e| Error::prim(p, format!("invalid path: {e}")));
        let mut prims = self.prims;

        let root = data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
        let m = &self.meta;
        if let Some(v) = m.start_time_code {
            root.add(FieldKey::StartTimeCode, Value::Double(v));
        }
        if let Some(v) = m.end_time_code {
            root.add(FieldKey::EndTimeCode, Value::Double(v));
        }
        if let Some(v) = m.time_codes_per_second {
            root.add(FieldKey::TimeCodesPerSecond, Value::Double(v));
        }
        if let Some(v) = m.frames_per_second {
            root.add("framesPerSecond", Value::Double(v));
        }
        if let Some(v) = &m.up_axis {
            root.add("upAxis", Value::Token(v.as_str().into()));
        }
        if let Some(v) = m.meters_per_unit {
            root.add("metersPerUnit", Value::Double(v));
        }
        if !self.custom_layer_data.is_empty() {
            root.add(
                "customLayerData",
                Value::Dictionary(self.custom_layer_data.into_iter().collect()),
            );
        }
        root.add(
            "documentation",
            Value::String("Baked by painterly: over specs only; sublayer above the input.".into()),
        );
        if let Some(kids) = children.get("/") {
            if !kids.is_empty() {
                root.add(
                    ChildrenKey::PrimChildren,
                    Value::TokenVec(kids.iter().map(|k| k.as_str().into()).collect()),
                );
            }
        }

        for (prim_path, kids) in &children {
            if prim_path == "/" {
                continue;
            }
            let p = path(prim_path)?;
            let out = prims.remove(prim_path);
            let mut props: Vec<String> = Vec::new();
            if let Some(o) = &out {
                props.extend(o.attrs.keys().cloned());
                props.extend(o.blocked_rels.iter().cloned());
            }
            {
                let spec = data.create_spec(p, SpecType::Prim);
                spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Over));
                if !kids.is_empty() {
                    spec.add(
                        ChildrenKey::PrimChildren,
                        Value::TokenVec(kids.iter().map(|k| k.as_str().into()).collect()),
                    );
                }
                if !props.is_empty() {
                    spec.add(
                        ChildrenKey::PropertyChildren,
                        Value::TokenVec(props.iter().map(|k| k.as_str().into()).collect()),
                    );
                }
            }
            let Some(o) = out else { continue };
            for (name, a) in o.attrs {
                let ap = path(&format!("{prim_path}.{name}"))?;
                let spec = data.create_spec(ap, SpecType::Attribute);
                spec.add(FieldKey::TypeName, Value::Token(a.type_name.into()));
                spec.add(FieldKey::Custom, Value::Bool(false));
                spec.add(FieldKey::Variability, Value::Variability(Variability::Varying));
                for (k, v) in a.metadata {
                    spec.add(k, v);
                }
                match a.samples {
                    // Moved, not cloned: bakes hold hundreds of MB of samples.
                    Samples::Values(v) => spec.add(FieldKey::TimeSamples, Value::TimeSamples(v)),
                    Samples::Default(v) => spec.add(FieldKey::Default, v),
                    Samples::Streamed(key) => {
                        streamed.insert(format!("{prim_path}.{name}"), key);
                    }
                }
            }
            for rel in &o.blocked_rels {
                let rp = path(&format!("{prim_path}.{rel}"))?;
                let spec = data.create_spec(rp, SpecType::Relationship);
                spec.add(FieldKey::Custom, Value::Bool(false));
                spec.add(FieldKey::Variability, Value::Variability(Variability::Uniform));
                spec.add(
                    FieldKey::TargetPaths,
                    Value::PathListOp(sdf::PathListOp::explicit(Vec::<sdf::Path>::new())),
                );
            }
        }
        Ok((data, streamed))
    }

    /// Serialises to bytes in `format`.
    pub fn into_bytes(self, format: Format) -> Result<Vec<u8>> {
        let data = self.into_data()?;
        match format {
            Format::Usdc => Ok(super::usdc::write_layer(&data, Cursor::new(Vec::new()))?.into_inner()),
            Format::Usda => {
                let s = openusd::usda::TextWriter::write_to_string(&data)
                    .map_err(|e| Error::msg(format!("cannot serialise layer: {e}")))?;
                Ok(s.into_bytes())
            }
        }
    }

    /// Writes atomically: a temporary file beside `path`, then a rename.
    /// `.usdc` is streamed to the file rather than built in memory first.
    pub fn write(self, path: &Path) -> Result<()> {
        match Format::from_path(path)? {
            Format::Usdc => super::usdc::write_layer_file(path, &self.into_data()?),
            Format::Usda => write_atomic(path, &self.into_bytes(Format::Usda)?),
        }
    }
}

/// Checks that `path`, about to be written between `@`s as an asset path
/// (a sublayer, a clip), reads back in usd-core: it allows no `@` there and
/// no control character (a tab or newline in a folder's name). `file` is
/// the file the path names, for the message.
pub fn check_asset_path(path: &str, file: &Path) -> Result<()> {
    let bad = if path.contains('@') {
        "'@'".to_string()
    } else if let Some(c) = path.chars().find(|c| c.is_control()) {
        format!("a control character ({c:?})")
    } else {
        return Ok(());
    };
    Err(Error::msg(format!(
        "its path contains {bad}, which a USD asset path cannot hold: rename the file or folder"
    ))
    .in_file(file))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_follow_the_extension_in_any_case() {
        // As Sdf.FileFormat.FindByExtension: "x.USDA" is usda, "x.UsdC" and
        // "x.USD" are crate files (usd-core writes a created x.USDA as text).
        for (name, want) in [
            ("x.USDA", Format::Usda),
            ("x.UsdC", Format::Usdc),
            ("x.USD", Format::Usdc),
        ] {
            assert_eq!(Format::from_path(Path::new(name)).unwrap(), want, "{name}");
        }
        assert!(Format::from_path(Path::new("x.USDZ")).is_err());
    }

    #[test]
    fn write_keeps_defaults_sibling_prims_and_every_blocked_relationship() {
        let dir = super::super::atomic::TempDir::new().unwrap();
        for name in ["cache.usdc", "cache.usda"] {
            let mut l = OverLayer::new(StageMetadata::default());
            l.set_default("/R/A", "v", "int[]", Value::IntVec(vec![1, 2, 3]));
            l.set_default("/R/B", "v", "int[]", Value::IntVec(vec![4]));
            l.block_relationship("/R/A", "skel:skeleton");
            l.block_relationship("/R/A", "proxyPrim");
            l.block_relationship("/R/A", "skel:skeleton");
            let path = dir.path().join(name);
            l.write(&path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let back = sdf::LayerRegistry::read_bytes(openusd::ar::AssetBuffer::Owned(bytes), name).unwrap();
            let p = |s: &str| sdf::Path::new(s).unwrap();
            let tokens = |v: &[&str]| Value::TokenVec(v.iter().map(|&t| t.into()).collect());
            let field = |path: &str, f: &str| back.get_field(&p(path), f).map(|v| v.into_owned()).ok();
            // Over specs for /R and its two children, in order, and nothing else.
            let children = ChildrenKey::PrimChildren.as_str();
            assert_eq!(field("/", children), Some(tokens(&["R"])), "{name}");
            assert_eq!(field("/R", children), Some(tokens(&["A", "B"])), "{name}");
            assert_eq!(field("/R/A.v", "default"), Some(Value::IntVec(vec![1, 2, 3])), "{name}");
            assert_eq!(field("/R/B.v", "default"), Some(Value::IntVec(vec![4])), "{name}");
            let props = ChildrenKey::PropertyChildren.as_str();
            assert_eq!(
                field("/R/A", props),
                Some(tokens(&["v", "skel:skeleton", "proxyPrim"])),
                "{name}"
            );
            for rel in ["/R/A.skel:skeleton", "/R/A.proxyPrim"] {
                assert_eq!(back.spec_type(&p(rel)), Some(SpecType::Relationship), "{name} {rel}");
            }
            let mut paths: Vec<String> = back.spec_paths().iter().map(|s| s.as_str().to_string()).collect();
            paths.sort();
            assert_eq!(
                paths,
                [
                    "/",
                    "/R",
                    "/R/A",
                    "/R/A.proxyPrim",
                    "/R/A.skel:skeleton",
                    "/R/A.v",
                    "/R/B",
                    "/R/B.v"
                ],
                "{name}"
            );
        }
    }
}
