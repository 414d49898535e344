//! Posing a skeleton at a time for joint skinning: bind and rest
//! transforms, the animation's joint transforms (ignored, as usd-core does,
//! at times where its arrays do not fit its joints) and the mesh's own joint
//! order.

use glam::DMat4;
use openusd::gf;
use openusd::sdf::Value;
use openusd::usd;

use super::inherited_attr;
use super::mapper::OrderMap;
use super::topology::{duplicates, quoted};
use crate::error::{Error, Result};
use crate::skel_deform::local_to_skel;
use crate::usd_io::stage::{HeldQuery, StageReader};
use crate::usd_io::values;

/// How the skeleton is posed at a time, for a mesh skinned by joints.
pub(super) struct JointPose {
    skeleton: String,
    parents: Vec<Option<usize>>,
    /// `restTransforms`, when authored with one matrix per joint.
    rest: Option<Vec<DMat4>>,
    inverse_bind: Vec<DMat4>,
    /// The animation's joint transforms and where they land in the skeleton,
    /// when it drives any joint.
    anim: Option<(AnimJoints, OrderMap)>,
    /// Skeleton joints → mesh joints (`skel:joints`); None = skeleton order.
    pub(super) mesh_map: Option<OrderMap>,
}

/// The joint-transform arrays of a SkelAnimation.
pub(super) struct AnimJoints {
    path: String,
    joints: usize,
    translations: HeldQuery,
    rotations: HeldQuery,
    scales: HeldQuery,
}

const TRS: [&str; 3] = ["translations", "rotations", "scales"];

impl AnimJoints {
    /// Joint-local transforms at `t`, or why usd-core ignores the animation
    /// there (the attribute and the reason): an array missing, of another
    /// type, or not one entry per joint.
    fn local(&self, t: f64) -> Result<std::result::Result<Vec<DMat4>, (&'static str, String)>> {
        let get = |q: &HeldQuery, name: &str| -> Result<Option<Value>> {
            q.get_at(t)
                .map_err(|e| Error::attr(&self.path, name, format!("cannot read at time {t}: {e}")))
        };
        // Between two quatf[] samples the rotations are GfSlerp's, read
        // from the samples; openusd's interpolation is not asked for too.
        let rotations = match self.rotations_between_samples(t)? {
            Some(q) => Some(Value::QuatfVec(q)),
            None => get(&self.rotations, TRS[1])?,
        };
        let raw = [get(&self.translations, TRS[0])?, rotations, get(&self.scales, TRS[2])?];
        let n = self.joints;
        let [Some(tr), Some(rot), Some(mut sc)] = raw else {
            let i = raw.iter().position(|v| v.is_none()).unwrap_or(0);
            return Ok(Err((TRS[i], format!("{} is not authored", TRS[i]))));
        };
        if let Some(h) = self.half_scales_between_samples(t)? {
            sc = Value::Vec3hVec(h);
        }
        let kinds = [values::kind_name(&tr), values::kind_name(&rot), values::kind_name(&sc)];
        let cast = (
            tr.cast::<Vec<gf::Vec3f>>().ok(),
            // Only quatf[]: usd-core's ComputeJointLocalTransforms reads
            // no half or double quaternions, and the skeleton rests.
            match rot {
                Value::QuatfVec(q) => Some(q),
                _ => None,
            },
            sc.cast::<Vec<gf::Vec3f>>().ok(),
        );
        let (Some(tr), Some(rot), Some(sc)) = cast else {
            let ok = [cast.0.is_some(), cast.1.is_some(), cast.2.is_some()];
            let i = ok.iter().position(|ok| !ok).unwrap_or(0);
            let expected = ["float3[]", "quatf[]", "half3[]"][i];
            return Ok(Err((
                TRS[i],
                format!("{} is {}, expected {expected}", TRS[i], kinds[i]),
            )));
        };
        let lens = [tr.len(), rot.len(), sc.len()];
        if let Some(i) = lens.iter().position(|&l| l != n) {
            return Ok(Err((
                TRS[i],
                format!("{} has {} values for {n} joints", TRS[i], lens[i]),
            )));
        }
        Ok(Ok(tr
            .iter()
            .zip(&rot)
            .zip(&sc)
            .map(|((t, r), s)| values::usd_matrix(&gf::Matrix4d::from_trs(*t, *r, *s)))
            .collect()))
    }
}

