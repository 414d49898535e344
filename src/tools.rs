//! The smudge and expand brushes (Bassett §3.3), as pure math.
//!
//! Both move stroke points within `radius` of a tool path by `strength`
//! modulated by a falloff of the distance normalised by the radius: smudge
//! along the path's unit tangent at the closest path point, expand along the
//! proxy surface normal at the point's bound position.

use glam::DVec3;

/// How a brush's effect fades with distance from the tool path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Falloff {
    /// The paper's cubic step 2r³ − 3r² + 1 (1 on the path, 0 at the radius).
    Cubic,
    /// Full strength everywhere within the radius.
    None,
}

impl Falloff {
    /// Weight at normalised distance `r` (0 outside the radius).
    pub fn weight(self, r: f64) -> f64 {
        if !(0.0..=1.0).contains(&r) {
            return 0.0;
        }
        match self {
            Falloff::Cubic => 2.0 * r * r * r - 3.0 * r * r + 1.0,
            Falloff::None => 1.0,
        }
    }
}

/// The point of a polyline closest to `p`: (distance, unit tangent there).
///
/// The tangent is that of the segment holding the closest point; where two
/// segments hold it (a corner), the earlier one's. Zero-length segments are
/// skipped; the path must have a segment of non-zero length.
pub fn closest_on_path(path: &[DVec3], p: DVec3) -> Option<(f64, DVec3)> {
    let mut best: Option<(f64, DVec3)> = None;
    for w in path.windows(2) {
        let (a, b) = (w[0], w[1]);
        let d = b - a;
        let len2 = d.length_squared();
        if len2 <= 0.0 {
            continue;
        }
        let t = ((p - a).dot(d) / len2).clamp(0.0, 1.0);
        let dist = (a + d * t - p).length();
        if best.is_none_or(|(bd, _)| dist < bd) {
            best = Some((dist, d / len2.sqrt()));
        }
    }
    best
}

/// Why `path` cannot steer a brush (fewer than two points, a non-finite
/// point, or no segment of non-zero length), as the end of a sentence whose
/// subject each caller names; `None` when it can.
pub fn tool_path_problem(path: &[DVec3]) -> Option<String> {
    if path.len() < 2 {
        Some(format!("has {} point(s); a tool path needs at least two", path.len()))
    } else if path.iter().any(|p| !p.is_finite()) {
        Some("has a non-finite point".into())
    } else if closest_on_path(path, DVec3::ZERO).is_none() {
        Some("has no segment of non-zero length".into())
    } else {
        None
    }
}

/// Smudge displacements: along the path tangent, `strength · falloff(d / radius)`.
pub fn smudge(points: &[DVec3], path: &[DVec3], radius: f64, strength: f64, falloff: Falloff) -> Vec<DVec3> {
    points
        .iter()
        .map(|&p| match closest_on_path(path, p) {
            Some((d, tangent)) if d <= radius => tangent * (strength * falloff.weight(d / radius)),
            _ => DVec3::ZERO,
        })
        .collect()
}

/// Expand displacements: along each point's surface `normals`, scaled by the
/// falloff of its distance to the path.
pub fn expand(
    points: &[DVec3],
    normals: &[DVec3],
    path: &[DVec3],
    radius: f64,
    strength: f64,
    falloff: Falloff,
) -> Vec<DVec3> {
    points
        .iter()
        .zip(normals)
        .map(|(&p, &n)| match closest_on_path(path, p) {
            Some((d, _)) if d <= radius => n * (strength * falloff.weight(d / radius)),
            _ => DVec3::ZERO,
        })
        .collect()
}

/// Area-weighted vertex normals of a triangle mesh (unit length; zero for
/// vertices on no non-degenerate triangle), on the side the mesh faces: a
/// `rightHanded` mesh faces where its counter-clockwise triangles do, a
/// `leftHanded` one (`left_handed`, USD's `orientation`) the other way.
pub fn vertex_normals(points: &[DVec3], triangles: &[[u32; 3]], left_handed: bool) -> Vec<DVec3> {
    let mut n = vec![DVec3::ZERO; points.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| points[i as usize]);
        // The cross product's length is twice the area: area weighting for free.
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    let side = if left_handed { -1.0 } else { 1.0 };
    n.iter().map(|v| v.normalize_or_zero() * side).collect()
}

