//! UsdSkel point deformation: blend shapes, then linear-blend or
//! dual-quaternion skinning, in skeleton space.
//!
//! Pure math over plain arrays; `usd_io::skel` reads the stage into a
//! [`SkelDeformer`] once and feeds it joint poses per frame. Implemented here
//! rather than through `openusd-schemas`' skinning helpers because those skip
//! dual-quaternion skinning, clamp inbetween weights and panic on some inputs
//! (see `../shared/notes/usdskel.md`); the crate still does reading and topology.

use glam::{DMat3, DMat4, DQuat, DVec3};

use crate::gf::{orthonormalized, rotation_quaternion};

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
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BlendShape {
    /// Offsets at weight 1; empty when the shape has no `offsets` (only
    /// `normalOffsets`): it then moves no point.
    pub offsets: Vec<DVec3>,
    /// Normal offsets at weight 1 (empty: none).
    pub normal_offsets: Vec<DVec3>,
    /// Point each offset applies to; None = dense (offset i → point i).
    pub point_indices: Option<Vec<u32>>,
    /// Inbetween shapes, any order.
    pub inbetweens: Vec<Inbetween>,
}

/// An inbetween shape; empty offsets move nothing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Inbetween {
    pub weight: f64,
    pub offsets: Vec<DVec3>,
    pub normal_offsets: Vec<DVec3>,
}

/// UsdSkelBlendShapeQuery's tolerance for inbetween weights and segment
/// parameters: a float 1e-6, so 9.99999997e-7 here (an inbetween authored
/// at `1e-6` is a breakpoint to usd-core).
const QUERY_EPS: f64 = 1e-6_f32 as f64;

/// UsdSkelApplyBlendShape's tolerance for a sub-shape's weight: a double.
const APPLY_EPS: f64 = 1e-6;

/// GfIsClose: strictly closer than `eps`, so a difference of exactly `eps`
/// counts as apart.
fn gf_is_close(a: f64, b: f64, eps: f64) -> bool {
    (a - b).abs() < eps
}

/// Whether UsdSkelBlendShapeQuery ignores an inbetween at `weight`: closer
/// than its float EPS to 0 or to 1 (the rest and the primary shape).
pub fn ignores_inbetween_at(weight: f64) -> bool {
    gf_is_close(weight, 0.0, QUERY_EPS) || gf_is_close(weight, 1.0, QUERY_EPS)
}

/// A sub-shape of a blend shape: the primary or an inbetween.
#[derive(Debug, Clone, Copy, PartialEq)]
enum SubShape {
    Primary,
    Inbetween(usize),
}

impl BlendShape {
    /// The sub-shapes `weight` blends and their factors, as
    /// UsdSkelBlendShapeQuery resolves them.
    ///
    /// Without inbetweens the primary shape scales linearly with the weight
    /// (also below 0 and above 1). With inbetweens, the sub-shapes (rest at
    /// weight 0, the primary at 1, each inbetween at its weight; inbetweens
    /// closer than a float 1e-6 to 0 or 1 are ignored) are piecewise-linear breakpoints
    /// along the weight axis, and outside the outermost breakpoints the
    /// outermost segment extrapolates.
    fn sub_shapes(&self, weight: f64) -> Vec<(SubShape, f64)> {
        // Sub-shapes sorted by weight: primary, rest (None), inbetweens.
        let mut subs: Vec<(f64, Option<SubShape>)> = vec![(1.0, Some(SubShape::Primary)), (0.0, None)];
        subs.extend(
            self.inbetweens
                .iter()
                .enumerate()
                .filter(|(_, ib)| !ignores_inbetween_at(ib.weight))
                .map(|(k, ib)| (ib.weight, Some(SubShape::Inbetween(k)))),
        );
        if subs.len() == 2 {
            return vec![(SubShape::Primary, weight)];
        }
        subs.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The first sub-shape above the weight bounds the segment from above.
        let upper = subs.iter().position(|s| s.0 > weight).unwrap_or(subs.len());
        let (lo, hi) = match upper {
            0 => (0, 1),
            u if u == subs.len() => (u - 2, u - 1),
            u => (u - 1, u),
        };
        let ((w0, s0), (w1, s1)) = (subs[lo], subs[hi]);
        let span = w1 - w0;
        if span <= QUERY_EPS {
            return Vec::new();
        }
        let alpha = (weight - w0) / span;
        let mut out = Vec::new();
        if let Some(s0) = s0 {
            if !gf_is_close(alpha, 1.0, QUERY_EPS) {
                out.push((s0, 1.0 - alpha));
            }
        }
        if let Some(s1) = s1 {
            if !gf_is_close(alpha, 0.0, QUERY_EPS) {
                out.push((s1, alpha));
            }
        }
        out
    }

    fn add(&self, target: &mut [DVec3], offsets: &[DVec3], scale: f64) {
        if gf_is_close(scale, 0.0, APPLY_EPS) || offsets.is_empty() {
            return;
        }
        match &self.point_indices {
            None => target.iter_mut().zip(offsets).for_each(|(p, o)| *p += *o * scale),
            Some(idx) => {
                for (&i, o) in idx.iter().zip(offsets) {
                    if let Some(p) = target.get_mut(i as usize) {
                        *p += *o * scale;
                    }
                }
            }
        }
    }

    /// Adds `weight` of this shape to `points`.
    pub fn apply(&self, weight: f64, points: &mut [DVec3]) {
        for (sub, f) in self.sub_shapes(weight) {
            let offsets = match sub {
                SubShape::Primary => &self.offsets,
                SubShape::Inbetween(k) => &self.inbetweens[k].offsets,
            };
            self.add(points, offsets, f);
        }
    }

    /// Adds `weight` of this shape's normal offsets to per-point `normals`
    /// (not renormalised: see [`SkelDeformer::deform_normals`]).
    pub fn apply_normals(&self, weight: f64, normals: &mut [DVec3]) {
        for (sub, f) in self.sub_shapes(weight) {
            let offsets = match sub {
                SubShape::Primary => &self.normal_offsets,
                SubShape::Inbetween(k) => &self.inbetweens[k].normal_offsets,
            };
            self.add(normals, offsets, f);
        }
    }

