//! Configuration axes (SPEC §4): `PainterlyAxis` prims read from the stage and
//! evaluated at each baked time.
//!
//! Each axis yields one scalar coordinate in axis units, as the source
//! reads it. Pose keys' `coordinates` are stored in those units (SPEC 1.1
//! §4); `scale` (Bassett requirement 5: axes are scaled by their
//! importance) multiplies both sides only where keys are interpolated
//! ([`crate::usd_io::scene::LayerKeys::configuration`]), so re-scaling an
//! axis never moves its keys.

use glam::{DMat4, DQuat, DVec3};
use openusd::sdf::Value;
use openusd_schemas::skel::{Animation, SkelAnimQuery};

use super::stage::{HeldQuery, StageReader};
use super::values;
use crate::error::{Error, Result};

/// What an axis measures.
pub enum AxisSource {
    /// An attribute's resolved value; `element` picks an array element,
    /// `component` a vector/quaternion component.
    Attribute { prim: String, attr: String },
    /// The weight of blend shape `name` in a SkelAnimation: its
    /// `blendShapeWeights` and the shape's index there.
    BlendShape {
        weights: Option<HeldQuery>,
        index: Option<usize>,
    },
    /// A component of a joint's rotation vector relative to its rest rotation.
    JointRotation {
        rest: DQuat,
        /// The Skeleton's animation's `rotations`, and the animation's path.
        anim: Option<(HeldQuery, String)>,
        index: Option<usize>,
    },
    /// A component of a prim's world-space origin, in the proxy's local space.
    Position { prim: String },
    /// A component of the unit vector from the posed proxy's bounding-box
    /// centre to a camera, in the proxy's local space. `None`: the bake's
    /// `--camera`.
    ViewDirection { camera: Option<String> },
}

/// One `PainterlyAxis`.
pub struct Axis {
    pub path: String,
    /// The `kind` token.
    pub kind: String,
    pub source: AxisSource,
    pub element: i64,
    pub component: i64,
    /// `scale`: the axis's importance; multiplies coordinates where keys
    /// are interpolated, never what is stored.
    pub scale: f64,
}

/// Per-frame data axes are measured against.
pub struct AxisFrame<'a> {
    pub time: f64,
    /// Proxy local-to-world at `time`.
    pub proxy_to_world: DMat4,
    /// Centre of the posed proxy's bounding box, proxy-local.
    pub proxy_centre: DVec3,
    /// Length of that box's diagonal: a camera within 1e-6 of it (and of
    /// the centre's distance from the origin) is at the centre, its
    /// direction rounding noise.
    pub proxy_extent: f64,
    /// The bake's `--camera`, if any.
    pub camera: Option<&'a str>,
    /// A world-space eye position that replaces the camera of every
    /// viewDirection axis, even one with its own `source` (a live
    /// preview's orbit camera).
    pub eye: Option<DVec3>,
}

const KINDS: &str = "attribute, blendShape, jointRotation, position or viewDirection";

/// Checks an attribute axis's `element` and `component` against a value of
/// its attribute now (the default, or the first time sample), so `inspect`
/// reports a bad axis too.
fn check_attribute_pick(
    r: &StageReader,
    path: &str,
    target: &str,
    prim: &openusd::usd::Prim,
    attr: &str,
    element: i64,
    component: i64,
) -> Result<()> {
    let probe = match r.value(prim, attr, None)? {
        Some(v) => Some(v),
        None => match r.sample_times(prim, attr)?.first() {
            Some(&t0) => r.value(prim, attr, Some(t0))?,
            None => None,
        },
    };
    let Some(probe) = probe else {
        return Err(Error::attr(
            path,
            "source",
            format!("targets {target}, which has no value"),
        ));
    };
    pick(&probe, element, component).map_err(|(which, m)| Error::attr(path, which, format!("{target}: {m}")))?;
    Ok(())
}

