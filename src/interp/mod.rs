//! Configuration-space interpolation (Bassett et al. 2013, §4).
//!
//! Pure math, no USD and no I/O. Given `n` keys at coordinates `x_i ∈ R^d`
//! (one coordinate per configuration axis), an [`Interpolator`] turns any
//! query configuration `x̂` into basis weights `w_i(x̂)` such that the
//! interpolated value is `ŷ(x̂) = Σ_i w_i(x̂) y_i`. Every method here is linear
//! in the key values, so one weight vector blends a whole layer at once: all
//! stroke points of a position key, or an opacity.
//!
//! Methods ([`Method`]):
//! - smooth Voronoi (the paper's §4.2, eqs. 7–12, α = 0.5, β = 5, γ = 0.2,
//!   ε = 0.2): the default and the only one satisfying requirements R1–R5;
//! - normalized Gaussian RBF (§4.1, eq. 3), for comparison;
//! - Shepard with 1/d² weights (§4.1, eq. 5), for comparison.
//!
//! Every method's weights sum to 1 (a constant key value is reproduced) and
//! reproduce the keys exactly (`w_i(x_j) = δ_ij`). The smooth step S_γ uses
//! the SPEC's erratum to eq. 7 (quadratic pieces divided by 2γ(1 − γ)); see
//! [`smooth_step`].
//!
//! [`naive`] holds a direct O(n⁴d) transcription of eqs. 7–12 that the fast
//! implementation is tested against; [`json`] is the body of the
//! `painterly interpolate` subcommand used by cross-language tests.

pub mod json;
pub mod naive;
mod rbf;
mod shepard;
mod smooth_voronoi;
mod step;
#[cfg(test)]
pub(crate) mod testutil;

pub use step::{smooth_step, smooth_step_derivative};

use std::fmt;

/// Smooth Voronoi α (eq. 11): a_ij samples kernel i at α x_i + (1 − α) x_j.
pub const ALPHA: f64 = 0.5;
/// Smooth Voronoi β (eq. 12): how sharply b_ij switches a key's gradient
/// off when it has no neighbour on the far side.
pub const BETA: f64 = 5.0;
/// γ of the smooth step S_γ (eq. 7), used by the kernels, by b_ij and by the
/// temporal sentinel blends (SPEC §5).
pub const GAMMA: f64 = 0.2;
/// Tikhonov weight ε of the gradient fit (eq. 10's regularisation).
pub const EPSILON: f64 = 0.2;

/// Relative distance under which two keys count as the same point: keys
/// closer than this times the keys' bounding-box diagonal are rejected.
pub const DUPLICATE_TOLERANCE: f64 = 1e-12;

/// The most keys one interpolation takes (README, Limits): smooth Voronoi's
/// set-up costs about n⁴ operations, 4.4 s for 300 keys on this machine.
pub const MAX_KEYS: usize = 300;

/// The RBF radii accepted: within them radius² and 1/radius² are normal f64.
pub const MIN_RADIUS: f64 = 1e-150;
/// See [`MIN_RADIUS`].
pub const MAX_RADIUS: f64 = 1e150;

/// Why the weights at query `x` cannot be given (`w` as computed there): a
/// non-finite coordinate, or a point so far from the keys that its squared
/// distances overflow. `None` when they can.
pub fn query_problem(x: &[f64], w: &[f64]) -> Option<&'static str> {
    if x.iter().any(|v| !v.is_finite()) {
        Some("has a non-finite coordinate")
    } else if w.iter().any(|v| !v.is_finite()) {
        Some("is too far from the keys to weigh (its squared distances overflow)")
    } else {
        None
    }
}