impl AnimJoints {
    /// The first animation value at `t` that is not finite, as an error
    /// naming its attribute and joint: what made posed points not finite,
    /// which would otherwise be blamed on the mesh's `points`.
    fn non_finite_at(&self, t: f64) -> Result<Option<Error>> {
        let finite = |c: &[f32]| c.iter().all(|c| c.is_finite());
        for (i, q) in [&self.translations, &self.rotations, &self.scales]
            .into_iter()
            .enumerate()
        {
            let value = q
                .get_at(t)
                .map_err(|e| Error::attr(&self.path, TRS[i], format!("cannot read at time {t}: {e}")))?;
            let bad = match value {
                Some(Value::QuatfVec(v)) => v.iter().position(|q| !finite(&[q.w, q.x, q.y, q.z])),
                Some(v) => v
                    .cast::<Vec<gf::Vec3f>>()
                    .ok()
                    .and_then(|v| v.iter().position(|v| !finite(&[v.x, v.y, v.z]))),
                None => None,
            };
            if let Some(j) = bad {
                return Ok(Some(
                    Error::attr(
                        &self.path,
                        TRS[i],
                        format!("joint {j}'s value is not finite at time {t}"),
                    )
                    .rule(crate::rule::Rule::NonFinite),
                ));
            }
        }
        Ok(None)
    }

    /// The samples of `q` (the animation's `name`) on either side of `t`,
    /// strictly between them, and `t`'s fraction of the way: what usd-core
    /// interpolates there. None at or outside the sample times, or where a
    /// side has no value.
    fn samples_around(&self, q: &HeldQuery, name: &str, t: f64) -> Result<Option<(Value, Value, f64)>> {
        let times = q
            .times()
            .map_err(|e| Error::attr(&self.path, name, format!("cannot read time samples: {e}")))?;
        // A binary search: a scan made a check at every sample cost the
        // square of the samples (a shot sampled every frame).
        let j = times.partition_point(|&x| x <= t);
        if j == 0 || j == times.len() || times[j - 1] >= t {
            return Ok(None);
        }
        let i = j - 1;
        let (t0, t1) = (times[i], times[i + 1]);
        let sample = |at: f64| {
            q.get_at(at)
                .map_err(|e| Error::attr(&self.path, name, format!("cannot read at time {at}: {e}")))
        };
        Ok(match (sample(t0)?, sample(t1)?) {
            (Some(a), Some(b)) => Some((a, b, (t - t0) / (t1 - t0))),
            _ => None,
        })
    }

    /// `quatf[]` rotations between two samples as usd-core interpolates them
    /// (GfSlerp: the shorter way round, a plain lerp when 1 − cos θ ≤ 1e-5,
    /// never normalised). openusd normalises a nearly
    /// parallel pair, which moves a quaternion not of unit length (as
    /// exporters write them) by up to its excess length. None where that
    /// does not apply.
    fn rotations_between_samples(&self, t: f64) -> Result<Option<Vec<gf::Quatf>>> {
        let Some((Value::QuatfVec(a), Value::QuatfVec(b), alpha)) = self.samples_around(&self.rotations, TRS[1], t)?
        else {
            return Ok(None);
        };
        if a.len() != b.len() {
            return Ok(None);
        }
        Ok(Some(a.iter().zip(&b).map(|(a, b)| gf_slerp(alpha, a, b)).collect()))
    }

    /// `half3[]` scales between two samples as usd-core interpolates them:
    /// `(1 − α)·a + α·b` in GfVec3h arithmetic, each product and the sum
    /// rounded to half (openusd rounds once; they differ by up to ~1e-4 of
    /// the character). None where that does not apply.
    fn half_scales_between_samples(&self, t: f64) -> Result<Option<Vec<gf::Vec3h>>> {
        let Some((Value::Vec3hVec(a), Value::Vec3hVec(b), alpha)) = self.samples_around(&self.scales, TRS[2], t)?
        else {
            return Ok(None);
        };
        if a.len() != b.len() {
            return Ok(None);
        }
        let half = |x: f64| gf::f16::from_f32(x as f32);
        let lerp = |a: gf::f16, b: gf::f16| {
            let (pa, pb) = (half(a.to_f64() * (1.0 - alpha)), half(b.to_f64() * alpha));
            gf::f16::from_f32(pa.to_f32() + pb.to_f32())
        };
        Ok(Some(
            a.iter()
                .zip(&b)
                .map(|(a, b)| gf::Vec3h {
                    x: lerp(a.x, b.x),
                    y: lerp(a.y, b.y),
                    z: lerp(a.z, b.z),
                })
                .collect(),
        ))
    }
}