    /// Whether any sub-shape has normal offsets.
    pub fn has_normal_offsets(&self) -> bool {
        !self.normal_offsets.is_empty() || self.inbetweens.iter().any(|ib| !ib.normal_offsets.is_empty())
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
    /// `constant` interpolation: one set of influences for the whole mesh
    /// (usd-core then moves the mesh's transform, not its points).
    pub rigid: bool,
}

/// Everything needed to deform one skinned mesh, read once.
#[derive(Debug, Clone)]
pub struct SkelDeformer {
    /// The mesh's own `points` (bind pose, no blend shapes).
    pub rest_points: Vec<DVec3>,
    /// `primvars:skel:geomBindTransform` (column form).
    pub geom_bind: DMat4,
    /// Joint influences; None when the mesh has none (blend shapes only).
    pub influences: Option<Influences>,
    pub method: SkinningMethod,
    /// Blend shapes in the mesh's `skel:blendShapes` order.
    pub blend_shapes: Vec<BlendShape>,
}

impl SkelDeformer {
    /// Deformed points for blend-shape weights (mesh order) and, when the
    /// mesh is skinned by joints, their skinning transforms (mesh joint
    /// order, column form: inverse bind then posed joint).
    ///
    /// With joint skinning the result is in skeleton space; without, the
    /// blend-shaped points stay in the mesh's own space (BakeSkinning
    /// applies no geomBindTransform then).
    pub fn deform(&self, skinning: Option<&[DMat4]>, shape_weights: &[f64]) -> Vec<DVec3> {
        let mut pts = self.rest_points.clone();
        for (shape, &w) in self.blend_shapes.iter().zip(shape_weights) {
            shape.apply(w, &mut pts);
        }
        let (Some(skinning), Some(infl)) = (skinning, &self.influences) else {
            return pts;
        };
        let dq = match self.method {
            SkinningMethod::ClassicLinear => None,
            SkinningMethod::DualQuaternion => Some(DqJoints::new(skinning)),
        };
        for (i, p) in pts.iter_mut().enumerate() {
            *p = skin_point(self.geom_bind.transform_point3(*p), infl, i, skinning, dq.as_ref());
        }
        pts
    }

