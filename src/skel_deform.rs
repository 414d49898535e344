//! UsdSkel point deformation: blend shapes, then linear-blend or
//! dual-quaternion skinning, in skeleton space.
//!
//! Pure math over plain arrays; `usd_io::skel` reads the stage into a
//! [`SkelDeformer`] once and feeds it joint poses per frame. Implemented here
//! rather than through `openusd-schemas`' skinning helpers because those skip
//! dual-quaternion skinning, clamp inbetween weights and panic on some inputs
//! (see `../shared/notes/usdskel.md`); the crate still does reading and topology.

use glam::{DMat3, DMat4, DQuat, DVec3};

/// How the joint transforms are blended (`skel:skinningMethod`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SkinningMethod {
    /// `classicLinear`: Σ w_j (p · S_j).
    ClassicLinear,
    /// `dualQuaternion`: blend of unit dual quaternions, after a linear blend
    /// of each joint's scale/shear part (UsdSkel's convention).
    DualQuaternion,
}

/// One blend shape target: sparse or dense offsets plus inbetweens.
#[derive(Debug, Clone, PartialEq)]
pub struct BlendShape {
    /// Offsets at weight 1.
    pub offsets: Vec<DVec3>,
    /// Point each offset applies to; None = dense (offset i → point i).
    pub point_indices: Option<Vec<u32>>,
    /// Inbetween shapes: (weight, offsets), any order.
    pub inbetweens: Vec<(f64, Vec<DVec3>)>,
}

impl BlendShape {
    /// Adds `weight` of this shape to `points`.
    ///
    /// Inbetweens are piecewise-linear breakpoints along the weight axis with
    /// the rest (weight 0, zero offsets) and the primary shape (weight 1);
    /// outside the outermost breakpoints the outermost segment extrapolates,
    /// as UsdSkel does for weights beyond [0, 1].
    pub fn apply(&self, weight: f64, points: &mut [DVec3]) {
        if weight == 0.0 {
            return;
        }
        let add = |points: &mut [DVec3], offsets: &[DVec3], scale: f64| {
            if scale == 0.0 {
                return;
            }
            match &self.point_indices {
                None => points.iter_mut().zip(offsets).for_each(|(p, o)| *p += *o * scale),
                Some(idx) => {
                    for (&i, o) in idx.iter().zip(offsets) {
                        points[i as usize] += *o * scale;
                    }
                }
            }
        };
        if self.inbetweens.is_empty() {
            add(points, &self.offsets, weight);
            return;
        }
        // Breakpoints sorted by weight: rest, inbetweens, primary.
        let mut bps: Vec<(f64, Option<&[DVec3]>)> = vec![(0.0, None), (1.0, Some(&self.offsets))];
        bps.extend(self.inbetweens.iter().map(|(w, o)| (*w, Some(o.as_slice()))));
        bps.sort_by(|a, b| a.0.total_cmp(&b.0));
        let seg = (0..bps.len() - 1)
            .find(|&k| weight <= bps[k + 1].0)
            .unwrap_or(bps.len() - 2);
        let (w0, o0) = bps[seg];
        let (w1, o1) = bps[seg + 1];
        let span = w1 - w0;
        let t = if span > 0.0 { (weight - w0) / span } else { 1.0 };
        if let Some(o0) = o0 {
            add(points, o0, 1.0 - t);
        }
        if let Some(o1) = o1 {
            add(points, o1, t);
        }
    }
}

/// Joint influences of a skinned mesh, expanded per point.
#[derive(Debug, Clone, PartialEq)]
pub struct Influences {
    /// Influences per point (the primvars' elementSize).
    pub per_point: usize,
    /// Mesh-order joint index of each influence (len = points × per_point).
    pub joints: Vec<u32>,
    /// Weight of each influence.
    pub weights: Vec<f64>,
}

/// Everything needed to deform one skinned mesh, read once.
#[derive(Debug, Clone)]
pub struct SkelDeformer {
    /// The mesh's own `points` (bind pose, no blend shapes).
    pub rest_points: Vec<DVec3>,
    /// `primvars:skel:geomBindTransform` (column form).
    pub geom_bind: DMat4,
    pub influences: Influences,
    pub method: SkinningMethod,
    /// Blend shapes in the mesh's `skel:blendShapes` order.
    pub blend_shapes: Vec<BlendShape>,
}

