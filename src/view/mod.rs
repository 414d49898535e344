//! View-dependent geometry (Rademacher 1999, §3–4): pure math, no USD, no I/O.
//!
//! A view-dependent mesh has a *base model* and *key deformations*, each seen
//! from a *key viewpoint*: a unit direction in the mesh's local space, from
//! the centre of the base model's bounding box towards the key camera. At
//! render time the eye direction (camera position minus that centre,
//! normalised) picks a blend of the keys:
//!
//! * [`ViewBlender`] precomputes the convex hull of the key directions once
//!   and, per frame, turns an eye direction into [`ViewWeights`] (§3.2, with
//!   the uncovered-region rules of §3.3, see [`Uncovered`]).
//! * [`blend_offsets`] applies those weights to point arrays.
//! * [`NaturalCubicSpline`] interpolates each key viewpoint's offsets over
//!   time for animated base models (§4.2).
//!
//! Blends are blends of *offsets* from the base: for key `k`,
//! `offset_k = key_points_k − base`, and the blended shape is
//! `base_scale · base + Σ w_k · offset_k` (see [`ViewWeights::base_scale`]).
//! The weights sum to one, so this is identical to blending the absolute
//! key shapes, and it is what lets the same weights drive an animated base
//! (Rademacher §4.2 adds interpolated offsets to the moving base).

#![warn(missing_docs)]

mod blend;
mod hull;
mod spline;

pub use blend::{blend_offsets, Uncovered, ViewBlender, ViewWeights};
pub use hull::{same_direction, SAME_DIRECTION_TOLERANCE};
pub use spline::{weighted_sum, NaturalCubicSpline};

use std::fmt;

/// Whether an eye `offset` from the centre of a box (diagonal `extent`,
/// centre `centre` from the origin) is at that centre up to rounding: within
/// 1e-6 × (extent + |centre|), or exactly there. The box is f32 and the
/// camera's transform a product of matrices, so nearer than that an eye
/// direction is made of noise.
pub fn eye_at_centre(offset: glam::DVec3, extent: f64, centre: glam::DVec3) -> bool {
    let d = offset.length();
    d <= 1e-6 * (extent + centre.length()) || d <= f64::MIN_POSITIVE
}

/// Why key viewpoints, a sharpness or a set of key times were rejected.
///
/// Each variant names the offending input by index so that callers can point
/// the user at the authored prim.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewError {
    /// A key direction has a component that is NaN or infinite.
    NonFiniteDirection {
        /// Index of the key viewpoint.
        index: usize,
    },
    /// A key direction has zero length, so it names no viewpoint.
    ZeroDirection {
        /// Index of the key viewpoint.
        index: usize,
    },
    /// Two key viewpoints have the same direction (within
    /// [`SAME_DIRECTION_TOLERANCE`]); they must be merged into one viewpoint
    /// (keys at different times) by the caller.
    DuplicateDirection {
        /// Index of the earlier viewpoint.
        first: usize,
        /// Index of the later viewpoint.
        second: usize,
    },
    /// The sharpness exponent α must be finite and greater than zero.
    InvalidSharpness(f64),
    /// The convex hull of the key directions could not be built reliably
    /// (directions that are nearly coincident or nearly coplanar at the
    /// limit of floating-point precision).
    Hull(String),
    /// A spline needs at least one key time.
    NoKeyTimes,
    /// A key time is NaN or infinite.
    NonFiniteTime {
        /// Index of the key time.
        index: usize,
    },
    /// Key times must be strictly increasing; `index` is the first time that
    /// is not greater than its predecessor.
    TimesNotIncreasing {
        /// Index of the offending key time.
        index: usize,
    },
}

impl fmt::Display for ViewError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ViewError::NonFiniteDirection { index } => {
                write!(f, "key viewpoint {index}: direction is not finite")
            }
            ViewError::ZeroDirection { index } => {
                write!(f, "key viewpoint {index}: direction has zero length")
            }
            ViewError::DuplicateDirection { first, second } => write!(
                f,
                "key viewpoints {first} and {second} have the same direction; \
                 give them a shared viewpoint (keys at different times) or distinct directions"
            ),
            ViewError::InvalidSharpness(s) => {
                write!(f, "sharpness must be finite and > 0, got {s}")
            }
            ViewError::Hull(msg) => write!(f, "key viewpoint hull: {msg}"),
            ViewError::NoKeyTimes => write!(f, "at least one key time is needed"),
            ViewError::NonFiniteTime { index } => {
                write!(f, "key time {index} is not finite")
            }
            ViewError::TimesNotIncreasing { index } => write!(
                f,
                "key time {index} is not greater than key time {}",
                index.saturating_sub(1)
            ),
        }
    }
}

impl std::error::Error for ViewError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_eye_within_rounding_of_the_centre_is_at_it() {
        use glam::DVec3;
        let c = DVec3::new(3.0, 4.0, 0.0); // |c| = 5; with extent 5, the tolerance is 1e-5
        assert!(eye_at_centre(DVec3::new(0.99e-5, 0.0, 0.0), 5.0, c));
        assert!(!eye_at_centre(DVec3::new(1.1e-5, 0.0, 0.0), 5.0, c));
        // A box of no size at the origin: only there, or so near that the
        // length underflows (1e-300² is below f64's range: no direction).
        assert!(eye_at_centre(DVec3::ZERO, 0.0, DVec3::ZERO));
        assert!(eye_at_centre(DVec3::new(1e-300, 0.0, 0.0), 0.0, DVec3::ZERO));
        assert!(!eye_at_centre(DVec3::new(1e-150, 0.0, 0.0), 0.0, DVec3::ZERO));
    }
}