/// A jointRotation axis's source: the joint's rest rotation and, where the
/// Skeleton has an animation that names the joint, where to read it there.
fn joint_rotation_source(
    r: &StageReader,
    path: &str,
    target: &str,
    skel: &openusd::usd::Prim,
    joint: &str,
) -> Result<AxisSource> {
    if r.type_name(skel)? != "Skeleton" {
        return Err(Error::attr(
            path,
            "source",
            format!("targets {target}, which is not a Skeleton"),
        ));
    }
    let joints = r
        .typed(skel, "joints", None, "token[]", values::token_array)?
        .unwrap_or_default();
    let j = joints.iter().position(|n| n == joint).ok_or_else(|| {
        // Joints are named by their whole path; a short name that ends
        // exactly one of them is most likely that one.
        let ends: Vec<&String> = joints.iter().filter(|n| n.rsplit('/').next() == Some(joint)).collect();
        let hint = match ends.as_slice() {
            [one] => format!(" (joints are named by their path: {one:?}?)"),
            _ => String::new(),
        };
        Error::attr(path, "name", format!("joint {joint:?} is not in {target}.joints{hint}"))
    })?;
    let rest = match r.value(skel, "restTransforms", None)? {
        Some(Value::Matrix4dVec(m)) if m.len() == joints.len() => rotation_of(&values::usd_matrix(&m[j])),
        _ => DQuat::IDENTITY,
    };
    let anim_path = super::skel::animation_source_path(r, skel)?;
    let (anim, index) = match anim_path {
        Some(a) => match anim_query(r, path, &a)? {
            Some(q) => {
                let index = q.joint_order().iter().position(|n| n == joint);
                (Some((HeldQuery::new(&r.require_prim(&a)?, "rotations")?, a)), index)
            }
            None => (None, None),
        },
        None => (None, None),
    };
    Ok(AxisSource::JointRotation { rest, anim, index })
}

impl Axis {
    /// Reads and validates an axis prim.
    pub fn read(r: &StageReader, path: &str) -> Result<Axis> {
        let prim = r.require_prim(path)?;
        let ty = r.type_name(&prim)?;
        if ty != "PainterlyAxis" {
            return Err(Error::prim(path, format!("is a {ty:?} prim, expected a PainterlyAxis")));
        }
        let kind = r
            .typed(&prim, "kind", None, "token", values::token)?
            .unwrap_or_else(|| "attribute".into());
        let int = |name: &str| -> Result<i64> {
            Ok(r.typed(&prim, name, None, "int", values::scalar)?.unwrap_or(0.0) as i64)
        };
        let element = int("element")?;
        let component = int("component")?;
        let scale = r.typed(&prim, "scale", None, "float", values::scalar)?.unwrap_or(1.0);
        if !scale.is_finite() {
            return Err(Error::attr(path, "scale", "scale is not finite"));
        }
        let name = r.typed(&prim, "name", None, "token", values::token)?;
        let target = r.one_target(&prim, "source")?;
        let need_target = |what: &str| -> Result<String> {
            target
                .clone()
                .ok_or_else(|| Error::attr(path, "source", format!("a {kind} axis needs `rel source` to {what}")))
        };
        let need_name = |what: &str| -> Result<String> {
            name.clone()
                .ok_or_else(|| Error::attr(path, "name", format!("a {kind} axis needs `token name` ({what})")))
        };
        let require = |p: &str, what: &str| -> Result<openusd::usd::Prim> {
            r.prim(p)?
                .ok_or_else(|| Error::attr(path, "source", format!("targets {p}, which does not exist ({what})")))
        };
        let check_component = |max: i64| -> Result<()> {
            if component < 0 || component > max {
                return Err(Error::attr(
                    path,
                    "component",
                    format!("component {component} is not in 0..={max}"),
                ));
            }
            Ok(())
        };
        let source = match kind.as_str() {
            "attribute" => {
                let t = need_target("an attribute")?;
                let (prim_path, attr) = t.split_once('.').ok_or_else(|| {
                    Error::attr(
                        path,
                        "source",
                        format!("targets {t}, which is a prim; expected an attribute path"),
                    )
                })?;
                let p = require(prim_path, "attribute's prim")?;
                check_attribute_pick(r, path, &t, &p, attr, element, component)?;
                AxisSource::Attribute {
                    prim: prim_path.to_string(),
                    attr: attr.to_string(),
                }
            }
            "blendShape" => {
                let t = need_target("a SkelAnimation")?;
                let shape = need_name("the blend shape's name")?;
                let anim_prim = require(&t, "SkelAnimation")?;
                let (weights, index) = match anim_query(r, path, &t)? {
                    Some(q) => (
                        Some(HeldQuery::new(&anim_prim, "blendShapeWeights")?),
                        q.blend_shape_order().iter().position(|n| *n == shape),
                    ),
                    None => (None, None),
                };
                AxisSource::BlendShape { weights, index }
            }
            "jointRotation" => {
                check_component(2)?;
                let t = need_target("a Skeleton")?;
                let joint = need_name("the joint's path in the Skeleton's joints")?;
                let skel = require(&t, "Skeleton")?;
                joint_rotation_source(r, path, &t, &skel, &joint)?
            }
            "position" => {
                check_component(2)?;
                let t = need_target("an Xformable prim")?;
                require(&t, "Xformable")?;
                AxisSource::Position { prim: t }
            }
            "viewDirection" => {
                check_component(2)?;
                if let Some(t) = &target {
                    require(t, "camera")?;
                }
                AxisSource::ViewDirection { camera: target }
            }
            other => {
                return Err(Error::attr(
                    path,
                    "kind",
                    format!("unknown axis kind {other:?} (expected {KINDS})"),
                ))
            }
        };
        Ok(Axis {
            path: path.to_string(),
            kind,
            source,
            element,
            component,
            scale,
        })
    }