    /// Authored normals deformed as BakeSkinning deforms them: blend-shape
    /// normal offsets (then renormalised), then, when joints skin the mesh,
    /// the inverse transposes of the geomBindTransform and of each joint's
    /// skinning transform, blended like the points (LBS: weighted sum; DQS:
    /// blended rotation after the blended stretch) and renormalised. Rigid
    /// bindings (usd-core moves the mesh's transform instead) get the
    /// inverse transpose of the blended transform. `point_of` gives each
    /// normal's point for `faceVarying` normals (None: one per point). Same
    /// space as [`Self::deform`].
    pub fn deform_normals(
        &self,
        normals: &[DVec3],
        point_of: Option<&[u32]>,
        skinning: Option<&[DMat4]>,
        shape_weights: &[f64],
    ) -> Vec<DVec3> {
        let mut out = normals.to_vec();
        if point_of.is_none() && self.blend_shapes.iter().any(BlendShape::has_normal_offsets) {
            for (shape, &w) in self.blend_shapes.iter().zip(shape_weights) {
                shape.apply_normals(w, &mut out);
            }
            out.iter_mut().for_each(|n| *n = normalized(*n));
        }
        let (Some(skinning), Some(infl)) = (skinning, &self.influences) else {
            return out;
        };
        let point = |ni: usize| point_of.map_or(ni, |p| p[ni] as usize);
        if infl.rigid {
            // The linear part of p ↦ skin(geomBind · p), the same for every point.
            let dq = match self.method {
                SkinningMethod::ClassicLinear => None,
                SkinningMethod::DualQuaternion => Some(DqJoints::new(skinning)),
            };
            let f = |p: DVec3| skin_point(self.geom_bind.transform_point3(p), infl, 0, skinning, dq.as_ref());
            let o = f(DVec3::ZERO);
            let linear = DMat3::from_cols(f(DVec3::X) - o, f(DVec3::Y) - o, f(DVec3::Z) - o);
            let m = inverse_transpose(linear);
            return out.iter().map(|n| m * *n).collect();
        }
        let bind = inverse_transpose(DMat3::from_mat4(self.geom_bind));
        let joint: Vec<DMat3> = skinning
            .iter()
            .map(|s| inverse_transpose(DMat3::from_mat4(*s)))
            .collect();
        let dq = match self.method {
            SkinningMethod::ClassicLinear => None,
            SkinningMethod::DualQuaternion => Some(DqJoints::normal_rotations(&joint)),
        };
        let n_per = infl.per_point;
        for (ni, n) in out.iter_mut().enumerate() {
            let n0 = bind * *n;
            let pi = point(ni);
            let (joints, weights) = (
                &infl.joints[pi * n_per..pi * n_per + n_per],
                &infl.weights[pi * n_per..pi * n_per + n_per],
            );
            *n = normalized(match &dq {
                None => joints
                    .iter()
                    .zip(weights)
                    .filter(|(_, &w)| w != 0.0)
                    .map(|(&j, &w)| joint[j as usize] * n0 * w)
                    .sum(),
                Some(dq) => dq.skin(n0, joints, weights),
            });
        }
        out
    }
}

/// One point (already through the geomBindTransform), skinned with point
/// `i`'s influences.
fn skin_point(bound: DVec3, infl: &Influences, i: usize, skinning: &[DMat4], dq: Option<&DqJoints>) -> DVec3 {
    let n = infl.per_point;
    let joints = &infl.joints[i * n..i * n + n];
    let weights = &infl.weights[i * n..i * n + n];
    match dq {
        None => {
            let mut acc = DVec3::ZERO;
            for (&j, &w) in joints.iter().zip(weights) {
                if w != 0.0 {
                    acc += skinning[j as usize].transform_point3(bound) * w;
                }
            }
            acc
        }
        Some(dq) => dq.skin(bound, joints, weights),
    }
}

/// Inverse transpose of a 3x3 (identity when singular, as a normal matrix
/// has nothing better to offer).
fn inverse_transpose(m: DMat3) -> DMat3 {
    if m.determinant().abs() > 0.0 {
        m.inverse().transpose()
    } else {
        DMat3::IDENTITY
    }
}

/// Gf's GetNormalized: divided by its length, or by 1e-10 when shorter.
fn normalized(v: DVec3) -> DVec3 {
    v / v.length().max(1e-10)
}

/// A unit dual quaternion (rotation `real`, translation in `dual`).
#[derive(Debug, Clone, Copy)]
struct DualQuat {
    real: DQuat,
    dual: DQuat,
}

/// Every joint's skinning transform split as UsdSkel's DQS does: a rigid
/// part (blended as dual quaternions) after a scale/shear part (blended
/// linearly, and only when some joint has one).
struct DqJoints {
    rigid: Vec<DualQuat>,
    stretch: Vec<DMat3>,
    /// Whether any stretch differs from identity (by 1e-6 or more in an
    /// entry, GfIsClose's strict test); when none does, points are not multiplied by the weight sum.
    has_stretch: bool,
}

impl DqJoints {
    /// Joints from their rigid and stretch parts; `has_stretch` follows.
    fn from_parts(rigid: Vec<DualQuat>, stretch: Vec<DMat3>) -> Self {
        let has_stretch = stretch.iter().any(|s| {
            (*s - DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .any(|d| !gf_is_close(*d, 0.0, 1e-6))
        });
        DqJoints {
            rigid,
            stretch,
            has_stretch,
        }
    }

    fn new(skinning: &[DMat4]) -> Self {
        let mut rigid = Vec::with_capacity(skinning.len());
        let mut stretch = Vec::with_capacity(skinning.len());
        for m in skinning {
            let linear = DMat3::from_mat4(*m);
            if linear.determinant().abs() < 1e-10 {
                // UsdSkel cannot factor it: it contributes nothing.
                let zero = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
                rigid.push(DualQuat { real: zero, dual: zero });
                stretch.push(DMat3::IDENTITY);
                continue;
            }
            let t = m.w_axis.truncate();
            // Polar decomposition linear = R · S with R a rotation.
            let (r, s) = polar(linear);
            let real = DQuat::from_mat3(&r).normalize();
            let tq = DQuat::from_xyzw(t.x, t.y, t.z, 0.0);
            let dual = (tq * real) * 0.5;
            rigid.push(DualQuat { real, dual });
            stretch.push(s);
        }
        DqJoints::from_parts(rigid, stretch)
    }

    /// For normals: each joint's normal matrix (inverse transpose) split as
    /// UsdSkel does, a rotation from Gf's iterative orthonormalisation of
    /// its rows and the stretch left over (not a polar decomposition: they
    /// differ when joints scale non-uniformly).
    fn normal_rotations(mats: &[DMat3]) -> Self {
        let mut rigid = Vec::with_capacity(mats.len());
        let mut stretch = Vec::with_capacity(mats.len());
        for m in mats {
            let r = orthonormalized(*m);
            let zero = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
            rigid.push(DualQuat {
                real: rotation_quaternion(&r),
                dual: zero,
            });
            let s = if r.determinant().abs() > 0.0 {
                r.inverse() * *m
            } else {
                DMat3::IDENTITY
            };
            stretch.push(s);
        }
        DqJoints::from_parts(rigid, stretch)
    }

    /// One point. The pivot (the rotation every other joint's is brought
    /// onto the hemisphere of) is the joint with the largest weight, the
    /// first one on ties. A point whose weights are all zero stays where it
    /// is (UsdSkel normalises the zero dual quaternion to the identity).
    fn skin(&self, p: DVec3, joints: &[u32], weights: &[f64]) -> DVec3 {
        let mut pivot: Option<(usize, f64)> = None;
        for (&j, &w) in joints.iter().zip(weights) {
            if pivot.is_none_or(|(_, best)| best < w) {
                pivot = Some((j as usize, w));
            }
        }
        let pivot = pivot.map_or(DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), |(j, _)| self.rigid[j].real);
        let mut real = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        let mut dual = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        let mut scaled = DVec3::ZERO;
        for (&j, &w) in joints.iter().zip(weights) {
            if w == 0.0 {
                continue;
            }
            let q = &self.rigid[j as usize];
            if self.has_stretch {
                scaled += self.stretch[j as usize] * p * w;
            }
            let w = if q.real.dot(pivot) < 0.0 { -w } else { w };
            real = real + q.real * w;
            dual = dual + q.dual * w;
        }
        if !self.has_stretch {
            scaled = p;
        }
        let len = real.length();
        if len < 1e-10 {
            return scaled;
        }
        let (real, dual) = (real * (1.0 / len), dual * (1.0 / len));
        let t = (dual * real.conjugate()) * 2.0;
        real * scaled + DVec3::new(t.x, t.y, t.z)
    }
}

/// Polar decomposition M = R · S (R proper rotation, S symmetric) by SVD.
fn polar(m: DMat3) -> (DMat3, DMat3) {
    let a = nalgebra::Matrix3::from_column_slice(&m.to_cols_array());
    let svd = a.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return (DMat3::IDENTITY, m);
    };
    let mut r = u * vt;
    // A mirroring M: the rotation is −U·Vᵀ and S takes all three scales
    // negative, as GfMatrix4d::Factor (and so UsdSkel's DQS) splits it.
    if r.determinant() < 0.0 {
        r = -r;
    }
    let rg = DMat3::from_cols_slice(r.as_slice());
    (rg, rg.transpose() * m)
}

