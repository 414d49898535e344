//! Reads a UsdSkel-bound mesh into a [`SkelDeformer`] and poses it per frame.
//!
//! Follows the rules usd-core's `UsdSkel.BakeSkinning` applies (SPEC §2):
//! - the skeleton binding, joint influences, `skel:joints`, the skinning
//!   method and the geomBindTransform may be inherited from ancestors; the
//!   animation source is looked up on the Skeleton first;
//! - joints are parented by path (`a/b/c` → the nearest listed ancestor),
//!   parents must come before children, and names map between arrays as
//!   `UsdSkelAnimMapper` maps them (the last of duplicated names wins);
//! - joints the animation does not drive keep their `restTransforms`; at a
//!   time where the animation's arrays are missing or do not match its
//!   joints, the whole skeleton takes its rest pose;
//! - a mesh without joint influences (or a skeleton without joints, or no
//!   animation and no rest pose) is not skinned: blend shapes alone deform
//!   it, in its own space;
//! - skinned points are in skeleton space and are brought into the mesh's
//!   local space through the Skeleton prim's transform (scene.rs).
//!
//! Where usd-core cannot skin the mesh as authored (invalid topology, bind
//! transforms missing or of the wrong length, a rest pose needed but not
//! authored, bad joint influences) it warns and leaves the mesh, or some
//! frames, unskinned: those are errors here, naming the prim and attribute.
//! Where its rules give a complete but surprising result, the result is
//! matched and a note says what happens (`painterly inspect` shows them).

mod mapper;
mod pose;
mod shapes;
mod topology;

use glam::{DMat4, DVec3};
use openusd::sdf::Value;
use openusd::usd;

use super::stage::StageReader;
use super::values;
use crate::error::{Error, Result};
use crate::skel_deform::{Influences, SkelDeformer, SkinningMethod};
use mapper::OrderMap;
use pose::{read_joint_pose, JointPose};
use shapes::{read_shapes, ShapeWeights};
pub use topology::joint_parents;
use topology::{duplicates, quoted, validate_topology};

/// A skinned proxy: its deformer plus what is needed to pose it at a time.
pub struct SkelProxy {
    /// Path of the bound Skeleton prim.
    pub skeleton: String,
    /// Path of the SkelAnimation, if any.
    pub animation: Option<String>,
    pub deformer: SkelDeformer,
    /// What usd-core does with this binding that its author may not expect
    /// (reported by `painterly inspect`).
    pub notes: Vec<String>,
    /// Joint skinning, when usd-core skins the mesh by joints.
    joints: Option<JointPose>,
    /// Animated blend-shape weights, when usd-core applies blend shapes.
    shapes: Option<ShapeWeights>,
}

