//! USD input and output: the only modules that touch `openusd`.
//!
//! Data flows one way: [`stage`] and [`scene`] read a composed stage into plain
//! arrays, the math modules evaluate, and [`bake_layer`] streams the override
//! layer of a bake ([`layer`] holds the specs of the smaller layers).

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
