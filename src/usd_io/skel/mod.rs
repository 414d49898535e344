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

/// `prim` and its ancestors, nearest first, up to (not including) `/`.
fn lineage(prim: &usd::Prim) -> Vec<usd::Prim> {
    let mut chain = Vec::new();
    let mut cur = Some(prim.clone());
    while let Some(p) = cur {
        if p.path().as_str() == "/" {
            break;
        }
        cur = p.parent();
        chain.push(p);
    }
    chain
}

/// `prim` and its ancestors up to the outermost SkelRoot above it: usd-core
/// skins a mesh only under a SkelRoot and inherits binding properties from
/// that root down (a SkelRoot nested in another is part of the outer one's
/// scope). Empty when no SkelRoot is above `prim`.
fn skel_scope(r: &StageReader, prim: &usd::Prim) -> Result<Vec<usd::Prim>> {
    let mut chain = lineage(prim);
    let mut root = None;
    for (i, p) in chain.iter().enumerate() {
        if r.type_name(p)? == "SkelRoot" {
            root = Some(i);
        }
    }
    chain.truncate(root.map_or(0, |i| i + 1));
    Ok(chain)
}

/// Nearest authored opinion of a relationship along `chain` (a prim, then
/// its ancestors).
fn inherited_targets(r: &StageReader, chain: &[usd::Prim], name: &str) -> Result<Option<(String, Vec<String>)>> {
    for p in chain {
        let rel = p.relationship(name);
        let authored = rel
            .has_authored_targets()
            .map_err(|e| Error::attr(p.path(), name, format!("cannot read: {e}")))?;
        if authored {
            return Ok(Some((p.path().as_str().to_string(), r.targets(p, name)?)));
        }
    }
    Ok(None)
}