impl SkelDeformer {
    /// Skel-space points for joint skinning transforms (mesh joint order,
    /// column form: inverse bind then posed joint) and blend-shape weights
    /// (mesh order).
    pub fn deform(&self, skinning: &[DMat4], shape_weights: &[f64]) -> Vec<DVec3> {
        let mut pts = self.rest_points.clone();
        for (shape, &w) in self.blend_shapes.iter().zip(shape_weights) {
            shape.apply(w, &mut pts);
        }
        let n = self.influences.per_point;
        let dq: Vec<(DualQuat, DMat3)> = match self.method {
            SkinningMethod::ClassicLinear => Vec::new(),
            SkinningMethod::DualQuaternion => skinning.iter().map(DualQuat::from_skinning).collect(),
        };
        for (i, p) in pts.iter_mut().enumerate() {
            let bound = self.geom_bind.transform_point3(*p);
            let joints = &self.influences.joints[i * n..i * n + n];
            let weights = &self.influences.weights[i * n..i * n + n];
            *p = match self.method {
                SkinningMethod::ClassicLinear => {
                    let mut acc = DVec3::ZERO;
                    for (&j, &w) in joints.iter().zip(weights) {
                        if w != 0.0 {
                            acc += skinning[j as usize].transform_point3(bound) * w;
                        }
                    }
                    acc
                }
                SkinningMethod::DualQuaternion => dq_skin(bound, joints, weights, &dq),
            };
        }
        pts
    }
}

/// A unit dual quaternion (rotation `real`, translation in `dual`).
#[derive(Debug, Clone, Copy)]
struct DualQuat {
    real: DQuat,
    dual: DQuat,
}

impl DualQuat {
    /// Splits a skinning transform into scale/shear (applied first, blended
    /// linearly) and a rigid part (blended as a dual quaternion).
    fn from_skinning(m: &DMat4) -> (DualQuat, DMat3) {
        let linear = DMat3::from_mat4(*m);
        let t = m.w_axis.truncate();
        // Polar decomposition linear = R · S with R a rotation.
        let (r, s) = polar(linear);
        let real = DQuat::from_mat3(&r).normalize();
        let tq = DQuat::from_xyzw(t.x, t.y, t.z, 0.0);
        let dual = (tq * real) * 0.5;
        (DualQuat { real, dual }, s)
    }
}

fn dq_skin(p: DVec3, joints: &[u32], weights: &[f64], dq: &[(DualQuat, DMat3)]) -> DVec3 {
    let mut real = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    let mut dual = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    let mut scale = DMat3::ZERO;
    let mut pivot: Option<DQuat> = None;
    for (&j, &w) in joints.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        let (q, s) = &dq[j as usize];
        // Keep every rotation on the pivot's hemisphere (shortest path).
        let sign = match pivot {
            None => {
                pivot = Some(q.real);
                1.0
            }
            Some(pv) if pv.dot(q.real) < 0.0 => -1.0,
            Some(_) => 1.0,
        };
        real = real + q.real * (w * sign);
        dual = dual + q.dual * (w * sign);
        scale += *s * w;
    }
    let len = real.length();
    if len <= f64::MIN_POSITIVE {
        return p;
    }
    let (real, dual) = (real * (1.0 / len), dual * (1.0 / len));
    let scaled = scale * p;
    let t = (dual * real.conjugate()) * 2.0;
    real * scaled + DVec3::new(t.x, t.y, t.z)
}

/// Polar decomposition M = R · S (R proper rotation, S symmetric) by SVD.
fn polar(m: DMat3) -> (DMat3, DMat3) {
    let a = nalgebra::Matrix3::from_column_slice(&m.to_cols_array());
    let svd = a.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return (DMat3::IDENTITY, m);
    };
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        let mut col = u2.column_mut(2);
        col *= -1.0;
        r = u2 * vt;
    }
    let rg = DMat3::from_cols_slice(r.as_slice());
    (rg, rg.transpose() * m)
}