/// GfSlerp of two `GfQuatf`s: the shorter way round, and a plain lerp,
/// never normalised, once 1 − cos θ ≤ 1e-5 (usd-core's rule). The
/// arithmetic is openusd's (f64, rounded to f32 at the end), which matched
/// usd-core on unit quaternions, where dual-quaternion skinning's sign
/// choice can turn on the last bit; only its normalised lerp above
/// cos θ = 0.9995 departed from usd-core (see
/// [`AnimJoints::rotations_between_samples`]).
fn gf_slerp(alpha: f64, a: &gf::Quatf, b: &gf::Quatf) -> gf::Quatf {
    let a = [a.w as f64, a.x as f64, a.y as f64, a.z as f64];
    let b = [b.w as f64, b.x as f64, b.y as f64, b.z as f64];
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    let sign = if dot < 0.0 { -1.0 } else { 1.0 };
    let cos = dot.abs();
    let (s_a, s_b) = if 1.0 - cos > 1e-5 {
        let theta = cos.acos();
        let sin = theta.sin();
        (((1.0 - alpha) * theta).sin() / sin, (alpha * theta).sin() / sin * sign)
    } else {
        (1.0 - alpha, alpha * sign)
    };
    let q = |i: usize| (a[i] * s_a + b[i] * s_b) as f32;
    gf::Quatf {
        w: q(0),
        x: q(1),
        y: q(2),
        z: q(3),
    }
}

impl JointPose {
    /// Why skinning at `t` gives points that are not finite, when the cause
    /// is an animation value (see [`AnimJoints::non_finite_at`]).
    pub(super) fn non_finite_input(&self, t: f64) -> Result<Option<Error>> {
        match &self.anim {
            Some((anim, _)) => anim.non_finite_at(t),
            None => Ok(None),
        }
    }

    /// Skinning transforms in mesh joint order (column form: inverse bind,
    /// then the posed joint in skeleton space).
    pub(super) fn skinning(&self, t: f64) -> Result<Vec<DMat4>> {
        let rest = || {
            self.rest.clone().ok_or_else(|| {
                Error::attr(
                    &self.skeleton,
                    "restTransforms",
                    format!("needed at time {t} but not usable"),
                )
            })
        };
        let local = match &self.anim {
            Some((anim, map)) => match anim.local(t)? {
                Ok(xf) => {
                    let mut local = if map.sparse { rest()? } else { Vec::new() };
                    map.remap(&xf, &mut local, DMat4::IDENTITY);
                    local
                }
                Err(_) => rest()?,
            },
            None => rest()?,
        };
        let skel = local_to_skel(&local, &self.parents);
        let skinning: Vec<DMat4> = skel.iter().zip(&self.inverse_bind).map(|(s, ib)| *s * *ib).collect();
        Ok(match &self.mesh_map {
            None => skinning,
            Some(map) => {
                let mut out = Vec::new();
                map.remap(&skinning, &mut out, DMat4::IDENTITY);
                out
            }
        })
    }
}