/// Why a set of keys cannot be interpolated.
#[derive(Clone, Debug, PartialEq)]
pub enum InterpError {
    /// No keys at all: there is nothing to interpolate.
    Empty,
    /// `keys.len()` is not a positive multiple of `dim` (or `dim` is 0).
    DimensionMismatch {
        /// The dimension the caller asked for.
        dim: usize,
        /// The length of the flat key array.
        len: usize,
    },
    /// A key has a NaN or infinite coordinate.
    NonFinite {
        /// Index of the offending key.
        key: usize,
    },
    /// Two keys sit at the same coordinates (exactly, or closer than
    /// [`DUPLICATE_TOLERANCE`] × the keys' bounding-box diagonal): the
    /// interpolant would have to take two values at one point.
    DuplicateKeys {
        /// Index of the first key of the pair.
        first: usize,
        /// Index of the second key of the pair (`second > first`).
        second: usize,
    },
    /// Two keys so far apart that their squared distance overflows f64:
    /// no weight can be computed between them.
    TooFarApart {
        /// Index of the first key of the pair.
        first: usize,
        /// Index of the second key of the pair (`second > first`).
        second: usize,
    },
    /// The RBF kernel radius is not a finite positive number whose square
    /// is a normal f64 (1/radius² must be finite).
    InvalidRadius {
        /// The radius given.
        radius: f64,
    },
    /// The RBF interpolation matrix is numerically singular (radius far
    /// too wide for the key spacing).
    SingularSystem,
    /// More keys than [`MAX_KEYS`]: setting up their interpolation grows as
    /// the fourth power of their number.
    TooManyKeys {
        /// How many keys were given.
        count: usize,
    },
}

impl fmt::Display for InterpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InterpError::Empty => write!(f, "no keys to interpolate"),
            InterpError::DimensionMismatch { dim, len } => write!(
                f,
                "key coordinates do not match the dimension: {len} values for dimension {dim}"
            ),
            InterpError::NonFinite { key } => {
                write!(f, "key {key} has a non-finite coordinate")
            }
            InterpError::DuplicateKeys { first, second } => {
                write!(
                    f,
                    "keys {first} and {second} are at the same coordinates (within {DUPLICATE_TOLERANCE:e} of the keys' extent)"
                )
            }
            InterpError::TooFarApart { first, second } => write!(
                f,
                "keys {first} and {second} are too far apart to interpolate (their squared distance overflows): \
                 bring the key coordinates nearer, or give the axes a smaller scale"
            ),
            InterpError::InvalidRadius { radius } => write!(
                f,
                "RBF radius must be a finite positive number between {MIN_RADIUS:e} and {MAX_RADIUS:e} \
                 (its square must be a normal number), got {}",
                crate::error::readable(*radius)
            ),
            InterpError::TooManyKeys { count } => write!(
                f,
                "{count} keys; painterly interpolates at most {MAX_KEYS} (setting them up grows as the fourth power of their number: {MAX_KEYS} take about 5 s): split them over layers or sentinels"
            ),
            InterpError::SingularSystem => write!(
                f,
                "RBF weights cannot be solved accurately: the kernel radius is too wide for the key spacing \
                 (try one near the distance between neighbouring keys)"
            ),
        }
    }
}

impl std::error::Error for InterpError {}

/// Which interpolation scheme to use (USD `painterly:interpolation`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// Smooth Voronoi interpolation (§4.2): the default, no parameters.
    SmoothVoronoi,
    /// Normalized Gaussian RBF (eq. 3) with kernel exp(−‖x − x_i‖² / radius²).
    Rbf {
        /// Kernel radius, in configuration-space units (must be > 0).
        radius: f64,
    },
    /// Shepard inverse-distance weighting with 1/d² weights (eq. 5).
    Shepard,
}

impl Method {
    /// Parses a USD `painterly:interpolation` token (`"smoothVoronoi"`,
    /// `"rbf"` or `"shepard"`); `rbf_radius` is used only by `"rbf"`.
    /// Returns `None` for any other token so the caller can name the prim.
    pub fn from_token(token: &str, rbf_radius: f64) -> Option<Method> {
        match token {
            "smoothVoronoi" => Some(Method::SmoothVoronoi),
            "rbf" => Some(Method::Rbf { radius: rbf_radius }),
            "shepard" => Some(Method::Shepard),
            _ => None,
        }
    }

    /// The USD token naming this method (inverse of [`Method::from_token`]).
    pub fn token(&self) -> &'static str {
        match self {
            Method::SmoothVoronoi => "smoothVoronoi",
            Method::Rbf { .. } => "rbf",
            Method::Shepard => "shepard",
        }
    }
}

