//! The binding cache of a chunked bake: `<stem>.clips/<stem>.binding.usdc`.
//!
//! Every task of a chunked bake needs the same binding of the input's stroke
//! points to the rest proxy, and computing it (closest point on the proxy for
//! every point) is most of a task's fixed cost. As with OpenSubdiv's stencil
//! tables, it is computed once and applied every frame: the first process
//! that binds (the farm submission, or the first task) leaves the binding
//! here as an override layer of `painterly:bindVertices`/`bindWeights`
//! defaults, stamped with the input's hash and painterly's version; later
//! tasks and the assembly read it instead of binding again.
//!
//! A cache never fails a bake: a missing, stale or malformed one is ignored
//! (with a `-v` line) and the binding computed, as without it. An entry is
//! used only after the checks an authored binding gets (SPEC §3 table: one
//! in-range entry per point, finite weights).

use std::path::Path;

use openusd::sdf::{self, Value};

use super::bake_layer::{open_mapped_layer, provenance_of, Provenance};
use super::layer::OverLayer;
use super::scene::{check_binding, Rig};
use super::stage::StageMetadata;
use super::values;
use crate::bind::Binding;
use crate::error::Result;

/// An opened binding cache that matches the input.
pub struct BindingCache {
    layer: sdf::Layer,
}

impl BindingCache {
    /// The cache at `path` when it exists and was written for an input
    /// with `input_hash` by this painterly; None otherwise.
    pub fn open(path: &Path, input_hash: &str) -> Option<BindingCache> {
        if !path.is_file() {
            return None;
        }
        let layer = match open_mapped_layer(path) {
            Ok(l) => l,
            Err(e) => {
                crate::vlog!("binding cache ignored: {e}");
                return None;
            }
        };
        match provenance_of(&layer) {
            Some(p) if p.input_hash.as_deref() == Some(input_hash) && p.version == env!("CARGO_PKG_VERSION") => {
                Some(BindingCache { layer })
            }
            _ => {
                crate::vlog!(
                    "binding cache {} ignored: written for another input or painterly version",
                    path.display()
                );
                None
            }
        }
    }

    /// Gives every layer of `rigs` without a binding of its own the cached
    /// one, when the cache holds a valid one for it; returns how many did.
    pub fn fill(&self, rigs: &mut [Rig]) -> usize {
        let mut filled = 0;
        for rig in rigs {
            let proxy_points = rig.proxy.rest.len();
            for l in rig.layers.iter_mut().filter(|l| l.cached_binding.is_none()) {
                let verts = self
                    .field(&l.path, "painterly:bindVertices")
                    .and_then(|v| values::int3_array(&v));
                let weights = self
                    .field(&l.path, "painterly:bindWeights")
                    .and_then(|v| values::vec3_array(&v));
                let (Some(verts), Some(weights)) = (verts, weights) else {
                    continue;
                };
                match check_binding(&l.path, &verts, &weights, l.rest_points.len(), proxy_points) {
                    Ok(b) => {
                        l.cached_binding = Some(b);
                        filled += 1;
                    }
                    Err(e) => crate::vlog!("binding cache entry ignored: {e}"),
                }
            }
        }
        filled
    }

    fn field(&self, prim: &str, attr: &str) -> Option<Value> {
        let path = sdf::Path::new(&format!("{prim}.{attr}")).ok()?;
        self.layer
            .data()
            .get_field(&path, "default")
            .ok()
            .map(|v| v.into_owned())
    }
}

/// Writes the bindings of `layers` (stroke layer prim path, binding) to a
/// cache at `path` for an input with `input_hash` (temporary file, rename).
pub fn write<'a>(
    path: &Path,
    input: &Path,
    input_hash: &str,
    layers: impl IntoIterator<Item = (&'a str, &'a Binding)>,
) -> Result<()> {
    let mut out = OverLayer::new(StageMetadata::default());
    out.set_provenance(&Provenance {
        input: input.to_string_lossy().into_owned(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        input_hash: Some(input_hash.to_string()),
        ..Default::default()
    });
    for (prim, b) in layers {
        let (verts, weights) = values::binding_values(b);
        out.set_default(prim, "painterly:bindVertices", "int3[]", verts);
        out.set_default(prim, "painterly:bindWeights", "float3[]", weights);
    }
    out.write(path)
}