/// Bind and rest transforms, the animation's joint transforms and the mesh's
/// joint order, checked as usd-core needs them for joint skinning.
#[allow(clippy::too_many_arguments)]
pub(super) fn read_joint_pose(
    r: &StageReader,
    skel_prim: &usd::Prim,
    skeleton: &str,
    joints: &[String],
    parents: Vec<Option<usize>>,
    anim: Option<(&usd::Prim, &Vec<String>, OrderMap)>,
    mesh: &usd::Prim,
    notes: &mut Vec<String>,
) -> Result<JointPose> {
    let nj = joints.len();
    let inverse_bind = inverse_bind_transforms(r, skel_prim, skeleton, joints, notes)?;
    let rest_all = matrices(r, skel_prim, skeleton, "restTransforms")?;
    let rest_len = rest_all.as_ref().map_or(0, |m| m.len());
    let rest = rest_all.filter(|m| m.len() == nj);
    let anim = match anim {
        None => {
            if rest.is_none() {
                return Err(Error::attr(
                    skeleton,
                    "restTransforms",
                    format!(
                        "{rest_len} matrices for {nj} joints, and no animation drives the joints: usd-core cannot pose {skeleton}"
                    ),
                ));
            }
            None
        }
        Some((prim, anim_joints, map)) => {
            let skel = SkelRest {
                skeleton,
                joints,
                has_rest: rest.is_some(),
                rest_len,
            };
            Some(check_animation(r, &skel, prim, anim_joints, map, notes)?)
        }
    };
    let mesh_map = mesh_joint_order(r, mesh, skeleton, joints, notes)?;
    Ok(JointPose {
        skeleton: skeleton.to_string(),
        parents,
        rest,
        inverse_bind,
        anim,
        mesh_map,
    })
}

/// A `matrix4d[]` attribute of the skeleton, when authored.
fn matrices(r: &StageReader, skel_prim: &usd::Prim, skeleton: &str, name: &str) -> Result<Option<Vec<DMat4>>> {
    match r.value(skel_prim, name, None)? {
        None => Ok(None),
        Some(Value::Matrix4dVec(m)) => Ok(Some(m.iter().map(values::usd_matrix).collect())),
        Some(v) => Err(Error::attr(
            skeleton,
            name,
            format!("expected matrix4d[], found {}", values::kind_name(&v)),
        )),
    }
}

/// The inverses of `bindTransforms`, one per joint.
fn inverse_bind_transforms(
    r: &StageReader,
    skel_prim: &usd::Prim,
    skeleton: &str,
    joints: &[String],
    notes: &mut Vec<String>,
) -> Result<Vec<DMat4>> {
    let nj = joints.len();
    let bind = matrices(r, skel_prim, skeleton, "bindTransforms")?.unwrap_or_default();
    if bind.len() != nj {
        return Err(Error::attr(
            skeleton,
            "bindTransforms",
            format!(
                "{} matrices for {nj} joints: usd-core cannot skin without one bind transform per joint",
                bind.len()
            ),
        ));
    }
    // A singular bind transform has no inverse. usd-core's GfMatrix4d
    // inverse is then a scale by FLT_MAX, which throws the joint's points to
    // infinity; painterly takes the identity instead, and says so.
    let mut singular = Vec::new();
    let inverse_bind: Vec<DMat4> = bind
        .iter()
        .zip(joints)
        .map(|(m, joint)| {
            if m.determinant().abs() > 0.0 {
                m.inverse()
            } else {
                singular.push(joint.as_str());
                DMat4::IDENTITY
            }
        })
        .collect();
    if !singular.is_empty() {
        notes.push(format!(
            "{skeleton}.bindTransforms of {} cannot be inverted: usd-core would scale the points they move by FLT_MAX; painterly leaves them unscaled",
            quoted(&singular)
        ));
    }
    Ok(inverse_bind)
}

/// What the animation checks need of the skeleton.
struct SkelRest<'a> {
    skeleton: &'a str,
    joints: &'a [String],
    /// `restTransforms` holds one matrix per joint.
    has_rest: bool,
    /// How many `restTransforms` are authored.
    rest_len: usize,
}

/// Why the rest pose cannot stand in for the animation.
fn rest_problem(rest_len: usize, nj: usize) -> String {
    if rest_len == 0 {
        "has no restTransforms".to_string()
    } else {
        format!("has {rest_len} restTransforms for {nj} joints")
    }
}