    /// The coordinate at a frame, in axis units (before `scale`), sharing
    /// what `reads` already holds for this frame.
    pub fn value(&self, r: &StageReader, f: &AxisFrame, reads: &mut FrameReads) -> Result<f64> {
        let t = f.time;
        let raw = match &self.source {
            AxisSource::Attribute { prim, attr } => {
                let p = r.require_prim(prim)?;
                let v = r.value(&p, attr, Some(t))?.ok_or_else(|| {
                    Error::attr(&self.path, "source", format!("{prim}.{attr} has no value at time {t}"))
                })?;
                pick(&v, self.element, self.component)
                    .map_err(|(which, m)| Error::attr(&self.path, which, format!("{prim}.{attr}: {m}")))?
            }
            // Read as usd-core reads them (a sample holds up to a block),
            // which openusd-schemas' animation query does not.
            AxisSource::BlendShape { weights, index } => match (weights, index) {
                (Some(w), Some(i)) => w
                    .get_at(t)
                    .map_err(|e| Error::attr(&self.path, "source", format!("cannot read blend shape weights: {e}")))?
                    .and_then(|v| values::f32_array(&v))
                    .and_then(|w| w.get(*i).copied())
                    .unwrap_or(0.0) as f64,
                _ => 0.0,
            },
            AxisSource::JointRotation { rest, anim, index } => {
                let q = match (anim, index) {
                    (Some((a, anim_path)), Some(i)) => {
                        let rots = reads.joint_rotations(anim_path, || {
                            let v = a.get_at(t).map_err(|e| {
                                Error::attr(&self.path, "source", format!("cannot read joint rotations: {e}"))
                            })?;
                            Ok(v.and_then(|v| v.cast::<Vec<openusd::gf::Quatf>>().ok())
                                .unwrap_or_default())
                        })?;
                        // No rotation there: usd-core leaves the joint at rest.
                        match rots.get(*i) {
                            Some(q) => DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64).normalize(),
                            None => *rest,
                        }
                    }
                    _ => *rest,
                };
                rotation_vector(rest.inverse() * q)[self.component as usize]
            }
            AxisSource::Position { prim } => {
                let p = r.require_prim(prim)?;
                let world = r.local_to_world(&p, t)?.transform_point3(DVec3::ZERO);
                f.proxy_to_world.inverse().transform_point3(world)[self.component as usize]
            }
            AxisSource::ViewDirection { camera } => {
                let (world, cam) = match f.eye {
                    Some(eye) => (eye, self.path.as_str()),
                    None => {
                        let cam = camera.as_deref().or(f.camera).ok_or_else(|| {
                            Error::attr(
                                &self.path,
                                "source",
                                "a viewDirection axis needs `rel source` or `--camera`",
                            )
                        })?;
                        let p = r
                            .prim(cam)?
                            .ok_or_else(|| Error::prim(cam, "camera prim does not exist"))?;
                        (r.local_to_world(&p, t)?.transform_point3(DVec3::ZERO), cam)
                    }
                };
                let local = f.proxy_to_world.inverse().transform_point3(world);
                let d = local - f.proxy_centre;
                if crate::view::eye_at_centre(d, f.proxy_extent, f.proxy_centre) {
                    return Err(Error::prim(cam, format!("camera is at the proxy's centre at time {t}")));
                }
                d.normalize()[self.component as usize]
            }
        };
        if !raw.is_finite() {
            return Err(Error::attr(
                &self.path,
                "source",
                format!("value at time {t} is not finite"),
            ));
        }
        Ok(raw)
    }
}