/// Joint local transforms (skeleton order) to skeleton space. Parents come
/// before their children (a valid UsdSkel topology; checked when read).
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

    fn ib(weight: f64, offsets: Vec<DVec3>) -> Inbetween {
        Inbetween {
            weight,
            offsets,
            normal_offsets: vec![],
        }
    }

    fn shape_with_inbetween() -> BlendShape {
        BlendShape {
            offsets: vec![DVec3::new(2.0, 0.0, 0.0)],
            inbetweens: vec![ib(0.5, vec![DVec3::new(0.0, 1.0, 0.0)])],
            ..Default::default()
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
    fn inbetweens_extrapolate_below_and_ignore_weights_at_0_and_1() {
        let s = BlendShape {
            offsets: vec![DVec3::X],
            // The ones at ~0 and ~1 are ignored (usd-core: within 1e-6).
            inbetweens: vec![
                ib(-0.5, vec![DVec3::Y]),
                ib(1.0 - 1e-7, vec![DVec3::Z * 100.0]),
                ib(1e-7, vec![DVec3::Z * 100.0]),
            ],
            ..Default::default()
        };
        let at = |w| {
            let mut p = vec![DVec3::ZERO];
            s.apply(w, &mut p);
            p[0]
        };
        assert!((at(-0.5) - DVec3::Y).length() < 1e-12);
        // Below the lowest breakpoint the (-0.5, 0) segment extrapolates.
        assert!((at(-1.0) - DVec3::Y * 2.0).length() < 1e-12);
        assert!((at(-0.25) - DVec3::Y * 0.5).length() < 1e-12);
        assert!((at(2.0) - DVec3::X * 2.0).length() < 1e-12);
    }

    #[test]
    fn shapes_without_offsets_move_nothing() {
        let s = BlendShape {
            inbetweens: vec![ib(0.5, vec![DVec3::Y])],
            ..Default::default()
        };
        let mut p = vec![DVec3::ZERO];
        s.apply(1.0, &mut p);
        assert_eq!(p[0], DVec3::ZERO);
        s.apply(0.25, &mut p);
        assert!((p[0] - DVec3::Y * 0.5).length() < 1e-12);
    }

    #[test]
    fn sparse_offsets_touch_only_their_points() {
        let s = BlendShape {
            offsets: vec![DVec3::X],
            point_indices: Some(vec![1]),
            ..Default::default()
        };
        let mut p = vec![DVec3::ZERO; 3];
        s.apply(0.5, &mut p);
        assert_eq!(p, vec![DVec3::ZERO, DVec3::X * 0.5, DVec3::ZERO]);
    }

    fn deformer(method: SkinningMethod) -> SkelDeformer {
        SkelDeformer {
            rest_points: vec![DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 2.0, 0.0)],
            geom_bind: DMat4::IDENTITY,
            influences: Some(Influences {
                per_point: 2,
                joints: vec![0, 1, 0, 1],
                weights: vec![0.5, 0.5, 1.0, 0.0],
                rigid: false,
            }),
            method,
            blend_shapes: vec![],
        }
    }

    #[test]
    fn lbs_averages_joint_transforms() {
        let d = deformer(SkinningMethod::ClassicLinear);
        let xf = [DMat4::IDENTITY, DMat4::from_translation(DVec3::new(0.0, 0.0, 2.0))];
        let p = d.deform(Some(&xf), &[]);
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
        let lbs = deformer(SkinningMethod::ClassicLinear).deform(Some(&xf), &[]);
        let dqs = deformer(SkinningMethod::DualQuaternion).deform(Some(&xf), &[]);
        assert!(lbs[0].length() < 1e-12);
        assert!((dqs[0] - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12);
        // Single influence: DQS equals the rigid transform itself.
        assert!((dqs[1] - xf[0].transform_point3(DVec3::new(0.0, 2.0, 0.0))).length() < 1e-12);
    }

    #[test]
    fn dqs_of_translation_and_rotation_single_joint() {
        let m = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0)) * DMat4::from_rotation_y(0.7);
        let mut d = deformer(SkinningMethod::DualQuaternion);
        d.influences.as_mut().unwrap().weights = vec![1.0, 0.0, 1.0, 0.0];
        let p = d.deform(Some(&[m, DMat4::IDENTITY]), &[]);
        assert!((p[0] - m.transform_point3(DVec3::X)).length() < 1e-12);
    }

    #[test]
    fn dqs_pivot_is_the_largest_weight() {
        // Rotations of 0°, +120° and -120° about z: +120° and -120° are on
        // opposite quaternion hemispheres. With the +120° joint as pivot (the
        // largest weight), the -120° one is flipped; a pivot at the first
        // joint would flip nothing and give another point.
        let xf = [
            DMat4::IDENTITY,
            DMat4::from_rotation_z(120f64.to_radians()),
            DMat4::from_rotation_z(-120f64.to_radians()),
        ];
        let w = [0.2, 0.5, 0.3];
        let mut d = deformer(SkinningMethod::DualQuaternion);
        d.rest_points = vec![DVec3::X];
        d.influences = Some(Influences {
            per_point: 3,
            joints: vec![0, 1, 2],
            weights: w.to_vec(),
            rigid: false,
        });
        let p = d.deform(Some(&xf), &[])[0];
        let q = |deg: f64| DQuat::from_rotation_z(deg.to_radians());
        let blend = (q(0.0) * w[0] + q(120.0) * w[1] - q(-120.0) * w[2]).normalize();
        assert!((p - blend * DVec3::X).length() < 1e-12, "{p}");
    }

    #[test]
    fn dqs_without_joint_scale_ignores_the_weight_sum() {
        let xf = [DMat4::from_rotation_z(0.3), DMat4::from_rotation_z(-0.2)];
        let mut d = deformer(SkinningMethod::DualQuaternion);
        d.influences.as_mut().unwrap().weights = vec![0.4, 0.4, 0.9, 0.0];
        let p = d.deform(Some(&xf), &[]);
        // Unnormalised weights: the rigid blend is normalised, the point is not scaled.
        assert!((p[0].length() - 1.0).abs() < 1e-12);
        assert!((p[1].length() - 2.0).abs() < 1e-12);
        // With a scaled joint the stretch part is the weighted sum.
        let xf = [DMat4::from_scale(DVec3::splat(2.0)), DMat4::IDENTITY];
        let p = d.deform(Some(&xf), &[]);
        assert!((p[0] - DVec3::X * (0.4 * 2.0 + 0.4)).length() < 1e-12);
    }

    #[test]
    fn normals_follow_the_inverse_transpose() {
        // A joint squashing y by 2 tilts a 45° normal towards y.
        let mut d = deformer(SkinningMethod::ClassicLinear);
        d.influences.as_mut().unwrap().weights = vec![1.0, 0.0, 1.0, 0.0];
        let s = DMat4::from_scale(DVec3::new(1.0, 0.5, 1.0));
        let n = DVec3::new(1.0, 1.0, 0.0).normalize();
        let out = d.deform_normals(&[n, n], None, Some(&[s, DMat4::IDENTITY]), &[]);
        let want = DVec3::new(1.0, 2.0, 0.0).normalize();
        assert!((out[0] - want).length() < 1e-12, "{}", out[0]);
        // faceVarying: each normal takes its point's influences.
        let out = d.deform_normals(&[n], Some(&[1]), Some(&[s, DMat4::IDENTITY]), &[]);
        assert!((out[0] - want).length() < 1e-12);
    }

    #[test]
    fn orthonormalized_keeps_rotations_and_orthogonalises() {
        let r = DMat3::from_rotation_y(0.7) * DMat3::from_rotation_x(-0.3);
        assert!((orthonormalized(r) - r).to_cols_array().iter().all(|d| d.abs() < 1e-12));
        let m = DMat3::from_cols(
            DVec3::new(1.0, 0.2, 0.0),
            DVec3::new(0.1, 2.0, 0.3),
            DVec3::new(0.0, 0.0, 0.5),
        );
        let o = orthonormalized(m);
        let g = o.transpose() * o;
        assert!(
            (g - DMat3::IDENTITY).to_cols_array().iter().all(|d| d.abs() < 1e-5),
            "{g}"
        );
    }

    #[test]
    fn skeleton_space_composes_parents_first() {
        let local = [DMat4::from_translation(DVec3::X), DMat4::from_translation(DVec3::Y)];
        let skel = local_to_skel(&local, &[None, Some(0)]);
        assert_eq!(skel[1].transform_point3(DVec3::ZERO), DVec3::new(1.0, 1.0, 0.0));
    }

    /// Where `s` at weight `w` moves a point at the origin.
    fn shape_at(s: &BlendShape, w: f64) -> DVec3 {
        let mut p = vec![DVec3::ZERO];
        s.apply(w, &mut p);
        p[0]
    }

    #[test]
    fn shape_weights_below_1e6_are_skipped_and_1e6_applies() {
        // UsdSkelApplyBlendShape skips a weight when GfIsClose(w, 0, 1e-6),
        // i.e. |w| < 1e-6 (strict).
        let s = BlendShape {
            offsets: vec![DVec3::X * 1e6],
            ..Default::default()
        };
        assert_eq!(shape_at(&s, 5e-7), DVec3::ZERO);
        assert_eq!(shape_at(&s, -5e-7), DVec3::ZERO);
        assert!((shape_at(&s, 1e-6) - DVec3::X).length() < 1e-9);
    }

    #[test]
    fn the_top_segment_extrapolates_among_three_inbetweens() {
        // Breakpoints 0, 0.25, 0.5, 0.75, 1 (inbetweens listed out of order):
        // above 1 the (0.75, 1) segment extrapolates, alpha = 3, so
        // 3·X − 2·(0.5·X) = 2·X.
        let s = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![
                ib(0.75, vec![DVec3::X * 0.5]),
                ib(0.25, vec![DVec3::Y]),
                ib(0.5, vec![DVec3::Z]),
            ],
            ..Default::default()
        };
        assert!((shape_at(&s, 1.5) - DVec3::X * 2.0).length() < 1e-12);
        assert!((shape_at(&s, 0.375) - (DVec3::Y + DVec3::Z) * 0.5).length() < 1e-12);
    }

    #[test]
    fn a_weight_shared_by_two_inbetweens_applies_the_later_one() {
        // As UsdSkel.BlendShapeQuery does (checked with usd-core): at the shared
        // weight the later inbetween, below it the earlier one, above it the later.
        let s = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![ib(0.5, vec![DVec3::Y]), ib(0.5, vec![DVec3::Z])],
            ..Default::default()
        };
        assert_eq!(shape_at(&s, 0.5), DVec3::Z);
        assert!((shape_at(&s, 0.25) - DVec3::Y * 0.5).length() < 1e-12);
        assert!((shape_at(&s, 0.75) - (DVec3::X + DVec3::Z) * 0.5).length() < 1e-12);
    }

    #[test]
    fn normal_offsets_on_an_inbetween_alone_deform_normals() {
        let only_points = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![ib(0.5, vec![DVec3::Y])],
            ..Default::default()
        };
        assert!(!only_points.has_normal_offsets());
        let s = BlendShape {
            inbetweens: vec![Inbetween {
                weight: 0.5,
                offsets: vec![],
                normal_offsets: vec![DVec3::Y],
            }],
            ..Default::default()
        };
        assert!(s.has_normal_offsets());
        let mut d = deformer(SkinningMethod::ClassicLinear);
        d.influences = None;
        d.blend_shapes = vec![s];
        let out = d.deform_normals(&[DVec3::X], None, None, &[0.5]);
        let want = DVec3::new(1.0, 1.0, 0.0).normalize();
        assert!((out[0] - want).length() < 1e-12, "{}", out[0]);
    }

    #[test]
    fn normals_of_a_joint_scaled_to_zero_keep_their_direction() {
        // No inverse transpose exists: Gf's inverse is then FLT_MAX·I, which
        // leaves a lone influence's normal where it was, as our identity does.
        let mut d = deformer(SkinningMethod::ClassicLinear);
        d.influences.as_mut().unwrap().weights = vec![1.0, 0.0, 1.0, 0.0];
        let flat = DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0));
        let n = DVec3::new(1.0, 1.0, 0.0).normalize();
        let out = d.deform_normals(&[n], None, Some(&[flat, DMat4::IDENTITY]), &[]);
        assert!((out[0] - n).length() < 1e-12, "{}", out[0]);
    }

    #[test]
    fn dqs_normals_of_a_mirrored_joint_blended_with_another_match_usd_core() {
        // usd-core 26.11: UsdSkel.SkinNormals(dualQuaternion, identity, the
        // inverse transposes of [S(-1, 1, 1)·T(0.5, 0.2, 0), rotate z 0.6 rad]
        // (row vectors), indices [0, 1], weights [0.6, 0.4], 2 per point), in
        // float. Gf takes the mirror's quaternion from an improper matrix.
        let mirrored =
            DMat4::from_translation(DVec3::new(0.5, 0.2, 0.0)) * DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        let turned = DMat4::from_rotation_z(0.6);
        let d = SkelDeformer {
            rest_points: vec![DVec3::ZERO],
            influences: Some(Influences {
                per_point: 2,
                joints: vec![0, 1],
                weights: vec![0.6, 0.4],
                rigid: false,
            }),
            ..deformer(SkinningMethod::DualQuaternion)
        };
        for (n, want) in [
            (
                (0.3, 1.0, 0.4),
                (-0.9325495362281799, -0.048490848392248154, 0.3577708899974823),
            ),
            ((1.0, 0.0, 0.0), (-0.3366982042789459, 0.9416126012802124, 0.0)),
            (
                (0.2, -0.5, 0.8),
                (0.4183754324913025, 0.3698512613773346, 0.8295613527297974),
            ),
        ] {
            let n = DVec3::new(n.0, n.1, n.2);
            let got = d.deform_normals(&[n], None, Some(&[mirrored, turned]), &[])[0];
            let want = DVec3::new(want.0, want.1, want.2);
            assert!((got - want).abs().max_element() < 1e-6, "{n}: {got}, usd-core {want}");
        }
    }

    #[test]
    fn dqs_normals_of_a_lone_mirror_follow_gfs_largest_diagonal_rule() {
        // usd-core 26.11: UsdSkel.SkinNormals(dualQuaternion, identity, [M], [0],
        // [1], 1, [(0.3, 0.5, 0.8)]) for each mirror M: Gf's rule on an improper
        // matrix gives a half turn (its ties between equal diagonal entries and
        // between the trace and the largest entry decide which), not the mirror.
        let d = SkelDeformer {
            rest_points: vec![DVec3::ZERO],
            influences: Some(Influences {
                per_point: 1,
                joints: vec![0],
                weights: vec![1.0],
                rigid: false,
            }),
            ..deformer(SkinningMethod::DualQuaternion)
        };
        let (x, y, z) = (0.30304577946662903, 0.5050762891769409, 0.8081220388412476);
        for (mirror, want) in [
            (DVec3::new(-1.0, 1.0, 1.0), DVec3::new(-x, -y, z)),
            (DVec3::new(1.0, -1.0, 1.0), DVec3::new(-x, -y, z)),
            (DVec3::new(1.0, 1.0, -1.0), DVec3::new(-x, y, -z)),
            (DVec3::splat(-1.0), DVec3::new(-x, -y, z)),
        ] {
            let m = DMat4::from_scale(mirror);
            let got = d.deform_normals(&[DVec3::new(0.3, 0.5, 0.8)], None, Some(&[m]), &[])[0];
            assert!(
                (got - want).abs().max_element() < 1e-6,
                "{mirror}: {got}, usd-core {want}"
            );
        }
    }

    #[test]
    fn gf_rotation_quaternion_agrees_with_glam_on_rotations() {
        // Every branch of the largest-diagonal rule: small and large angles
        // about each axis, and half turns.
        for axis in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(1.0, 2.0, -0.5).normalize()] {
            for angle in [0.0, 0.3, 2.0, 3.0, std::f64::consts::PI] {
                let q = DQuat::from_axis_angle(axis, angle);
                let got = rotation_quaternion(&DMat3::from_quat(q));
                let d = if got.dot(q) < 0.0 { -got } else { got };
                assert!((d - q).length() < 1e-12, "{axis} {angle}: {got} vs {q}");
            }
        }
    }

    #[test]
    fn a_degenerate_normal_matrix_gets_an_identity_stretch() {
        // Its orthonormalisation is singular: the stretch must not turn NaN.
        let dq = DqJoints::normal_rotations(&[DMat3::ZERO]);
        assert_eq!(dq.stretch[0], DMat3::IDENTITY);
    }

    /// One point skinned by dual quaternions with the given influences.
    fn dqs_point(xf: &[DMat4], joints: &[u32], weights: &[f64], p: DVec3) -> DVec3 {
        let d = SkelDeformer {
            rest_points: vec![p],
            influences: Some(Influences {
                per_point: joints.len(),
                joints: joints.to_vec(),
                weights: weights.to_vec(),
                rigid: false,
            }),
            ..deformer(SkinningMethod::DualQuaternion)
        };
        d.deform(Some(xf), &[])[0]
    }

    fn rot_z(deg: f64) -> DQuat {
        DQuat::from_rotation_z(deg.to_radians())
    }

    #[test]
    fn dqs_pivot_ties_go_to_the_first_joint() {
        // +120° and -120° share the largest weight; usd-core takes the first as
        // pivot (checked with UsdSkel.SkinPoints), so -120° is the one flipped.
        let xf = [0.0, 120.0, -120.0].map(|deg: f64| DMat4::from_rotation_z(deg.to_radians()));
        let p = dqs_point(&xf, &[1, 2, 0], &[0.4, 0.4, 0.2], DVec3::X);
        let blend = (rot_z(120.0) * 0.4 - rot_z(-120.0) * 0.4 + rot_z(0.0) * 0.2).normalize();
        assert!((p - blend * DVec3::X).length() < 1e-12, "{p}");
    }

    #[test]
    fn dqs_does_not_flip_a_joint_orthogonal_to_the_pivot() {
        // A half turn about z is at exactly 90° (dot 0) from the identity pivot
        // in quaternion space; usd-core flips only below 0: (0, 0, 0.3, 0.7).
        let half_turn = DMat4::from_scale(DVec3::new(-1.0, -1.0, 1.0));
        let p = dqs_point(&[DMat4::IDENTITY, half_turn], &[0, 1], &[0.7, 0.3], DVec3::X);
        let angle = 2.0 * 0.3f64.atan2(0.7);
        assert!((p - DVec3::new(angle.cos(), angle.sin(), 0.0)).length() < 1e-12, "{p}");
    }

    #[test]
    fn dqs_points_without_weight_stay_unless_a_joint_stretches() {
        let t = DVec3::new(1.0, 2.0, 3.0);
        let moved = DMat4::from_translation(t);
        let p = DVec3::new(0.3, 1.0, 0.4);
        // The zero dual quaternion normalises to the identity (GfDualQuat)...
        assert_eq!(dqs_point(&[moved], &[0], &[0.0], p), p);
        // ...applied to the stretch blend, which with no weight is the origin
        // (UsdSkel.SkinPoints gives the same).
        let stretched = DMat4::from_scale(DVec3::new(2.0, 1.0, 1.0));
        assert_eq!(dqs_point(&[stretched, moved], &[0, 1], &[0.0, 0.0], p), DVec3::ZERO);
        // Only a length below 1e-10 counts as zero (Normalize's strict <).
        assert!((dqs_point(&[moved], &[0], &[1e-10], p) - (p + t)).length() < 1e-12);
    }

    #[test]
    fn dqs_blends_the_rotations_and_keeps_a_shared_translation() {
        // Both joints rotate then move by t: the dual parts are t/2 times the
        // real ones, so after normalising the translation is t exactly.
        let t = DVec3::new(1.0, -2.0, 0.5);
        let xf = [0.0, 90.0].map(|deg: f64| DMat4::from_translation(t) * DMat4::from_rotation_z(deg.to_radians()));
        let p = DVec3::new(0.3, 1.0, 0.4);
        let rot = (rot_z(0.0) * 0.75 + rot_z(90.0) * 0.25).normalize();
        let got = dqs_point(&xf, &[0, 1], &[0.75, 0.25], p);
        assert!((got - (rot * p + t)).length() < 1e-12, "{got}");
    }

    #[test]
    fn dqs_of_a_lone_mirrored_joint_is_its_transform() {
        // Negative determinant: the rotation must stay proper and the mirror go
        // into the stretch, or one joint would not reproduce its own transform.
        let m = DMat4::from_translation(DVec3::new(0.5, 0.2, -0.3))
            * DMat4::from_rotation_z(0.6)
            * DMat4::from_scale(DVec3::new(-1.5, 1.0, 0.8));
        let p = DVec3::new(0.3, 1.0, 0.4);
        let got = dqs_point(&[m], &[0], &[1.0], p);
        assert!((got - m.transform_point3(p)).length() < 1e-12, "{got}");
    }

    #[test]
    fn dqs_of_a_mirrored_joint_blended_with_another_matches_usd_core() {
        // usd-core 26.11: UsdSkel.SkinPoints(dualQuaternion, identity,
        // [S(-1, 1, 1)·T(0.5, 0.2, 0), rotate z 0.6 rad] (row vectors),
        // indices [0, 1], weights [0.6, 0.4], 2 per point, (0.3, 1, 0.4))
        // = (0.30230263, 0.28625697, -0.1819558), in float.
        let mirrored =
            DMat4::from_translation(DVec3::new(0.5, 0.2, 0.0)) * DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        let turned = DMat4::from_rotation_z(0.6);
        let got = dqs_point(&[mirrored, turned], &[0, 1], &[0.6, 0.4], DVec3::new(0.3, 1.0, 0.4));
        let want = DVec3::new(0.30230263, 0.28625697, -0.1819558);
        assert!((got - want).abs().max_element() < 1e-6, "{got}");
    }

    #[test]
    fn orthonormalized_stops_where_gf_stops() {
        // Expected: usd-core's Gf.Matrix4d.GetOrthonormalized of these rows. It
        // stops after the first round moving less than 1e-12 (squared), about
        // 2e-9 short of where all 20 rounds would get.
        let m = DMat3::from_cols(DVec3::X, DVec3::new(0.8, 0.6, 0.0), DVec3::new(0.6, 0.2, 0.7));
        let gf = DMat3::from_cols(
            DVec3::new(0.885225033639539, -0.4505438270964198, -0.11570177044102796),
            DVec3::new(0.4232627573625968, 0.8833409595818685, -0.20138864753206762),
            DVec3::new(0.1929385248704092, 0.1293020248241101, 0.9726539528512778),
        );
        let o = orthonormalized(m);
        assert!((o - gf).to_cols_array().iter().all(|d| d.abs() < 1e-12), "{o}");
    }

    #[test]
    fn orthonormalized_leaves_nearly_colinear_vectors_normalised() {
        // Two vectors within 1e-6 once normalised: Gf gives up and returns
        // them normalised (iterating would spread them 90° apart).
        let m = DMat3::from_cols(DVec3::X * 2.0, DVec3::new(1.0, 9e-7, 0.0), DVec3::Z);
        let want = DMat3::from_cols(DVec3::X, DVec3::new(1.0, 9e-7, 0.0).normalize(), DVec3::Z);
        let o = orthonormalized(m);
        assert!((o - want).to_cols_array().iter().all(|d| d.abs() < 1e-15), "{o}");
    }

    #[test]
    fn orthonormalized_measures_closeness_by_length_as_gf_does() {
        // Rows (1, 0, 0), (1, 9e-7, 9e-7), (0, 0, 1): the second differs from
        // the first by 9e-7 in each of two entries, 1.27e-6 in length, so Gf
        // iterates. Expected: usd-core's Gf.Matrix4d.GetOrthonormalized.
        let m = DMat3::from_cols(DVec3::X, DVec3::new(1.0, 9e-7, 9e-7), DVec3::Z);
        let gf = DMat3::from_cols(
            DVec3::new(0.7071070993843122, -0.7071064629886274, 1.323090131581618e-07),
            DVec3::new(0.7071064629883347, 0.7071070993841683, 7.968528491832221e-07),
            DVec3::new(-6.570164416105956e-07, -4.699037485056432e-07, 0.9999999999996738),
        );
        let o = orthonormalized(m);
        assert!((o - gf).to_cols_array().iter().all(|d| d.abs() < 1e-12), "{o}");
    }

    #[test]
    fn orthonormalized_gives_up_when_any_two_are_close() {
        // Only the first two rows are close (7.1e-7 apart); the third leans
        // on the first, so a round of iterating would move it. usd-core's
        // GetOrthonormalized returns the rows normalised, unchanged.
        let m = DMat3::from_cols(DVec3::X, DVec3::new(1.0, 5e-7, 5e-7), DVec3::new(0.6, 0.0, 0.8));
        let gf = DMat3::from_cols(
            DVec3::X,
            DVec3::new(0.99999999999975, 4.999999999998749e-07, 4.999999999998749e-07),
            DVec3::new(0.6, 0.0, 0.8),
        );
        let o = orthonormalized(m);
        assert!((o - gf).to_cols_array().iter().all(|d| d.abs() < 1e-15), "{o}");
    }

    #[test]
    fn orthonormalized_gives_up_when_the_last_two_are_close() {
        // Only the second and third rows are close (7.1e-7 apart); the first
        // is far from both but leans on them, so a round of iterating would
        // move it. usd-core's GetOrthonormalized returns the rows normalised,
        // unchanged (and warns that it did not converge).
        let m = DMat3::from_cols(DVec3::new(0.6, 0.0, 0.8), DVec3::Z, DVec3::new(5e-7, 5e-7, 1.0));
        let gf = DMat3::from_cols(
            DVec3::new(0.6, 0.0, 0.8),
            DVec3::Z,
            DVec3::new(4.999999999998749e-07, 4.999999999998749e-07, 0.99999999999975),
        );
        let o = orthonormalized(m);
        assert!((o - gf).to_cols_array().iter().all(|d| d.abs() < 1e-15), "{o}");
    }

    #[test]
    fn a_parent_not_before_its_joint_is_not_composed() {
        // Refused when read; here such a joint is a root, not an index ahead.
        let local = [DMat4::from_translation(DVec3::X), DMat4::from_translation(DVec3::Y)];
        assert_eq!(local_to_skel(&local, &[Some(1), Some(1)]), local.to_vec());
    }

    #[test]
    fn an_inbetween_at_a_float_1e6_is_a_breakpoint() {
        // usd-core's BlendShapeQuery skips an inbetween only when its weight
        // is strictly closer than its float EPS to 0 or 1, so one authored at
        // 1e-6 (as a float) stays, and at that weight it is the whole shape
        // (ComputeSubShapeWeights([1e-6]) gives the inbetween at 1).
        let eps = 1e-6_f32 as f64;
        let at_eps = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![ib(eps, vec![DVec3::Y * 100.0])],
            ..Default::default()
        };
        assert_eq!(at_eps.sub_shapes(eps), vec![(SubShape::Inbetween(0), 1.0)]);
        assert_eq!(shape_at(&at_eps, eps), DVec3::Y * 100.0);
        // Below it, the (0, 1e-6) segment is no wider than EPS: nothing
        // (weightDelta > EPS fails), as usd-core gives for w = 5e-7.
        assert!(at_eps.sub_shapes(eps / 2.0).is_empty());
        // The float just below 1e-6 is close to 0: skipped, the primary is linear.
        let below = f32::from_bits(1e-6_f32.to_bits() - 1) as f64;
        let skipped = BlendShape {
            inbetweens: vec![ib(below, vec![DVec3::Y * 100.0])],
            ..at_eps.clone()
        };
        assert_eq!(skipped.sub_shapes(0.5), vec![(SubShape::Primary, 0.5)]);
    }

    #[test]
    fn a_segment_parameter_of_exactly_eps_keeps_its_sub_shape() {
        // Breakpoints -1, 0, 1: at w = 1e-6f the (0, 1) segment has alpha =
        // EPS, not close to 0, so the primary comes at EPS (usd-core:
        // ComputeSubShapeWeights([1e-6]) = primary at 9.99999997e-7); just
        // below, alpha is close to 0 and nothing comes.
        let eps = 1e-6_f32 as f64;
        let s = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![ib(-1.0, vec![DVec3::Y])],
            ..Default::default()
        };
        assert_eq!(s.sub_shapes(eps), vec![(SubShape::Primary, eps)]);
        let below = f32::from_bits(1e-6_f32.to_bits() - 1) as f64;
        assert!(s.sub_shapes(below).is_empty());
        // Near the top of a segment: alpha = 1 - EPS keeps the lower
        // sub-shape at EPS, alpha = 1 - EPS/2 drops it.
        let s = BlendShape {
            offsets: vec![DVec3::X],
            inbetweens: vec![ib(2.0, vec![DVec3::Y])],
            ..Default::default()
        };
        assert_eq!(s.sub_shapes(1.0 - eps), vec![(SubShape::Primary, 1.0 - eps)]);
        let at = |w: f64| s.sub_shapes(w).into_iter().map(|(k, _)| k).collect::<Vec<_>>();
        assert_eq!(at(1.0 + eps), vec![SubShape::Primary, SubShape::Inbetween(0)]);
        assert_eq!(at(2.0 - eps), vec![SubShape::Primary, SubShape::Inbetween(0)]);
        assert_eq!(at(2.0 - eps / 2.0), vec![SubShape::Inbetween(0)]);
    }

    #[test]
    fn a_stretch_of_exactly_1e6_counts_as_a_stretch() {
        // GfIsClose(scale, identity, 1e-6) is strict per entry (checked with
        // Gf.IsClose on Matrix3d): an entry off by exactly 1e-6 is a stretch.
        let off = |d: f64| DMat3::from_cols(DVec3::X, DVec3::new(d, 1.0, 0.0), DVec3::Z);
        assert!(DqJoints::from_parts(vec![], vec![DMat3::IDENTITY, off(1e-6)]).has_stretch);
        assert!(DqJoints::from_parts(vec![], vec![off(-1e-6)]).has_stretch);
        assert!(!DqJoints::from_parts(vec![], vec![off(0.999_999e-6), DMat3::IDENTITY]).has_stretch);
    }
}