/// The animation, where it drives any joint: at every authored time its
/// arrays must fit its joints, or usd-core falls back on the rest pose.
fn check_animation(
    r: &StageReader,
    skel: &SkelRest,
    prim: &usd::Prim,
    anim_joints: &[String],
    map: OrderMap,
    notes: &mut Vec<String>,
) -> Result<(AnimJoints, OrderMap)> {
    let SkelRest {
        skeleton,
        joints,
        has_rest,
        rest_len,
    } = *skel;
    let nj = joints.len();
    let path = prim.path().as_str().to_string();
    let aj = AnimJoints {
        path: path.clone(),
        joints: anim_joints.len(),
        translations: HeldQuery::new(prim, "translations")?,
        rotations: HeldQuery::new(prim, "rotations")?,
        scales: HeldQuery::new(prim, "scales")?,
    };
    if map.sparse && !has_rest {
        let driven = map.sources(anim_joints.len()).iter().filter(|s| s.is_some()).count();
        return Err(Error::attr(
            skeleton,
            "restTransforms",
            format!(
                "{path} drives {driven} of the {nj} joints, so the others need the rest pose, but {skeleton} {}",
                rest_problem(rest_len, nj)
            ),
        ));
    }
    let unknown: Vec<&str> = anim_joints
        .iter()
        .filter(|n| !joints.contains(n))
        .map(|s| s.as_str())
        .collect();
    if !unknown.is_empty() {
        notes.push(format!(
            "{path} animates {}, not joints of {skeleton}: ignored",
            quoted(&unknown)
        ));
    }
    let mut times: Vec<f64> = Vec::new();
    for name in TRS {
        times.extend(r.sample_times(prim, name)?);
    }
    times.sort_by(f64::total_cmp);
    times.dedup();
    if times.is_empty() {
        times.push(0.0);
    }
    let mut bad: Vec<(f64, &str, String)> = Vec::new();
    for &t in &times {
        if let Err((attr, why)) = aj.local(t)? {
            bad.push((t, attr, why));
        }
    }
    if let Some((t, attr, why)) = bad.first() {
        let when = if times.len() == 1 {
            String::new()
        } else if bad.len() == times.len() {
            " at every time".to_string()
        } else if bad.len() == 1 {
            format!(" at time {t}")
        } else {
            let more: Vec<String> = bad[1..].iter().map(|(t, _, _)| t.to_string()).collect();
            format!(" at time {t} (and at {})", more.join(", "))
        };
        if !has_rest {
            return Err(Error::attr(
                &path,
                attr,
                format!(
                    "{why}{when}: usd-core then poses {skeleton} at rest, but it {}",
                    rest_problem(rest_len, nj)
                ),
            ));
        }
        notes.push(format!(
            "{path}: {why}{when}: usd-core ignores the animation there and poses {skeleton} at rest"
        ));
    }
    if !has_rest && rest_len > 0 {
        notes.push(format!(
            "{skeleton} {}: unused, the animation drives every joint",
            rest_problem(rest_len, nj)
        ));
    }
    Ok((aj, map))
}