/// What one frame's axes read in common: the joint rotations of each
/// SkelAnimation, read once however many jointRotation axes measure it
/// (the keys bench has 21 on one animation). Only for one frame's time.
#[derive(Default)]
pub struct FrameReads {
    rotations: Vec<(String, Vec<openusd::gf::Quatf>)>,
}

impl FrameReads {
    fn joint_rotations(
        &mut self,
        anim: &str,
        read: impl FnOnce() -> Result<Vec<openusd::gf::Quatf>>,
    ) -> Result<&[openusd::gf::Quatf]> {
        let at = match self.rotations.iter().position(|(a, _)| a == anim) {
            Some(at) => at,
            None => {
                self.rotations.push((anim.to_string(), read()?));
                self.rotations.len() - 1
            }
        };
        Ok(&self.rotations[at].1)
    }
}

fn anim_query(r: &StageReader, axis: &str, path: &str) -> Result<Option<SkelAnimQuery>> {
    let a = Animation::get(&r.stage, path)
        .map_err(|e| Error::attr(axis, "source", format!("cannot read {path}: {e}")))?
        .ok_or_else(|| Error::attr(axis, "source", format!("{path} is not a SkelAnimation")))?;
    SkelAnimQuery::new(a).map_err(|e| Error::attr(axis, "source", format!("cannot read {path}: {e}")))
}

/// Rotation of a (possibly scaled) joint-local matrix.
fn rotation_of(m: &DMat4) -> DQuat {
    // A mirroring matrix splits as UsdSkelDecomposeTransform (GfMatrix4d's
    // Factor) splits it, the split an animation holding the joint at rest
    // stores: all three scales negative, so the rotation is that of -M.
    let m3 = glam::DMat3::from_mat4(*m);
    let m3 = if m3.determinant() < 0.0 { -m3 } else { m3 };
    let (_, r, _) = DMat4::from_mat3(m3).to_scale_rotation_translation();
    r.normalize()
}

/// Axis × angle (radians) of a rotation, taking the shorter way round.
pub fn rotation_vector(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s <= 1e-300 {
        return DVec3::ZERO;
    }
    let angle = 2.0 * s.atan2(q.w);
    v / s * angle
}