/// Nearest authored opinion of a relationship on `prim` or its ancestors.
fn inherited_targets(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<(String, Vec<String>)>> {
    let mut cur = Some(prim.clone());
    while let Some(p) = cur {
        if p.path().as_str() == "/" {
            break;
        }
        let rel = p.relationship(name);
        let authored = rel
            .has_authored_targets()
            .map_err(|e| Error::attr(p.path(), name, format!("cannot read: {e}")))?;
        if authored {
            return Ok(Some((p.path().as_str().to_string(), r.targets(&p, name)?)));
        }
        cur = p.parent();
    }
    Ok(None)
}

/// Nearest prim (self or ancestor) with an authored attribute.
pub(super) fn inherited_attr(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<usd::Prim>> {
    let mut cur = Some(prim.clone());
    while let Some(p) = cur {
        if p.path().as_str() == "/" {
            break;
        }
        if r.has_authored(&p, name)? {
            return Ok(Some(p));
        }
        cur = p.parent();
    }
    Ok(None)
}

/// Whether `mesh` is bound to a skeleton (its own or an inherited `skel:skeleton`).
pub fn skeleton_binding(r: &StageReader, mesh: &usd::Prim) -> Result<Option<String>> {
    Ok(inherited_targets(r, mesh, "skel:skeleton")?.and_then(|(_, t)| t.into_iter().next()))
}

/// A primvar's flat value (indices applied), interpolation and elementSize.
struct Primvar {
    prim: String,
    value: Value,
    interpolation: String,
    element_size: usize,
}

/// Reads an (optionally indexed) primvar's flat value with its interpolation and elementSize.
fn read_primvar(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<Primvar>> {
    let Some(v) = r.value(prim, name, None)? else {
        return Ok(None);
    };
    let interp = r.primvar_interpolation(prim, name, "constant")?;
    let element_size = r
        .attr_metadata(prim, name, "elementSize")?
        .and_then(|v| values::scalar(&v))
        .unwrap_or(1.0);
    if !(1.0..=1e6).contains(&element_size) {
        return Err(Error::attr(
            prim.path(),
            name,
            format!("elementSize {element_size} must be a whole number from 1 to 1000000"),
        ));
    }
    let indices_name = format!("{name}:indices");
    let indices = r.typed(prim, &indices_name, None, "int[]", values::int_array)?;
    // Each index picks a whole tuple of elementSize values.
    let v = match indices {
        None => v,
        Some(idx) => expand_indexed(&v, &idx, element_size as usize)
            .ok_or_else(|| Error::attr(prim.path(), &indices_name, "index out of range"))?,
    };
    Ok(Some(Primvar {
        prim: prim.path().as_str().to_string(),
        value: v,
        interpolation: interp,
        element_size: element_size as usize,
    }))
}

fn expand_indexed(v: &Value, idx: &[i64], n: usize) -> Option<Value> {
    fn pick<T: Copy>(a: &[T], idx: &[i64], n: usize) -> Option<Vec<T>> {
        let mut out = Vec::with_capacity(idx.len() * n);
        for &i in idx {
            let i = usize::try_from(i).ok()?;
            out.extend_from_slice(a.get(i * n..(i + 1) * n)?);
        }
        Some(out)
    }
    Some(match v {
        Value::IntVec(a) => Value::IntVec(pick(a, idx, n)?),
        Value::FloatVec(a) => Value::FloatVec(pick(a, idx, n)?),
        Value::DoubleVec(a) => Value::DoubleVec(pick(a, idx, n)?),
        Value::HalfVec(a) => Value::HalfVec(pick(a, idx, n)?),
        _ => return None,
    })
}

/// Joint influences expanded per point, indices not yet range-checked.
struct RawInfluences {
    per_point: usize,
    joints: Vec<i64>,
    weights: Vec<f64>,
    rigid: bool,
}

/// Joint influences as usd-core validates them: indices and weights (each
/// possibly inherited), the same elementSize and interpolation, constant or
/// vertex, sized for the mesh. None when either primvar is absent (usd-core
/// then does not skin the mesh by joints); the note says which.
fn read_influences(
    r: &StageReader,
    mesh: &usd::Prim,
    npts: usize,
) -> Result<std::result::Result<RawInfluences, String>> {
    const IDX: &str = "primvars:skel:jointIndices";
    const WTS: &str = "primvars:skel:jointWeights";
    let mesh_path = mesh.path().as_str().to_string();
    let (Some(ip), Some(wp)) = (inherited_attr(r, mesh, IDX)?, inherited_attr(r, mesh, WTS)?) else {
        let which = match (inherited_attr(r, mesh, IDX)?, inherited_attr(r, mesh, WTS)?) {
            (None, None) => "no joint influences (primvars:skel:jointIndices)",
            (None, Some(_)) => "primvars:skel:jointWeights but no primvars:skel:jointIndices",
            _ => "primvars:skel:jointIndices but no primvars:skel:jointWeights",
        };
        return Ok(Err(format!("{mesh_path} has {which}")));
    };
    let (Some(idx), Some(wts)) = (read_primvar(r, &ip, IDX)?, read_primvar(r, &wp, WTS)?) else {
        return Ok(Err(format!("{mesh_path} has no values for its joint influences")));
    };
    let joint_idx = values::int_array(&idx.value).ok_or_else(|| {
        Error::attr(
            &idx.prim,
            IDX,
            format!("expected int[], found {}", values::kind_name(&idx.value)),
        )
    })?;
    let weights = values::f32_array(&wts.value).ok_or_else(|| {
        Error::attr(
            &wts.prim,
            WTS,
            format!("expected float[], found {}", values::kind_name(&wts.value)),
        )
    })?;
    let n = idx.element_size;
    if wts.element_size != n || wts.interpolation != idx.interpolation {
        return Err(Error::attr(
            &wts.prim,
            WTS,
            format!(
                "elementSize {} and interpolation {} differ from primvars:skel:jointIndices ({n}, {}): usd-core ignores such influences",
                wts.element_size, wts.interpolation, idx.interpolation
            ),
        ));
    }
    if weights.len() != joint_idx.len() {
        return Err(Error::attr(
            &wts.prim,
            WTS,
            format!(
                "{} weights for {} primvars:skel:jointIndices",
                weights.len(),
                joint_idx.len()
            ),
        ));
    }
    let interp = idx.interpolation.as_str();
    let (joint_idx, weights) = match interp {
        "constant" if joint_idx.len() == n => (joint_idx.repeat(npts), weights.repeat(npts)),
        "vertex" if joint_idx.len() == n * npts => (joint_idx, weights),
        "constant" | "vertex" => {
            return Err(Error::attr(
                &idx.prim,
                IDX,
                format!(
                    "{} values with {interp} interpolation and elementSize {n} do not fit a mesh of {npts} points",
                    joint_idx.len()
                ),
            ))
        }
        other => {
            return Err(Error::attr(
                &idx.prim,
                IDX,
                format!("interpolation {other:?}: joint influences must be \"constant\" or \"vertex\""),
            ))
        }
    };
    if weights.iter().any(|w| !w.is_finite()) {
        return Err(Error::attr(&wts.prim, WTS, "weights must be finite"));
    }
    Ok(Ok(RawInfluences {
        per_point: n,
        joints: joint_idx,
        weights: weights.iter().map(|&w| w as f64).collect(),
        rigid: interp == "constant",
    }))
}

impl SkelProxy {
    /// Reads the binding of `mesh` (whose rest points are given) to `skeleton`.
    pub fn read(r: &StageReader, mesh: &usd::Prim, skeleton: &str, rest_points: &[DVec3]) -> Result<Self> {
        let mesh_path = mesh.path().as_str().to_string();
        let skel_prim = r.prim(skeleton)?.ok_or_else(|| {
            Error::attr(
                &mesh_path,
                "skel:skeleton",
                format!("targets {skeleton}, which does not exist"),
            )
        })?;
        let ty = r.type_name(&skel_prim)?;
        if ty != "Skeleton" {
            return Err(Error::attr(
                &mesh_path,
                "skel:skeleton",
                format!("targets {skeleton}, a {ty:?} prim, expected a Skeleton"),
            ));
        }
        let mut notes = Vec::new();

        // Skeleton topology.
        let joints = r
            .typed(&skel_prim, "joints", None, "token[]", values::token_array)?
            .unwrap_or_default();
        let nj = joints.len();
        let parents = joint_parents(&joints);
        validate_topology(skeleton, &joints, &parents)?;
        let dups = duplicates(&joints);
        if !dups.is_empty() {
            notes.push(format!(
                "{skeleton} lists joint {} more than once: names resolve to the last of them, as in usd-core",
                quoted(&dups)
            ));
        }

        // Animation: on the Skeleton first, then inherited from the mesh.
        let anim_path = match inherited_targets(r, &skel_prim, "skel:animationSource")? {
            Some((_, t)) if !t.is_empty() => Some(t[0].clone()),
            _ => inherited_targets(r, mesh, "skel:animationSource")?.and_then(|(_, t)| t.into_iter().next()),
        };
        let anim_prim = match &anim_path {
            None => None,
            Some(p) => {
                let prim = r
                    .prim(p)?
                    .filter(|a| r.type_name(a).is_ok_and(|t| t == "SkelAnimation"));
                Some(prim.ok_or_else(|| {
                    Error::attr(
                        skeleton,
                        "skel:animationSource",
                        format!("targets {p}, which is not a SkelAnimation"),
                    )
                })?)
            }
        };

        let npts = rest_points.len();
        let geom_bind = match inherited_attr(r, mesh, "primvars:skel:geomBindTransform")? {
            Some(p) => r
                .typed(&p, "primvars:skel:geomBindTransform", None, "matrix4d", values::matrix4)?
                .unwrap_or(DMat4::IDENTITY),
            None => DMat4::IDENTITY,
        };
        // UsdSkel names it primvars:skel:skinningMethod; accept the bare
        // skel:skinningMethod some exporters write too.
        let mut method = SkinningMethod::ClassicLinear;
        for name in ["primvars:skel:skinningMethod", "skel:skinningMethod"] {
            if let Some(p) = inherited_attr(r, mesh, name)? {
                method = match r.typed(&p, name, None, "token", values::token)?.as_deref() {
                    None | Some("classicLinear") => SkinningMethod::ClassicLinear,
                    Some("dualQuaternion") => SkinningMethod::DualQuaternion,
                    Some(other) => {
                        return Err(Error::attr(
                            p.path(),
                            name,
                            format!("unknown skinning method {other:?} (expected classicLinear or dualQuaternion)"),
                        ))
                    }
                };
                break;
            }
        }

        // Joint skinning: influences, and a pose at every time.
        let influences = read_influences(r, mesh, npts)?;
        let rest_authored = r.has_authored(&skel_prim, "restTransforms")?;
        let anim_joints: Vec<String> = match &anim_prim {
            Some(a) => r
                .typed(a, "joints", None, "token[]", values::token_array)?
                .unwrap_or_default(),
            None => Vec::new(),
        };
        let anim_map = OrderMap::new(&anim_joints, &joints);
        let (influences, joint_pose) = match influences {
            Err(why) => {
                notes.push(format!("{why}: usd-core does not skin it by joints"));
                (None, None)
            }
            Ok(_) if nj == 0 && !rest_authored => {
                notes.push(format!(
                    "{skeleton} has no joints: usd-core ignores the joint influences of {mesh_path}"
                ));
                (None, None)
            }
            Ok(_) if (anim_prim.is_none() || anim_map.is_null()) && !rest_authored => {
                notes.push(format!(
                    "no animation drives the joints of {skeleton} and it has no restTransforms: usd-core does not skin {mesh_path} by joints"
                ));
                (None, None)
            }
            Ok(infl) => {
                let pose = read_joint_pose(
                    r,
                    &skel_prim,
                    skeleton,
                    &joints,
                    parents,
                    anim_prim
                        .as_ref()
                        .filter(|_| !anim_map.is_null())
                        .map(|a| (a, &anim_joints, anim_map.clone())),
                    mesh,
                    &mut notes,
                )?;
                let nmesh = pose.mesh_map.as_ref().map_or(nj, |m| m.target_len);
                if let Some(&bad) = infl.joints.iter().find(|&&j| j < 0 || j as usize >= nmesh) {
                    return Err(Error::attr(
                        &mesh_path,
                        "primvars:skel:jointIndices",
                        format!("joint index {bad} is out of range ({nmesh} joints)"),
                    ));
                }
                let infl = Influences {
                    per_point: infl.per_point,
                    joints: infl.joints.iter().map(|&j| j as u32).collect(),
                    weights: infl.weights,
                    rigid: infl.rigid,
                };
                (Some(infl), Some(pose))
            }
        };

        // Blend shapes, in the mesh's skel:blendShapes order.
        let (blend_shapes, shapes) = read_shapes(r, mesh, anim_prim.as_ref(), npts, &mut notes)?;
        if joint_pose.is_none() && shapes.is_none() {
            notes.push(format!(
                "nothing deforms {mesh_path}: usd-core leaves it in its authored pose"
            ));
        }

        Ok(SkelProxy {
            skeleton: skeleton.to_string(),
            animation: anim_path,
            deformer: SkelDeformer {
                rest_points: rest_points.to_vec(),
                geom_bind,
                influences,
                method,
                blend_shapes,
            },
            notes,
            joints: joint_pose,
            shapes,
        })
    }

    /// Whether joints skin the mesh: posed points are then in skeleton
    /// space; otherwise (blend shapes only) in the mesh's own space.
    pub fn skins_joints(&self) -> bool {
        self.joints.is_some()
    }

    /// Skinning transforms (when joints skin the mesh) and blend-shape
    /// weights at `t`.
    fn pose(&self, t: f64) -> Result<(Option<Vec<DMat4>>, Vec<f64>)> {
        let skinning = self.joints.as_ref().map(|j| j.skinning(t)).transpose()?;
        let weights = match &self.shapes {
            Some(s) => s.at(t)?,
            None => Vec::new(),
        };
        Ok((skinning, weights))
    }

    /// Deformed points at `t`: in skeleton space when [`Self::skins_joints`],
    /// else in the mesh's own space.
    pub fn deform(&self, t: f64) -> Result<Vec<DVec3>> {
        let (skinning, weights) = self.pose(t)?;
        Ok(self.deformer.deform(skinning.as_deref(), &weights))
    }

    /// Whether BakeSkinning rewrites authored normals: joints skin the mesh,
    /// or animated blend shapes have normal offsets.
    pub fn deforms_normals(&self) -> bool {
        self.joints.is_some()
            || (self.shapes.is_some() && self.deformer.blend_shapes.iter().any(|s| s.has_normal_offsets()))
    }

    /// Authored normals deformed at `t` (see [`SkelDeformer::deform_normals`]),
    /// in the same space as [`Self::deform`].
    pub fn deform_normals(&self, t: f64, normals: &[DVec3], point_of: Option<&[u32]>) -> Result<Vec<DVec3>> {
        let (skinning, weights) = self.pose(t)?;
        Ok(self
            .deformer
            .deform_normals(normals, point_of, skinning.as_deref(), &weights))
    }
}