/// Basis weights for one set of keys, precomputed once.
///
/// Build it when keys are set or moved (the expensive part: O(n⁴) for smooth
/// Voronoi), then call [`Interpolator::weights`] for every configuration
/// (O(nd + n²)-ish) and blend every key-carried array with the same weights.
#[derive(Clone, Debug)]
pub struct Interpolator {
    method: Method,
    dim: usize,
    n: usize,
    keys: Vec<f64>,
    kind: Kind,
}

#[derive(Clone, Debug)]
enum Kind {
    /// One key: weight 1 everywhere, whatever the method.
    Single,
    SmoothVoronoi(smooth_voronoi::SmoothVoronoi),
    Rbf(rbf::Rbf),
    Shepard,
}

impl Interpolator {
    /// Precomputes the interpolant for `keys`, `n × dim` coordinates stored
    /// row-major (key `i` is `keys[i*dim..(i+1)*dim]`).
    ///
    /// Errors: no keys, a length that is not a multiple of `dim`, a
    /// non-finite coordinate, two keys at the same coordinates, or (RBF) a
    /// bad radius or a singular system.
    pub fn new(method: Method, dim: usize, keys: &[f64]) -> Result<Self, InterpError> {
        let (n, sq) = validate_keys(dim, keys)?;
        let kind = if n == 1 {
            if let Method::Rbf { radius } = method {
                rbf::check_radius(radius)?;
            }
            Kind::Single
        } else {
            match method {
                Method::SmoothVoronoi => {
                    Kind::SmoothVoronoi(smooth_voronoi::SmoothVoronoi::new(n, sq, smooth_voronoi::Params::PAPER))
                }
                Method::Rbf { radius } => Kind::Rbf(rbf::Rbf::new(n, &sq, radius)?),
                Method::Shepard => Kind::Shepard,
            }
        };
        Ok(Interpolator {
            method,
            dim,
            n,
            keys: keys.to_vec(),
            kind,
        })
    }

    /// Writes the basis weights `w_i(x)` for configuration `x` into `out`,
    /// so that `ŷ(x) = Σ_i out[i] · y_i`. The weights sum to 1 and equal
    /// `δ_ij` at key `j`. Smooth Voronoi and RBF weights can be negative or
    /// above 1: the blended local gradients overshoot a little between keys
    /// (Bassett Fig. 12) and extrapolate outside the region the keys
    /// surround. Shepard weights stay in [0, 1]. Non-finite coordinates in
    /// `x` give NaN weights.
    ///
    /// # Panics
    /// If `x.len() != self.dim()` or `out.len() != self.len()`.
    pub fn weights(&self, x: &[f64], out: &mut [f64]) {
        assert_eq!(x.len(), self.dim, "query has the wrong dimension");
        assert_eq!(out.len(), self.n, "output has the wrong length");
        match &self.kind {
            Kind::Single => out[0] = 1.0,
            Kind::SmoothVoronoi(sv) => sv.weights(&self.keys, self.dim, x, out),
            Kind::Rbf(r) => r.weights(&self.keys, self.dim, x, out),
            Kind::Shepard => shepard::weights(&self.keys, self.dim, x, out),
        }
    }

    /// Convenience form of [`Interpolator::weights`] that allocates.
    pub fn weights_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        self.weights(x, &mut out);
        out
    }

    /// Number of keys `n` (the length of a weight vector).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: an interpolator has at least one key.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Dimension `d` of the configuration space.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The method this interpolator was built with.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The smooth Voronoi internals, for white-box tests.
    #[cfg(test)]
    pub(crate) fn smooth_voronoi(&self) -> Option<&smooth_voronoi::SmoothVoronoi> {
        match &self.kind {
            Kind::SmoothVoronoi(sv) => Some(sv),
            _ => None,
        }
    }
}

