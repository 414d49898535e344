//! painterly: painted strokes that follow rigged proxy meshes, in USD.
//!
//! Implements Bassett et al. 2013 (stroke skinning, configuration-space and
//! temporal keyframes) and Rademacher 1999 (view-dependent geometry) over
//! USD files. Data flows one way: [`usd_io`] reads a composed stage into plain
//! arrays, the math modules evaluate, and [`usd_io::bake_layer`] streams the
//! override layer a bake writes ([`usd_io::layer`] builds the specs of the
//! other layers painterly writes).
//!
//! | module | concept |
//! |---|---|
//! | [`mesh`] | proxy topology: fan triangulation, one-rings |
//! | [`extent`] | extents as usd-core computes them (points, curve widths) |
//! | [`bind`] | closest-point binding of stroke points (BVH) |
//! | [`polar`] | the rotation of a 3×3 Procrustes fit without an SVD (Horn's quaternion) |
//! | [`skinning`] | per-vertex Procrustes motions and their blend (Bassett eq. 1) |
//! | [`skel_deform`] | UsdSkel blend shapes, LBS and DQS |
//! | [`frames`] | frame ranges |
//! | [`keys`] | pose keys and temporal keys with sentinels |
//! | [`view`] | view-dependent geometry (Rademacher 1999) |
//! | [`usd_io`] | reading stages, writing layers |
//! | [`character`] | a character resolved for evaluation: rest data once, frames on demand |
//! | [`bake`] | the `bake` command: frames streamed through reader → evaluator → writer |
//! | [`inspect`] | the `inspect` command |
//! | [`farm`] | the `farm` command: chunked bakes as scheduler jobs (Slurm, Open Job Description) |
//! | [`rule`] | the schema rules `inspect` checks, with stable ids |
//! | [`interp`] | configuration-space interpolation (smooth Voronoi, RBF, Shepard) |
//! | [`render`] | the `render` command (`render/mod.rs`) over its math: camera, curves, clipping, rasterising, shading, compositing, sheets (the data types [`usd_io::render_scene`] reads into) |
//! | [`preview`] | the `preview` command: a live view in the browser (loopback server, WebGL2 page) |
//! | [`author`], [`tools`] | `bind`, `key`, `smudge`, `expand`: edits through an edit session; the brushes' math |
//! | [`cli`] | the command line: argument parsing, summary lines, exit codes |
//! | [`error`], [`log`], [`words`] | errors that name file, prim and attribute; `-v` logging and progress bars; plural and number wording |

pub mod author;
pub mod bake;
pub mod bind;
pub mod character;
pub mod cli;
pub mod error;
pub mod extent;
pub mod farm;
pub mod frames;
pub mod gf;
pub mod inspect;
pub mod interp;
pub mod keys;
pub mod log;
pub mod mesh;
pub mod polar;
pub mod preview;
pub mod render;
pub mod rule;
pub mod skel_deform;
pub mod skinning;
#[cfg(test)]
mod test_dir;
pub mod tools;
pub mod usd_io;
pub mod view;
pub mod words;

pub use error::{Error, Result};