/// Parses a stroke selection like `3,7-12` into inclusive index ranges,
/// sorted by start. Ranges stay ranges: `0-18446744073709551615` costs
/// nothing until it meets a layer's stroke count.
pub fn parse_strokes(s: &str) -> Result<Vec<(usize, usize)>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let num = |x: &str| {
            x.trim()
                .parse::<usize>()
                .map_err(|_| format!("{x:?} is not a stroke index"))
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                if b < a {
                    return Err(format!("range {part:?} ends before it starts"));
                }
                out.push((a, b));
            }
            None => {
                let a = num(part)?;
                out.push((a, a));
            }
        }
    }
    if out.is_empty() {
        return Err("no strokes selected".into());
    }
    out.sort_unstable();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tool_path_needs_two_finite_points_a_segment_apart() {
        let (a, b) = (DVec3::ZERO, DVec3::X);
        assert_eq!(
            tool_path_problem(&[a]).as_deref(),
            Some("has 1 point(s); a tool path needs at least two")
        );
        assert_eq!(
            tool_path_problem(&[a, DVec3::new(f64::NAN, 0.0, 0.0)]).as_deref(),
            Some("has a non-finite point")
        );
        assert_eq!(
            tool_path_problem(&[b, b, b]).as_deref(),
            Some("has no segment of non-zero length")
        );
        assert_eq!(tool_path_problem(&[a, a, b]), None);
    }

    #[test]
    fn cubic_falloff_is_the_papers_step() {
        let f = Falloff::Cubic;
        assert_eq!(f.weight(0.0), 1.0);
        assert_eq!(f.weight(1.0), 0.0);
        assert!((f.weight(0.5) - 0.5).abs() < 1e-15);
        assert_eq!(f.weight(1.5), 0.0);
        assert_eq!(Falloff::None.weight(0.99), 1.0);
    }

    #[test]
    fn smudge_moves_along_the_tangent_within_the_radius() {
        let path = [DVec3::ZERO, DVec3::X * 10.0];
        let pts = [DVec3::new(5.0, 0.5, 0.0), DVec3::new(5.0, 3.0, 0.0)];
        let d = smudge(&pts, &path, 1.0, 2.0, Falloff::Cubic);
        // r = 0.5: weight 0.5, along +x.
        assert!((d[0] - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12);
        assert_eq!(d[1], DVec3::ZERO);
    }

    #[test]
    fn expand_moves_along_normals() {
        let path = [DVec3::ZERO, DVec3::Y];
        let pts = [DVec3::new(0.0, 0.5, 0.0)];
        let d = expand(&pts, &[DVec3::Z], &path, 1.0, 0.3, Falloff::None);
        assert!((d[0] - DVec3::new(0.0, 0.0, 0.3)).length() < 1e-12);
    }

    #[test]
    fn brushes_measure_from_a_path_off_the_origin_at_any_radius() {
        // A path off the origin, drawn in −x, and radius 2: the falloff is
        // of d / 2, so at d = 1 the cubic step is 2/8 − 3/4 + 1 = 0.5.
        let path = [DVec3::new(3.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0)];
        assert_eq!(
            closest_on_path(&path, DVec3::new(2.0, 2.0, 0.0)),
            Some((1.0, -DVec3::X))
        );
        let pts = [
            DVec3::new(2.0, 1.0, 0.0), // on the path: weight 1
            DVec3::new(2.0, 2.0, 0.0), // d = 1: weight 0.5
            DVec3::new(0.0, 1.0, 0.0), // past the end (1, 1, 0), d = 1: weight 0.5
            DVec3::new(2.0, 1.0, 2.5), // d = 2.5, beyond the radius: unmoved
        ];
        let close = |got: &[DVec3], want: [DVec3; 4]| {
            for (g, w) in got.iter().zip(want) {
                assert!((*g - w).length() < 1e-12, "{g} vs {w}");
            }
        };
        let along = [0.4, 0.2, 0.2, 0.0].map(|s| -DVec3::X * s);
        close(&smudge(&pts, &path, 2.0, 0.4, Falloff::Cubic), along);
        let normals = [DVec3::Z, DVec3::Y, DVec3::X, DVec3::Z];
        let out = [DVec3::Z * 0.4, DVec3::Y * 0.2, DVec3::X * 0.2, DVec3::ZERO];
        close(&expand(&pts, &normals, &path, 2.0, 0.4, Falloff::Cubic), out);
    }

    #[test]
    fn the_closest_segment_of_a_path_gives_the_tangent() {
        // An L: +x from (1, 0, 0) to (3, 0, 0), then +y to (3, 2, 0).
        let path = [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(3.0, 2.0, 0.0),
        ];
        // Beside the second leg (distance 1; the first leg is √3.25 away).
        assert_eq!(closest_on_path(&path, DVec3::new(4.0, 1.5, 0.0)), Some((1.0, DVec3::Y)));
        // Beside the first leg (distance 0.5; the second is √1.25 away).
        assert_eq!(
            closest_on_path(&path, DVec3::new(2.0, -0.5, 0.0)),
            Some((0.5, DVec3::X))
        );
        // Off the corner, both legs at √2: the earlier leg's tangent.
        assert_eq!(
            closest_on_path(&path, DVec3::new(4.0, -1.0, 0.0)),
            Some((2f64.sqrt(), DVec3::X))
        );
    }

    #[test]
    fn normals_are_area_weighted_anywhere_in_space() {
        // Two triangles off the origin sharing the edge 0–1: one flat
        // (cross product (2,0,0)×(0,1,0) = (0,0,2)), one upright and three
        // times larger ((2,0,0)×(0,0,3) = (0,−6,0)). The shared vertices get
        // (0,−6,2)/√40, the others their own triangle's normal.
        let o = DVec3::new(10.0, -4.0, 5.0);
        let pts = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::Y,
            DVec3::new(0.0, 0.0, 3.0),
        ]
        .map(|p| p + o);
        let n = vertex_normals(&pts, &[[0, 1, 2], [0, 1, 3]], false);
        let shared = DVec3::new(0.0, -3.0, 1.0) / 10f64.sqrt();
        for (got, want) in n.iter().zip([shared, shared, DVec3::Z, -DVec3::Y]) {
            assert!((*got - want).length() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn normals_of_a_flat_square_point_up() {
        let pts = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let n = vertex_normals(&pts, &[[0, 1, 2], [0, 2, 3]], false);
        assert!(n.iter().all(|v| (*v - DVec3::Z).length() < 1e-12));
    }

    #[test]
    fn a_left_handed_mesh_faces_the_other_side_of_its_winding() {
        // The square wound clockwise seen from +z: rightHanded it faces −z,
        // leftHanded +z, as the counter-clockwise square does rightHanded.
        let pts = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let cw = [[0, 2, 1], [0, 3, 2]];
        for (left, want) in [(false, -DVec3::Z), (true, DVec3::Z)] {
            let n = vertex_normals(&pts, &cw, left);
            assert!(
                n.iter().all(|v| (*v - want).length() < 1e-12),
                "left_handed {left}: {n:?}"
            );
        }
        // A vertex on no triangle stays zero either way.
        assert_eq!(vertex_normals(&[DVec3::ZERO], &[], true), vec![DVec3::ZERO]);
    }

    #[test]
    fn stroke_selection_parses_ranges() {
        assert_eq!(parse_strokes("3,7-9, 1").unwrap(), vec![(1, 1), (3, 3), (7, 9)]);
        assert_eq!(parse_strokes("4-4,2").unwrap(), vec![(2, 2), (4, 4)]);
        // The widest range is two numbers, not 2^64 indices.
        assert_eq!(parse_strokes("0-18446744073709551615").unwrap(), vec![(0, usize::MAX)]);
        assert_eq!(
            parse_strokes("1,5-2").unwrap_err(),
            "range \"5-2\" ends before it starts"
        );
        assert!(parse_strokes("x").is_err());
        assert!(parse_strokes("").is_err());
    }
}