/// Checks a flat key array and returns `n` with the n×n matrix of squared
/// pairwise distances (row-major, computed directly from coordinate
/// differences, so translation-invariant and free of Gram cancellation).
pub(crate) fn validate_keys(dim: usize, keys: &[f64]) -> Result<(usize, Vec<f64>), InterpError> {
    if keys.is_empty() {
        return Err(InterpError::Empty);
    }
    if dim == 0 || !keys.len().is_multiple_of(dim) {
        return Err(InterpError::DimensionMismatch { dim, len: keys.len() });
    }
    let n = keys.len() / dim;
    if n > MAX_KEYS {
        return Err(InterpError::TooManyKeys { count: n });
    }
    if let Some(pos) = keys.iter().position(|v| !v.is_finite()) {
        return Err(InterpError::NonFinite { key: pos / dim });
    }
    let sq = pairwise_sq_dists(keys, n, dim);
    // An overflowed distance would read as "the same point" below.
    if let Some(at) = sq.iter().position(|v| !v.is_finite()) {
        let (i, j) = (at / n, at % n);
        return Err(InterpError::TooFarApart {
            first: i.min(j),
            second: i.max(j),
        });
    }
    let threshold = duplicate_threshold(dim, n, keys);
    if !threshold.is_finite() {
        // The bounding box overflows though no pair does (within a factor of dim).
        let at = (0..n * n).fold(0, |b, k| if sq[k] > sq[b] { k } else { b });
        let (i, j) = (at / n, at % n);
        return Err(InterpError::TooFarApart {
            first: i.min(j),
            second: i.max(j),
        });
    }
    for i in 0..n {
        for j in i + 1..n {
            if sq[i * n + j] <= threshold {
                return Err(InterpError::DuplicateKeys { first: i, second: j });
            }
        }
    }
    Ok((n, sq))
}

/// The squared distance under which two of the `n` keys count as one
/// point: [`DUPLICATE_TOLERANCE`] × the layout's bounding-box diagonal, the
/// layout's length scale.
fn duplicate_threshold(dim: usize, n: usize, keys: &[f64]) -> f64 {
    let mut diag2 = 0.0;
    for c in 0..dim {
        let (lo, hi) = (0..n).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| {
            let v = keys[i * dim + c];
            (lo.min(v), hi.max(v))
        });
        diag2 += (hi - lo) * (hi - lo);
    }
    DUPLICATE_TOLERANCE * DUPLICATE_TOLERANCE * diag2
}

/// The other keys of a layout (`dim` coordinates each) that count as the
/// same point as key `k` under the rule interpolation enforces (see
/// [`InterpError::DuplicateKeys`]): a tool that adds key `k` learns which
/// key it would meet. Empty when a coordinate is not finite.
pub fn same_point_as(dim: usize, keys: &[f64], k: usize) -> Vec<usize> {
    if dim == 0 || !keys.len().is_multiple_of(dim) || keys.iter().any(|v| !v.is_finite()) {
        return Vec::new();
    }
    let n = keys.len() / dim;
    let threshold = duplicate_threshold(dim, n, keys);
    let at = |i: usize| &keys[i * dim..(i + 1) * dim];
    // An overflowed distance or extent is no meeting: the keys are too far apart.
    (0..n)
        .filter(|&i| i != k && threshold.is_finite() && sq_dist(at(i), at(k)) <= threshold)
        .collect()
}

/// Squared distance between two equally long coordinate slices.
#[inline]
pub(crate) fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| {
            let d = p - q;
            d * d
        })
        .sum()
}

/// n×n squared distances between keys, row-major, symmetric, zero diagonal.
/// Entry (i, j) is computed exactly as `sq_dist(key_i, key_j)`, which is
/// bitwise what [`sq_dists_to`] gives for a query sitting on key i.
fn pairwise_sq_dists(keys: &[f64], n: usize, dim: usize) -> Vec<f64> {
    let mut sq = vec![0.0; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let v = sq_dist(&keys[i * dim..(i + 1) * dim], &keys[j * dim..(j + 1) * dim]);
            sq[i * n + j] = v;
            sq[j * n + i] = v;
        }
    }
    sq
}