/// Nearest prim (`prim` or an ancestor within its SkelRoot's scope) with an
/// authored attribute.
pub(super) fn inherited_attr(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<usd::Prim>> {
    for p in skel_scope(r, prim)? {
        if r.has_authored(&p, name)? {
            return Ok(Some(p));
        }
    }
    Ok(None)
}

/// Whether `mesh` is bound to a skeleton (its own or an inherited
/// `skel:skeleton`, within a SkelRoot's scope).
pub fn skeleton_binding(r: &StageReader, mesh: &usd::Prim) -> Result<Option<String>> {
    Ok(inherited_targets(r, &skel_scope(r, mesh)?, "skel:skeleton")?.and_then(|(_, t)| t.into_iter().next()))
}

/// A note for a mesh that names a skeleton usd-core does not skin it with:
/// its `skel:skeleton` (its own or an ancestor's) lies outside any SkelRoot's
/// scope.
pub fn unscoped_binding_note(r: &StageReader, mesh: &usd::Prim) -> Result<Option<String>> {
    if skeleton_binding(r, mesh)?.is_some() {
        return Ok(None);
    }
    Ok(inherited_targets(r, &lineage(mesh), "skel:skeleton")?.map(|(on, _)| {
        format!(
            "skel:skeleton on {on} binds {} outside any SkelRoot's scope: usd-core does not skin it",
            mesh.path().as_str()
        )
    }))
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
    let Some(v) = r.value_over_time(prim, name)? else {
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
    let indices = r.typed_over_time(prim, &indices_name, "int[]", values::int_array)?;
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

/// The Skeleton prim `skel:skeleton` targets.
fn skeleton_prim(r: &StageReader, mesh_path: &str, skeleton: &str) -> Result<usd::Prim> {
    let skel_prim = r.prim(skeleton)?.ok_or_else(|| {
        Error::attr(
            mesh_path,
            "skel:skeleton",
            format!("targets {skeleton}, which does not exist"),
        )
    })?;
    let ty = r.type_name(&skel_prim)?;
    if ty != "Skeleton" {
        return Err(Error::attr(
            mesh_path,
            "skel:skeleton",
            format!("targets {skeleton}, a {ty:?} prim, expected a Skeleton"),
        ));
    }
    Ok(skel_prim)
}

/// The path `skel:animationSource` names for the Skeleton `skel_prim`, on it
/// or on its nearest ancestor that authors one (usd-core's
/// `GetInheritedAnimationSource`, which is not bounded by a SkelRoot).
pub fn animation_source_path(r: &StageReader, skel_prim: &usd::Prim) -> Result<Option<String>> {
    Ok(inherited_targets(r, &lineage(skel_prim), "skel:animationSource")?.and_then(|(_, t)| t.into_iter().next()))
}

/// The SkelAnimation that drives the skeleton: `skel:animationSource` on the
/// Skeleton or inherited from any of its ancestors, as usd-core's
/// `GetInheritedAnimationSource` finds it (one on the mesh plays no part).
fn animation_source(
    r: &StageReader,
    skel_prim: &usd::Prim,
    skeleton: &str,
) -> Result<(Option<String>, Option<usd::Prim>)> {
    let anim_path = animation_source_path(r, skel_prim)?;
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
    Ok((anim_path, anim_prim))
}

/// The mesh's skinning method, `primvars:skel:skinningMethod` (inherited
/// within the SkelRoot's scope). A bare `skel:skinningMethod`, which some
/// exporters write, is not UsdSkel's name: usd-core ignores it, so it is
/// ignored here too and a note says so.
fn skinning_method(r: &StageReader, mesh: &usd::Prim, notes: &mut Vec<String>) -> Result<SkinningMethod> {
    const NAME: &str = "primvars:skel:skinningMethod";
    if let Some(p) = inherited_attr(r, mesh, "skel:skinningMethod")? {
        notes.push(format!(
            "{} authors skel:skinningMethod, which is not UsdSkel's name ({NAME}): usd-core ignores it",
            p.path().as_str()
        ));
    }
    let Some(p) = inherited_attr(r, mesh, NAME)? else {
        return Ok(SkinningMethod::ClassicLinear);
    };
    match r.typed(&p, NAME, None, "token", values::token)?.as_deref() {
        None | Some("classicLinear") => Ok(SkinningMethod::ClassicLinear),
        Some("dualQuaternion") => Ok(SkinningMethod::DualQuaternion),
        Some(other) => Err(Error::attr(
            p.path(),
            NAME,
            format!("unknown skinning method {other:?} (expected classicLinear or dualQuaternion)"),
        )),
    }
}

impl SkelProxy {
    /// Reads the binding of `mesh` (whose rest points are given) to `skeleton`.
    pub fn read(r: &StageReader, mesh: &usd::Prim, skeleton: &str, rest_points: &[DVec3]) -> Result<Self> {
        let mesh_path = mesh.path().as_str().to_string();
        let skel_prim = skeleton_prim(r, &mesh_path, skeleton)?;
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

        let (anim_path, anim_prim) = animation_source(r, &skel_prim, skeleton)?;
        let npts = rest_points.len();
        let geom_bind = match inherited_attr(r, mesh, "primvars:skel:geomBindTransform")? {
            Some(p) => r
                .typed_over_time(&p, "primvars:skel:geomBindTransform", "matrix4d", values::matrix4)?
                .unwrap_or(DMat4::IDENTITY),
            None => DMat4::IDENTITY,
        };
        let method = skinning_method(r, mesh, &mut notes)?;

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
        let points = self.deformer.deform(skinning.as_deref(), &weights);
        if points.iter().any(|p| !p.is_finite()) {
            if let Some(e) = self
                .joints
                .as_ref()
                .map(|j| j.non_finite_input(t))
                .transpose()?
                .flatten()
            {
                return Err(e);
            }
        }
        Ok(points)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::testutil::stage_from_usda;
    use openusd::gf;

    const ID: &str = "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )";
    const INFL: &str = r#"int[] primvars:skel:jointIndices = [0, 0, 0] (interpolation = "vertex")
        float[] primvars:skel:jointWeights = [1, 1, 1] (interpolation = "vertex")"#;

    /// Skeleton /R/Skel (with `skel` lines) and a 3-point mesh /R/M bound to it.
    fn stage(skel: &str, mesh: &str) -> StageReader {
        stage_from_usda(&format!(
            r#"#usda 1.0
def SkelRoot "R"
{{
    def Skeleton "Skel"
    {{
        {skel}
    }}
    def Mesh "M"
    {{
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        {mesh}
        rel skel:skeleton = </R/Skel>
    }}
}}
"#
        ))
    }

    fn mesh(r: &StageReader) -> usd::Prim {
        r.prim("/R/M").unwrap().unwrap()
    }

    fn proxy(r: &StageReader) -> Result<SkelProxy> {
        let rest = [DVec3::ZERO, DVec3::X, DVec3::Y];
        SkelProxy::read(r, &mesh(r), "/R/Skel", &rest)
    }

    #[test]
    fn indexed_values_pick_whole_tuples() {
        // elementSize 2: index i picks elements 2i and 2i + 1, by hand.
        let idx = [2, 0, 2];
        assert_eq!(
            expand_indexed(&Value::IntVec(vec![0, 1, 2, 3, 4, 5]), &idx, 2),
            Some(Value::IntVec(vec![4, 5, 0, 1, 4, 5]))
        );
        assert_eq!(
            expand_indexed(&Value::FloatVec(vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]), &idx, 2),
            Some(Value::FloatVec(vec![2.0, 2.5, 0.0, 0.5, 2.0, 2.5]))
        );
        assert_eq!(
            expand_indexed(&Value::DoubleVec(vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]), &idx, 2),
            Some(Value::DoubleVec(vec![2.0, 2.5, 0.0, 0.5, 2.0, 2.5]))
        );
        let h = |v: &[f32]| v.iter().map(|&x| gf::f16::from_f32(x)).collect::<Vec<_>>();
        assert_eq!(
            expand_indexed(&Value::HalfVec(h(&[0.0, 0.5, 1.0, 1.5, 2.0, 2.5])), &idx, 2),
            Some(Value::HalfVec(h(&[2.0, 2.5, 0.0, 0.5, 2.0, 2.5])))
        );
        // Out of range (a whole tuple must exist), negative, or not a number array.
        assert_eq!(expand_indexed(&Value::IntVec(vec![0, 1, 2]), &[1], 2), None);
        assert_eq!(expand_indexed(&Value::IntVec(vec![0, 1]), &[-1], 1), None);
        assert_eq!(expand_indexed(&Value::String("x".into()), &[0], 1), None);
    }

    #[test]
    fn missing_influences_note_says_which_primvar() {
        let why = |m: &str| {
            read_influences(&stage("", m), &mesh(&stage("", m)), 3)
                .unwrap()
                .err()
                .unwrap()
        };
        assert_eq!(why(""), "/R/M has no joint influences (primvars:skel:jointIndices)");
        assert_eq!(
            why("float[] primvars:skel:jointWeights = [1, 1, 1] (interpolation = \"vertex\")"),
            "/R/M has primvars:skel:jointWeights but no primvars:skel:jointIndices"
        );
        assert_eq!(
            why("int[] primvars:skel:jointIndices = [0, 0, 0] (interpolation = \"vertex\")"),
            "/R/M has primvars:skel:jointIndices but no primvars:skel:jointWeights"
        );
    }

    #[test]
    fn influences_not_sized_for_the_mesh_are_refused() {
        // 3 points, elementSize 1: constant needs 1 value, vertex 3.
        for (interp, n) in [("constant", 3), ("vertex", 2), ("vertex", 4)] {
            let vals = vec!["0"; n].join(", ");
            let m = format!(
                r#"int[] primvars:skel:jointIndices = [{vals}] (interpolation = "{interp}")
                float[] primvars:skel:jointWeights = [{vals}] (interpolation = "{interp}")"#
            );
            let r = stage("", &m);
            let err = read_influences(&r, &mesh(&r), 3).err().expect(&m).to_string();
            assert!(err.contains("do not fit a mesh of 3 points"), "{err}");
        }
    }

    #[test]
    fn skeleton_without_joints_is_noted() {
        let r = stage("uniform token[] joints = []", INFL);
        assert_eq!(
            proxy(&r).unwrap().notes,
            [
                "/R/Skel has no joints: usd-core ignores the joint influences of /R/M",
                "nothing deforms /R/M: usd-core leaves it in its authored pose",
            ]
        );
    }

    #[test]
    fn animation_without_joints_and_no_rest_pose_does_not_skin() {
        // The SkelAnimation drives no joint (no joints authored) and there is
        // no restTransforms: usd-core cannot pose the skeleton, so it does
        // not skin the mesh; that is a note, not an error.
        let skel = format!(
            r#"uniform token[] joints = ["a"]
        uniform matrix4d[] bindTransforms = [{ID}]
        rel skel:animationSource = </R/Skel/Anim>
        def SkelAnimation "Anim"
        {{
        }}"#
        );
        let p = proxy(&stage(&skel, INFL)).unwrap();
        assert!(!p.skins_joints());
        assert_eq!(
            p.notes[0],
            "no animation drives the joints of /R/Skel and it has no restTransforms: usd-core does not skin /R/M by joints"
        );
    }

    #[test]
    fn joints_alone_deforming_need_no_note() {
        let skel = format!(
            r#"uniform token[] joints = ["a"]
        uniform matrix4d[] bindTransforms = [{ID}]
        uniform matrix4d[] restTransforms = [{ID}]"#
        );
        let p = proxy(&stage(&skel, INFL)).unwrap();
        assert!(p.skins_joints());
        assert!(p.notes.is_empty(), "{:?}", p.notes);
    }

    #[test]
    fn blend_shapes_without_normal_offsets_leave_normals() {
        // BakeSkinning rewrites normals for joint skinning or for blend
        // shapes with normalOffsets; point offsets alone move no normal.
        let skel = r#"rel skel:animationSource = </R/Skel/Anim>
        def SkelAnimation "Anim"
        {
            uniform token[] blendShapes = ["s"]
            float[] blendShapeWeights = [0.5]
        }"#;
        let mesh = r#"uniform token[] skel:blendShapes = ["s"]
        rel skel:blendShapeTargets = </R/M/s>
        def BlendShape "s"
        {
            uniform vector3f[] offsets = [(0, 0, 1), (0, 0, 0), (0, 0, 0)]
        }"#;
        let p = proxy(&stage(skel, mesh)).unwrap();
        assert!(!p.skins_joints());
        // The shape does deform the mesh: point 0 rises by half its offset.
        assert_eq!(p.deform(0.0).unwrap()[0], DVec3::new(0.0, 0.0, 0.5));
        assert!(!p.deforms_normals());
    }

    #[test]
    fn skeleton_with_empty_animation_source_is_at_rest() {
        // An authored but empty skel:animationSource names no animation:
        // usd-core poses the skeleton at rest.
        let skel = format!(
            r#"uniform token[] joints = ["a"]
        uniform matrix4d[] bindTransforms = [{ID}]
        uniform matrix4d[] restTransforms = [{ID}]
        rel skel:animationSource = None"#
        );
        let p = proxy(&stage(&skel, INFL)).unwrap();
        assert_eq!(p.animation, None);
        assert!(p.skins_joints());
    }
}
