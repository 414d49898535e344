//! Extents as usd-core computes them, so renderers that cull by `extent`
//! see the same box whether painterly or usd-core wrote it.
//!
//! - Meshes (any point-based prim): `UsdGeom.PointBased.ComputeExtent`, the
//!   componentwise min and max of the points.
//! - Curves: `UsdGeom.Curves.ComputeExtent`, that box padded on every side
//!   by half the largest of the `widths` values (whatever their
//!   interpolation; no widths pad by 0, and like usd-core an all-negative
//!   `widths` shrinks the box), in f32 as usd-core does.
//!
//! No points gives usd-core's empty box, `[(FLT_MAX,)*3, (-FLT_MAX,)*3]`.

use glam::Vec3;

/// `UsdGeom.PointBased.ComputeExtent`: `[min, max]` of `points`.
pub fn point_based_extent(points: &[Vec3]) -> [Vec3; 2] {
    crate::mesh::bounds(points).unwrap_or([Vec3::splat(f32::MAX), Vec3::splat(-f32::MAX)])
}

/// The largest width as usd-core takes it for an extent: the largest value
/// (`std::max_element`, so negative when all are), 0 when there are none.
/// Widths are finite (checked when read).
pub fn max_width(widths: impl IntoIterator<Item = f32>) -> f32 {
    widths.into_iter().reduce(f32::max).unwrap_or(0.0)
}

/// `UsdGeom.Curves.ComputeExtent`: the points' box grown by half of
/// `max_width` (see [`max_width`]) on every side.
pub fn curves_extent(points: &[Vec3], max_width: f32) -> [Vec3; 2] {
    pad_curves_extent(point_based_extent(points), max_width)
}

/// [`curves_extent`] from the points' box ([`point_based_extent`]).
pub fn pad_curves_extent([lo, hi]: [Vec3; 2], max_width: f32) -> [Vec3; 2] {
    let pad = Vec3::splat(max_width / 2.0);
    [lo - pad, hi + pad]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_pad_by_half_the_largest_width() {
        let pts = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 3.0)];
        assert_eq!(max_width([0.5, -3.0]), 0.5);
        assert_eq!(max_width([-1.0, -3.0]), -1.0);
        assert_eq!(max_width([]), 0.0);
        assert_eq!(
            curves_extent(&pts, max_width([0.5, -3.0])),
            [Vec3::splat(-0.25), Vec3::new(1.25, 2.25, 3.25)]
        );
        assert_eq!(curves_extent(&pts, 0.0), point_based_extent(&pts));
        // usd-core's max_element: all-negative widths shrink the box.
        assert_eq!(curves_extent(&pts, -1.0), [Vec3::splat(0.5), Vec3::new(0.5, 1.5, 2.5)]);
    }

    #[test]
    fn empty_is_usd_cores_empty_box() {
        let e = point_based_extent(&[]);
        assert_eq!(e, [Vec3::splat(f32::MAX), Vec3::splat(-f32::MAX)]);
        // f32 rounding keeps FLT_MAX − 0.5 at FLT_MAX, as in usd-core.
        assert_eq!(curves_extent(&[], 1.0), e);
    }
}