/// The mesh's own joint order (`skel:joints`), when it has one.
fn mesh_joint_order(
    r: &StageReader,
    mesh: &usd::Prim,
    skeleton: &str,
    joints: &[String],
    notes: &mut Vec<String>,
) -> Result<Option<OrderMap>> {
    let mesh_joints = match inherited_attr(r, mesh, "skel:joints")? {
        Some(p) => {
            let mj = r.typed(&p, "skel:joints", None, "token[]", values::token_array)?;
            if mj.as_ref().is_some_and(|m| m.is_empty()) {
                return Err(Error::attr(
                    p.path(),
                    "skel:joints",
                    "is empty: no joint index can name a joint (usd-core does not skin the mesh)",
                ));
            }
            mj
        }
        None => None,
    };
    let Some(mj) = mesh_joints else {
        return Ok(None);
    };
    let unknown: Vec<&str> = mj.iter().filter(|n| !joints.contains(n)).map(|s| s.as_str()).collect();
    if !unknown.is_empty() {
        notes.push(format!(
            "{}.skel:joints names {}, not joints of {skeleton}: usd-core gives them the identity transform",
            mesh.path(),
            quoted(&unknown)
        ));
    }
    let dups = duplicates(&mj);
    if !dups.is_empty() {
        notes.push(format!(
            "{}.skel:joints lists {} more than once: only the last of them follows the joint, as in usd-core",
            mesh.path(),
            quoted(&dups)
        ));
    }
    Ok(Some(OrderMap::new(joints, &mj)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::skel::joint_parents;
    use crate::usd_io::testutil::stage_from_usda;

    const ID: &str = "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )";
    const UP: &str = "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 1, 0, 1) )";
    const TR: &str = "float3[] translations = [(0, 0, 0), (0, 1, 0)]";
    const ROT: &str = "quatf[] rotations = [(1, 0, 0, 0), (1, 0, 0, 0)]";
    const SC: &str = "half3[] scales = [(1, 1, 1), (1, 1, 1)]";

    /// Skeleton `/R/Skel` (joints a, a/b) with `skel` extra lines, and its
    /// animation `/R/Skel/Anim` over `anim_joints` with the `anim` lines.
    fn stage(skel: &str, anim_joints: &str, anim: &str) -> StageReader {
        stage_from_usda(&format!(
            r#"#usda 1.0
def SkelRoot "R"
{{
    def Skeleton "Skel"
    {{
        uniform token[] joints = ["a", "a/b"]
        uniform matrix4d[] bindTransforms = [{ID}, {UP}]
        {skel}
        def SkelAnimation "Anim"
        {{
            uniform token[] joints = {anim_joints}
            {anim}
        }}
    }}
    def Mesh "M"
    {{
    }}
}}
"#
        ))
    }

    /// read_joint_pose of /R/M bound to /R/Skel, animated by /R/Skel/Anim.
    fn read(r: &StageReader) -> (Result<JointPose>, Vec<String>) {
        let skel = r.prim("/R/Skel").unwrap().unwrap();
        let anim = r.prim("/R/Skel/Anim").unwrap().unwrap();
        let mesh = r.prim("/R/M").unwrap().unwrap();
        let joints: Vec<String> = r
            .typed(&skel, "joints", None, "token[]", values::token_array)
            .unwrap()
            .unwrap();
        let anim_joints: Vec<String> = r
            .typed(&anim, "joints", None, "token[]", values::token_array)
            .unwrap()
            .unwrap();
        let map = OrderMap::new(&anim_joints, &joints);
        let mut notes = Vec::new();
        let pose = read_joint_pose(
            r,
            &skel,
            "/R/Skel",
            &joints,
            joint_parents(&joints),
            Some((&anim, &anim_joints, map)),
            &mesh,
            &mut notes,
        );
        (pose, notes)
    }

    fn anim_joints(r: &StageReader) -> AnimJoints {
        let prim = r.prim("/R/Skel/Anim").unwrap().unwrap();
        AnimJoints {
            path: "/R/Skel/Anim".into(),
            joints: 2,
            translations: HeldQuery::new(&prim, "translations").unwrap(),
            rotations: HeldQuery::new(&prim, "rotations").unwrap(),
            scales: HeldQuery::new(&prim, "scales").unwrap(),
        }
    }

    #[test]
    fn half_scales_between_samples_round_as_usd_core() {
        // Expected values: usd-core 25's Get(t) of the same half3[] samples
        // (pxr Usd attribute interpolation); rounding once, as openusd does,
        // differs in at least one component at each time.
        let r = stage(
            "",
            r#"["a", "a/b"]"#,
            &format!(
                "{TR}\n{ROT}\nhalf3[] scales.timeSamples = {{
                1: [(1.0009765625, 3, 0.7), (2.5, -1.25, 1)],
                3: [(3, 0.1, 1.3), (0.5, 2, 1)],
                6: [(1.5, 7, -0.3), (1, 1, 1)],
            }}"
            ),
        );
        let aj = anim_joints(&r);
        let f = |h: &[gf::Vec3h]| -> Vec<[f64; 3]> {
            h.iter().map(|v| [v.x.to_f64(), v.y.to_f64(), v.z.to_f64()]).collect()
        };
        let at = |t: f64| f(&aj.half_scales_between_samples(t).unwrap().unwrap());
        assert_eq!(
            at(2.2),
            [
                [2.19921875, 1.259765625, 1.0595703125],
                [1.2998046875, 0.7001953125, 1.0]
            ]
        );
        assert_eq!(
            at(4.1),
            [[2.44921875, 2.62890625, 0.71337890625], [0.68359375, 1.6328125, 1.0]]
        );
        // At, before and after the samples usd-core holds a sample: no interpolation.
        for t in [0.5, 1.0, 3.0, 6.0, 7.0] {
            assert!(aj.half_scales_between_samples(t).unwrap().is_none(), "t={t}");
        }
    }

    #[test]
    fn sparse_animation_error_says_how_rest_transforms_fail() {
        // "a/b" alone is animated: "a" needs its rest transform.
        let anim =
            "float3[] translations = [(0, 1, 0)]\nquatf[] rotations = [(1, 0, 0, 0)]\nhalf3[] scales = [(1, 1, 1)]";
        let err = |skel: &str| read(&stage(skel, r#"["a/b"]"#, anim)).0.err().unwrap().to_string();
        let none = err("");
        assert!(none.ends_with("but /R/Skel has no restTransforms"), "{none}");
        let one = err(&format!("uniform matrix4d[] restTransforms = [{ID}]"));
        assert!(one.ends_with("but /R/Skel has 1 restTransforms for 2 joints"), "{one}");
    }

    #[test]
    fn notes_name_every_time_the_animation_is_ignored() {
        let rest = format!("uniform matrix4d[] restTransforms = [{ID}, {UP}]");
        let rot = |bad: &[u32]| {
            let s: Vec<String> = [1, 3, 6]
                .iter()
                .map(|t| {
                    let q = if bad.contains(t) {
                        "(1, 0, 0, 0)"
                    } else {
                        "(1, 0, 0, 0), (1, 0, 0, 0)"
                    };
                    format!("{t}: [{q}],")
                })
                .collect();
            format!("{TR}\n{SC}\nquatf[] rotations.timeSamples = {{ {} }}", s.join(" "))
        };
        let notes = |bad: &[u32]| read(&stage(&rest, r#"["a", "a/b"]"#, &rot(bad))).1;
        let tail = ": usd-core ignores the animation there and poses /R/Skel at rest";
        assert_eq!(
            notes(&[3]),
            [format!(
                "/R/Skel/Anim: rotations has 1 values for 2 joints at time 3{tail}"
            )]
        );
        assert_eq!(
            notes(&[1, 6]),
            [format!(
                "/R/Skel/Anim: rotations has 1 values for 2 joints at time 1 (and at 6){tail}"
            )]
        );
    }

    #[test]
    fn full_animation_without_rest_transforms_has_no_note() {
        // Nothing needs a rest pose and none is authored: nothing to say.
        let (pose, notes) = read(&stage("", r#"["a", "a/b"]"#, &format!("{TR}\n{ROT}\n{SC}")));
        assert!(pose.is_ok());
        assert!(notes.is_empty(), "{notes:?}");
    }

    #[test]
    fn a_singular_bind_transform_is_left_out_with_a_note() {
        // usd-core (GfMatrix4d::GetInverse) would give a/b's skinning
        // transform diag(FLT_MAX) with translation (0, 2, 0); painterly
        // takes the identity for the inverse and notes it, so a/b skins by
        // its rest transform alone: a translation by (0, 2, 0).
        let r = stage_from_usda(&format!(
            r#"#usda 1.0
def SkelRoot "R"
{{
    def Skeleton "Skel"
    {{
        uniform token[] joints = ["a", "a/b"]
        uniform matrix4d[] bindTransforms = [{ID}, ( (1, 0, 0, 0), (0, 0, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )]
        uniform matrix4d[] restTransforms = [{ID}, ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 2, 0, 1) )]
    }}
    def Mesh "M"
    {{
    }}
}}
"#
        ));
        let skel = r.prim("/R/Skel").unwrap().unwrap();
        let mesh = r.prim("/R/M").unwrap().unwrap();
        let joints = vec!["a".to_string(), "a/b".to_string()];
        let mut notes = Vec::new();
        let pose = read_joint_pose(
            &r,
            &skel,
            "/R/Skel",
            &joints,
            joint_parents(&joints),
            None,
            &mesh,
            &mut notes,
        );
        let s = pose.unwrap().skinning(0.0).unwrap();
        assert_eq!(s[0], DMat4::IDENTITY);
        assert_eq!(s[1], DMat4::from_translation(glam::DVec3::new(0.0, 2.0, 0.0)));
        assert_eq!(
            notes,
            ["/R/Skel.bindTransforms of \"a/b\" cannot be inverted: usd-core would scale the points they move by FLT_MAX; painterly leaves them unscaled"]
        );
    }
}