/// Joint local transforms (skeleton order) to skeleton space, parents first.
pub fn local_to_skel(local: &[DMat4], parents: &[Option<usize>]) -> Vec<DMat4> {
    let mut out: Vec<DMat4> = Vec::with_capacity(local.len());
    for (j, l) in local.iter().enumerate() {
        let m = match parents[j] {
            Some(p) if p < j => out[p] * *l,
            _ => *l,
        };
        out.push(m);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape_with_inbetween() -> BlendShape {
        BlendShape {
            offsets: vec![DVec3::new(2.0, 0.0, 0.0)],
            point_indices: None,
            inbetweens: vec![(0.5, vec![DVec3::new(0.0, 1.0, 0.0)])],
        }
    }

    #[test]
    fn inbetween_is_exact_at_its_weight_and_linear_between() {
        let s = shape_with_inbetween();
        let at = |w| {
            let mut p = vec![DVec3::ZERO];
            s.apply(w, &mut p);
            p[0]
        };
        assert_eq!(at(0.5), DVec3::new(0.0, 1.0, 0.0));
        assert_eq!(at(1.0), DVec3::new(2.0, 0.0, 0.0));
        assert!((at(0.25) - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-12);
        assert!((at(0.75) - DVec3::new(1.0, 0.5, 0.0)).length() < 1e-12);
        // Beyond 1 the last segment extrapolates.
        assert!((at(1.5) - DVec3::new(4.0, -1.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn sparse_offsets_touch_only_their_points() {
        let s = BlendShape {
            offsets: vec![DVec3::X],
            point_indices: Some(vec![1]),
            inbetweens: vec![],
        };
        let mut p = vec![DVec3::ZERO; 3];
        s.apply(0.5, &mut p);
        assert_eq!(p, vec![DVec3::ZERO, DVec3::X * 0.5, DVec3::ZERO]);
    }

    fn deformer(method: SkinningMethod) -> SkelDeformer {
        SkelDeformer {
            rest_points: vec![DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 2.0, 0.0)],
            geom_bind: DMat4::IDENTITY,
            influences: Influences {
                per_point: 2,
                joints: vec![0, 1, 0, 1],
                weights: vec![0.5, 0.5, 1.0, 0.0],
            },
            method,
            blend_shapes: vec![],
        }
    }

    #[test]
    fn lbs_averages_joint_transforms() {
        let d = deformer(SkinningMethod::ClassicLinear);
        let xf = [DMat4::IDENTITY, DMat4::from_translation(DVec3::new(0.0, 0.0, 2.0))];
        let p = d.deform(&xf, &[]);
        assert!((p[0] - DVec3::new(1.0, 0.0, 1.0)).length() < 1e-12);
        assert!((p[1] - DVec3::new(0.0, 2.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn dqs_keeps_length_where_lbs_collapses() {
        // Two joints rotated ±90° about z: LBS pulls the point to the axis,
        // DQS rotates it by the average (0°) and keeps its distance.
        let xf = [
            DMat4::from_rotation_z(std::f64::consts::FRAC_PI_2),
            DMat4::from_rotation_z(-std::f64::consts::FRAC_PI_2),
        ];
        let lbs = deformer(SkinningMethod::ClassicLinear).deform(&xf, &[]);
        let dqs = deformer(SkinningMethod::DualQuaternion).deform(&xf, &[]);
        assert!(lbs[0].length() < 1e-12);
        assert!((dqs[0] - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12);
        // Single influence: DQS equals the rigid transform itself.
        assert!((dqs[1] - xf[0].transform_point3(DVec3::new(0.0, 2.0, 0.0))).length() < 1e-12);
    }

    #[test]
    fn dqs_of_translation_and_rotation_single_joint() {
        let m = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0)) * DMat4::from_rotation_y(0.7);
        let mut d = deformer(SkinningMethod::DualQuaternion);
        d.influences.weights = vec![1.0, 0.0, 1.0, 0.0];
        let p = d.deform(&[m, DMat4::IDENTITY], &[]);
        assert!((p[0] - m.transform_point3(DVec3::X)).length() < 1e-12);
    }

    #[test]
    fn skeleton_space_composes_parents_first() {
        let local = [DMat4::from_translation(DVec3::X), DMat4::from_translation(DVec3::Y)];
        let skel = local_to_skel(&local, &[None, Some(0)]);
        assert_eq!(skel[1].transform_point3(DVec3::ZERO), DVec3::new(1.0, 1.0, 0.0));
    }
}