/// Picks a scalar out of a value: scalars as is, arrays by `element`,
/// vectors and quaternions (x, y, z, w) by `component`.
/// Why [`pick`] failed: the axis attribute at fault and a message.
type PickError = (&'static str, String);

fn pick(v: &Value, element: i64, component: i64) -> std::result::Result<f64, PickError> {
    if let Some(x) = values::scalar(v) {
        // A pick on a scalar means the axis names the wrong attribute.
        return match (element, component) {
            (0, 0) => Ok(x),
            (0, c) => Err((
                "component",
                format!("component {c} picks from a scalar, which has none"),
            )),
            (e, _) => Err(("element", format!("element {e} picks from a scalar, which is no array"))),
        };
    }
    let comp = |c: &[f64]| -> std::result::Result<f64, PickError> {
        usize::try_from(component)
            .ok()
            .and_then(|i| c.get(i).copied())
            .ok_or_else(|| {
                (
                    "component",
                    format!(
                        "component {component} is out of range: the value has components 0..={}",
                        c.len() - 1
                    ),
                )
            })
    };
    let elem = |n: usize| -> std::result::Result<usize, PickError> {
        usize::try_from(element).ok().filter(|&e| e < n).ok_or_else(|| {
            (
                "element",
                format!("element {element} is out of range: the array has {n} elements"),
            )
        })
    };
    macro_rules! vecs {
        ($a:expr, $f:expr) => {{
            let e = elem($a.len())?;
            comp(&$f(&$a[e]))
        }};
    }
    match v {
        Value::Vec2f(p) => comp(&[p.x as f64, p.y as f64]),
        Value::Vec2d(p) => comp(&[p.x, p.y]),
        Value::Vec3f(p) => comp(&[p.x as f64, p.y as f64, p.z as f64]),
        Value::Vec3d(p) => comp(&[p.x, p.y, p.z]),
        Value::Vec3h(p) => comp(&[p.x.to_f64(), p.y.to_f64(), p.z.to_f64()]),
        Value::Vec4f(p) => comp(&[p.x as f64, p.y as f64, p.z as f64, p.w as f64]),
        Value::Vec4d(p) => comp(&[p.x, p.y, p.z, p.w]),
        Value::Quatf(q) => comp(&[q.x as f64, q.y as f64, q.z as f64, q.w as f64]),
        Value::Quatd(q) => comp(&[q.x, q.y, q.z, q.w]),
        Value::Quath(q) => comp(&[q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64()]),
        Value::FloatVec(a) => Ok(a[elem(a.len())?] as f64),
        Value::DoubleVec(a) => Ok(a[elem(a.len())?]),
        Value::HalfVec(a) => Ok(a[elem(a.len())?].to_f64()),
        Value::IntVec(a) => Ok(a[elem(a.len())?] as f64),
        Value::Vec3fVec(a) => vecs!(a, |p: &openusd::gf::Vec3f| [p.x as f64, p.y as f64, p.z as f64]),
        Value::Vec3dVec(a) => vecs!(a, |p: &openusd::gf::Vec3d| [p.x, p.y, p.z]),
        Value::Vec2fVec(a) => vecs!(a, |p: &openusd::gf::Vec2f| [p.x as f64, p.y as f64]),
        Value::QuatfVec(a) => vecs!(a, |q: &openusd::gf::Quatf| [
            q.x as f64, q.y as f64, q.z as f64, q.w as f64
        ]),
        Value::QuatdVec(a) => vecs!(a, |q: &openusd::gf::Quatd| [q.x, q.y, q.z, q.w]),
        other => Err((
            "source",
            format!("cannot take a coordinate from a {} value", values::kind_name(other)),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_reads_read_each_animation_once() {
        let q = |x: f32| vec![openusd::gf::quatf(1.0, x, 0.0, 0.0)];
        let mut reads = FrameReads::default();
        let mut calls = 0;
        for (anim, x) in [("/A", 0.1), ("/B", 0.2), ("/A", 0.9), ("/B", 0.9)] {
            let got = reads
                .joint_rotations(anim, || {
                    calls += 1;
                    Ok(q(x))
                })
                .unwrap();
            // The first read of each animation is the one kept.
            assert_eq!(got, q(if anim == "/A" { 0.1 } else { 0.2 }).as_slice());
        }
        assert_eq!(calls, 2);
        let mut fresh = FrameReads::default();
        assert!(fresh.joint_rotations("/A", || Err(Error::msg("unreadable"))).is_err());
        // A failed read is not kept.
        assert_eq!(fresh.joint_rotations("/A", || Ok(q(0.3))).unwrap(), q(0.3).as_slice());
    }

    #[test]
    fn rotation_vector_is_axis_times_angle_the_short_way() {
        let q = DQuat::from_axis_angle(DVec3::Z, 0.7);
        assert!((rotation_vector(q) - DVec3::new(0.0, 0.0, 0.7)).length() < 1e-12);
        // -q is the same rotation.
        assert!((rotation_vector(-q) - DVec3::new(0.0, 0.0, 0.7)).length() < 1e-12);
        let q = DQuat::from_axis_angle(DVec3::X, -2.5);
        assert!((rotation_vector(q) - DVec3::new(-2.5, 0.0, 0.0)).length() < 1e-12);
        assert_eq!(rotation_vector(DQuat::IDENTITY), DVec3::ZERO);
    }

    #[test]
    fn pick_reads_scalars_elements_and_components() {
        use openusd::gf;
        assert_eq!(pick(&Value::Float(0.5), 0, 0).unwrap(), 0.5);
        assert_eq!(pick(&Value::Float(0.5), 0, 2).unwrap_err().0, "component");
        assert_eq!(pick(&Value::Double(0.5), -1, 0).unwrap_err().0, "element");
        assert_eq!(pick(&Value::Bool(true), 5, 3).unwrap_err().0, "element");
        assert_eq!(pick(&Value::DoubleVec(vec![1.0, 2.0]), 1, 0).unwrap(), 2.0);
        let q = Value::Quatf(gf::Quatf {
            w: 0.1,
            x: 0.2,
            y: 0.3,
            z: 0.4,
        });
        // Quaternions as x, y, z, w: imaginary then real.
        assert!((pick(&q, 0, 3).unwrap() - 0.1).abs() < 1e-7);
        assert!((pick(&q, 0, 0).unwrap() - 0.2).abs() < 1e-7);
        assert_eq!(pick(&Value::DoubleVec(vec![1.0]), 2, 0).unwrap_err().0, "element");
        assert_eq!(
            pick(&Value::Vec3f(gf::vec3f(1.0, 2.0, 3.0)), 0, 3).unwrap_err().0,
            "component"
        );
        let v = Value::Vec3fVec(vec![gf::vec3f(1.0, 2.0, 3.0), gf::vec3f(4.0, 5.0, 6.0)]);
        assert_eq!(pick(&v, 1, 2).unwrap(), 6.0);
    }

    #[test]
    fn pick_element_equal_to_length_is_out_of_range() {
        use openusd::gf;
        // The last valid element is len - 1; len itself is an error, not a panic.
        assert_eq!(pick(&Value::DoubleVec(vec![1.0, 2.0]), 2, 0).unwrap_err().0, "element");
        let v = Value::Vec3fVec(vec![gf::vec3f(1.0, 2.0, 3.0)]);
        assert_eq!(pick(&v, 1, 0).unwrap_err().0, "element");
    }

    #[test]
    fn rotation_vector_of_a_half_turn_with_zero_w_keeps_its_axis() {
        // w = 0 is already the short way (w >= 0): a half turn about +Y is
        // (0, pi, 0), not the flipped (0, -pi, 0).
        let v = rotation_vector(DQuat::from_xyzw(0.0, 1.0, 0.0, 0.0));
        assert!((v - DVec3::new(0.0, std::f64::consts::PI, 0.0)).length() < 1e-12, "{v}");
    }

    /// The rest rotation of joint "a" of /Skel, read through a jointRotation
    /// axis, with `rest` as the Skeleton's restTransforms.
    fn rest_of_joint_a(rest: &str) -> DQuat {
        let r = crate::usd_io::testutil::stage_from_usda(&format!(
            r#"#usda 1.0
def Skeleton "Skel"
{{
    uniform token[] joints = ["a", "b"]
    uniform matrix4d[] restTransforms = {rest}
}}
def PainterlyAxis "Ax"
{{
    token kind = "jointRotation"
    token name = "a"
    rel source = </Skel>
}}
"#
        ));
        match Axis::read(&r, "/Ax").unwrap().source {
            AxisSource::JointRotation { rest, anim, index } => {
                assert!(anim.is_none() && index.is_none());
                rest
            }
            _ => panic!("not a jointRotation source"),
        }
    }

    #[test]
    fn joint_rest_rotation_needs_one_rest_transform_per_joint() {
        // +90 degrees about X in USD's row-vector convention.
        let x90 = "((1, 0, 0, 0), (0, 0, 1, 0), (0, -1, 0, 0), (0, 0, 0, 1))";
        let id = "((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))";
        let want = DQuat::from_axis_angle(DVec3::X, std::f64::consts::FRAC_PI_2);
        let got = rest_of_joint_a(&format!("[{x90}, {id}]"));
        assert!(got.dot(want).abs() > 1.0 - 1e-12, "{got}");
        // One transform for two joints: not a rest pose, so the identity.
        assert_eq!(rest_of_joint_a(&format!("[{x90}]")), DQuat::IDENTITY);
    }
}