/// Squared distances from `x` to every key, O(nd): the only part of an
/// evaluation that touches the d coordinates.
pub(crate) fn sq_dists_to(keys: &[f64], dim: usize, x: &[f64], out: &mut [f64]) {
    for (k, r) in out.iter_mut().enumerate() {
        *r = sq_dist(x, &keys[k * dim..(k + 1) * dim]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_errors() {
        let m = Method::SmoothVoronoi;
        assert_eq!(Interpolator::new(m, 2, &[]).unwrap_err(), InterpError::Empty);
        assert_eq!(
            Interpolator::new(m, 2, &[0.0, 1.0, 2.0]).unwrap_err(),
            InterpError::DimensionMismatch { dim: 2, len: 3 }
        );
        assert_eq!(
            Interpolator::new(m, 0, &[0.0]).unwrap_err(),
            InterpError::DimensionMismatch { dim: 0, len: 1 }
        );
        assert_eq!(
            Interpolator::new(m, 2, &[0.0, 1.0, 2.0, f64::NAN]).unwrap_err(),
            InterpError::NonFinite { key: 1 }
        );
        assert_eq!(
            Interpolator::new(m, 1, &[0.0, 1.0, 2.0, 1.0]).unwrap_err(),
            InterpError::DuplicateKeys { first: 1, second: 3 }
        );
        // Closer than 1e-12 × the layout's size also counts as the same point.
        assert_eq!(
            Interpolator::new(m, 1, &[0.0, 1000.0, 1000.0 + 1e-10]).unwrap_err(),
            InterpError::DuplicateKeys { first: 1, second: 2 }
        );
        assert!(Interpolator::new(m, 1, &[0.0, 1000.0, 1000.0 + 1e-6]).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = Interpolator::new(Method::Rbf { radius: bad }, 1, &[0.0, 1.0]).unwrap_err();
            assert!(matches!(err, InterpError::InvalidRadius { .. }), "{err}");
            // A single key needs no radius, but a bad one is still reported.
            let err = Interpolator::new(Method::Rbf { radius: bad }, 1, &[0.0]).unwrap_err();
            assert!(matches!(err, InterpError::InvalidRadius { .. }), "{err}");
        }
        let msg = InterpError::DuplicateKeys { first: 1, second: 3 }.to_string();
        assert!(msg.contains('1') && msg.contains('3'));
    }

    #[test]
    fn keys_whose_squared_distance_overflows_are_too_far_apart_not_the_same() {
        // (1e160)² overflows f64; the pair is named, never "the same point".
        let m = Method::SmoothVoronoi;
        assert_eq!(
            Interpolator::new(m, 1, &[0.0, 1.0, 1e160]).unwrap_err(),
            InterpError::TooFarApart { first: 0, second: 2 }
        );
        assert_eq!(same_point_as(1, &[0.0, 1.0, 1e160], 2), Vec::<usize>::new());
        // No pair overflows (at most 2 × (8.5e153)² = 1.45e308 < f64::MAX), but
        // the box diagonal does (3 × 7.2e307): the widest pair is named.
        let a = 8.5e153;
        let wide = [0.0, 0.0, 0.0, a, 0.0, 0.0, 0.0, a, 0.0, 0.0, 0.0, a];
        assert!(pairwise_sq_dists(&wide, 4, 3).iter().all(|d| d.is_finite()));
        assert_eq!(
            Interpolator::new(m, 3, &wide).unwrap_err(),
            InterpError::TooFarApart { first: 1, second: 2 }
        );
        assert_eq!(same_point_as(3, &wide, 1), Vec::<usize>::new());
        // 1e150 apart is fine.
        assert!(Interpolator::new(m, 1, &[0.0, 1e150]).is_ok());
        let msg = InterpError::TooFarApart { first: 0, second: 2 }.to_string();
        assert!(msg.starts_with("keys 0 and 2 are too far apart"), "{msg}");
    }

    #[test]
    fn rbf_radius_must_keep_its_square_normal() {
        let keys = [0.0, 1.0];
        for ok in [MIN_RADIUS, 1.0, MAX_RADIUS] {
            // Keys spaced like the radius, so the system is well conditioned.
            assert!(
                Interpolator::new(Method::Rbf { radius: ok }, 1, &[0.0, ok]).is_ok(),
                "{ok}"
            );
        }
        for bad in [MIN_RADIUS / 2.0, 1e-160, MAX_RADIUS * 2.0] {
            let err = Interpolator::new(Method::Rbf { radius: bad }, 1, &keys).unwrap_err();
            assert_eq!(err, InterpError::InvalidRadius { radius: bad });
        }
        let msg = InterpError::InvalidRadius { radius: 1e-160 }.to_string();
        assert!(msg.ends_with("got 1e-160"), "{msg}");
        let msg = InterpError::InvalidRadius { radius: -1.0 }.to_string();
        assert!(msg.ends_with("got -1"), "{msg}");
    }

    #[test]
    fn same_point_as_applies_the_duplicate_rule() {
        // The rule of `validation_errors`: 1e-10 apart in a layout 1000
        // across is one point, 1e-6 apart is not; a key never meets itself.
        assert_eq!(same_point_as(1, &[0.0, 1000.0, 1000.0 + 1e-10], 2), vec![1]);
        assert_eq!(same_point_as(1, &[0.0, 1000.0, 1000.0 + 1e-10], 1), vec![2]);
        assert_eq!(same_point_as(1, &[0.0, 1000.0, 1000.0 + 1e-6], 2), Vec::<usize>::new());
        // Exactly equal keys meet, also in a layout of no extent.
        assert_eq!(same_point_as(2, &[1.0, 2.0, 3.0, 4.0, 1.0, 2.0], 2), vec![0]);
        assert_eq!(same_point_as(2, &[1.0, 2.0, 1.0, 2.0, 1.0, 2.0], 0), vec![1, 2]);
        // Every coordinate counts: apart on the second axis only.
        assert_eq!(
            same_point_as(2, &[0.0, 0.0, 1.0, 1.0, 1.0, 1.5], 2),
            Vec::<usize>::new()
        );
        // The fuzz case: 8.8e-34 from a key, in a layout 2 across.
        let head = [0.0, 1.0, 1.0, 0.0, -1.0, 0.0, 0.0, -1.0, 1.0, 8.8e-34];
        assert_eq!(same_point_as(2, &head, 4), vec![1]);
        // No layout to judge: a non-finite coordinate, a ragged array, no axes.
        assert!(same_point_as(1, &[0.0, f64::NAN, 0.0], 2).is_empty());
        assert!(same_point_as(2, &[0.0, 0.0, 0.0], 0).is_empty());
        assert!(same_point_as(0, &[], 0).is_empty());
        // And it agrees with what interpolation refuses.
        for keys in [
            &[0.0, 1000.0, 1000.0 + 1e-10][..],
            &[0.0, 1000.0, 1000.0 + 1e-6],
            &head[..6],
        ] {
            let dim = if keys.len() == 6 { 2 } else { 1 };
            let n = keys.len() / dim;
            let met = (0..n).any(|k| !same_point_as(dim, keys, k).is_empty());
            let refused = matches!(
                Interpolator::new(Method::SmoothVoronoi, dim, keys),
                Err(InterpError::DuplicateKeys { .. })
            );
            assert_eq!(met, refused, "{keys:?}");
        }
    }

    #[test]
    fn tokens_round_trip() {
        for m in [Method::SmoothVoronoi, Method::Rbf { radius: 2.5 }, Method::Shepard] {
            assert_eq!(Method::from_token(m.token(), 2.5), Some(m));
        }
        assert_eq!(Method::from_token("linear", 1.0), None);
    }

    #[test]
    fn single_key_weighs_one_everywhere() {
        for m in [Method::SmoothVoronoi, Method::Rbf { radius: 0.5 }, Method::Shepard] {
            let it = Interpolator::new(m, 3, &[0.1, 0.2, 0.3]).unwrap();
            assert_eq!(it.len(), 1);
            assert_eq!(it.dim(), 3);
            for x in [[0.1, 0.2, 0.3], [5.0, -4.0, 1e6]] {
                assert_eq!(it.weights_vec(&x), vec![1.0]);
            }
        }
    }

    #[test]
    #[should_panic(expected = "wrong dimension")]
    fn wrong_query_dimension_panics() {
        let it = Interpolator::new(Method::Shepard, 2, &[0.0, 0.0, 1.0, 1.0]).unwrap();
        it.weights_vec(&[0.5]);
    }

    #[test]
    fn several_keys_report_their_count_and_are_not_empty() {
        let it = Interpolator::new(Method::Shepard, 2, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]).unwrap();
        assert_eq!(it.len(), 3);
        assert_eq!(it.dim(), 2);
        assert!(!it.is_empty());
        assert_eq!(it.method(), Method::Shepard);
        // Shepard (eq. 5) by hand on keys 0 and 1 at x = 0.25: 1/d² = 16 and
        // 16/9, so the weights are 9/10 and 1/10.
        let two = Interpolator::new(Method::Shepard, 1, &[0.0, 1.0]).unwrap();
        let w = two.weights_vec(&[0.25]);
        assert_eq!(w.len(), 2);
        assert!((w[0] - 0.9).abs() < 1e-12 && (w[1] - 0.1).abs() < 1e-12, "{w:?}");
    }

    #[test]
    fn non_finite_error_names_the_key_not_the_coordinate() {
        let m = Method::SmoothVoronoi;
        // Flat index 5 is coordinate 1 of key 2 (dimension 2).
        assert_eq!(
            Interpolator::new(m, 2, &[0.0, 0.0, 1.0, 0.0, 0.0, f64::NAN]).unwrap_err(),
            InterpError::NonFinite { key: 2 }
        );
        // Flat index 6 is coordinate 0 of key 2 (dimension 3).
        assert_eq!(
            Interpolator::new(m, 3, &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0, f64::INFINITY, 2.0, 2.0]).unwrap_err(),
            InterpError::NonFinite { key: 2 }
        );
    }

    #[test]
    fn duplicate_tolerance_uses_the_extent_of_every_axis() {
        let m = Method::Shepard;
        // Keys spanning [-1000, 1000]: the box diagonal is 2000, so keys
        // 1e-10 apart (squared 1e-20 ≤ 1e-24 · 2000² = 4e-18) are one point,
        // and keys 1e-6 apart (squared 1e-12) are not.
        assert_eq!(
            Interpolator::new(m, 1, &[-1000.0, 1000.0, 1000.0 + 1e-10]).unwrap_err(),
            InterpError::DuplicateKeys { first: 1, second: 2 }
        );
        assert!(Interpolator::new(m, 1, &[-1000.0, 1000.0, 1000.0 + 1e-6]).is_ok());
        // The same in 2D with the extent on the second axis only: diagonal
        // 1000, threshold 1e-18, keys 1 and 2 are 1e-10 apart.
        assert_eq!(
            Interpolator::new(m, 2, &[0.0, 0.0, 0.0, 1000.0, 0.0, 1000.0 + 1e-10]).unwrap_err(),
            InterpError::DuplicateKeys { first: 1, second: 2 }
        );
        assert!(Interpolator::new(m, 2, &[0.0, 0.0, 0.0, 1000.0, 0.0, 1000.0 + 1e-6]).is_ok());
    }

    #[test]
    fn squared_distances_in_three_dimensions() {
        // k0 = (0,0,0), k1 = (1,2,2), k2 = (3,0,4): squared distances
        // |k1−k0|² = 1+4+4 = 9, |k2−k0|² = 9+0+16 = 25, |k2−k1|² = 4+4+4 = 12.
        let keys = [0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 3.0, 0.0, 4.0];
        let (n, sq) = validate_keys(3, &keys).unwrap();
        assert_eq!(n, 3);
        #[rustfmt::skip]
        let want = [
            0.0, 9.0, 25.0,
            9.0, 0.0, 12.0,
            25.0, 12.0, 0.0,
        ];
        assert_eq!(sq, want);
        // From x = (1,1,1): 1+1+1 = 3, 0+1+1 = 2, 4+1+9 = 14.
        let mut out = [f64::NAN; 3];
        sq_dists_to(&keys, 3, &[1.0, 1.0, 1.0], &mut out);
        assert_eq!(out, [3.0, 2.0, 14.0]);
    }
}
