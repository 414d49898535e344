//! USD input and output: the only modules that touch `openusd`.
//!
//! Data flows one way: [`stage`] and [`scene`] read a composed stage into plain
//! arrays, the math modules evaluate, and [`bake_layer`] streams the override
//! layer of a bake ([`layer`] holds the specs of the smaller layers).

pub mod anchor;
pub mod assembly;
pub mod atomic;
pub mod axes;
pub mod bake_layer;
pub mod binding_cache;
pub mod clips;
pub mod compose_watch;
pub mod crate_samples;
pub mod edit;
pub mod guard;
pub mod layer;
pub mod memory;
pub mod regular;
pub mod render_scene;
pub mod scene;
pub mod skel;
pub mod spill;
pub mod stage;
#[cfg(test)]
pub(crate) mod testutil;
pub mod usda_splice;
pub mod usda_text;
pub mod usdc;
pub mod values;
pub mod view_mesh;

/// Whether `name` is one prim name (an identifier: a letter or `_`, then
/// letters, digits and `_`), as one element of a prim path must be.
pub fn is_prim_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c == '_' || c.is_alphabetic()) && chars.all(|c| c == '_' || c.is_alphanumeric())
}
