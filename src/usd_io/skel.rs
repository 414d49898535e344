//! Reads a UsdSkel-bound mesh into a [`SkelDeformer`] and poses it per frame.
//!
//! Follows UsdSkel's rules as usd-core's `UsdSkel.BakeSkinning` applies them:
//! the skeleton binding and joint influences may be inherited from ancestors;
//! the animation source is looked up on the Skeleton first; joints the
//! animation does not drive keep their rest transforms; skinned points are in
//! skeleton space and are brought into the mesh's local space through the
//! Skeleton prim's transform.

use glam::{DMat4, DVec3};
use openusd::sdf::Value;
use openusd::usd::{self, TimeCode};
use openusd_schemas::skel::{Animation, BlendShape as UsdBlendShape, SkelAnimQuery};

use super::stage::StageReader;
use super::values;
use crate::error::{Error, Result};
use crate::skel_deform::{local_to_skel, BlendShape, Influences, SkelDeformer, SkinningMethod};

/// A skinned proxy: its deformer plus what is needed to pose it at a time.
pub struct SkelProxy {
    /// Path of the bound Skeleton prim.
    pub skeleton: String,
    /// Path of the SkelAnimation, if any.
    pub animation: Option<String>,
    pub deformer: SkelDeformer,
    parents: Vec<Option<usize>>,
    rest_local: Vec<DMat4>,
    inverse_bind: Vec<DMat4>,
    /// Skeleton joint index for each animation joint.
    anim_to_skel: Vec<Option<usize>>,
    /// Skeleton joint index for each mesh-order joint (skel:joints).
    mesh_to_skel: Vec<Option<usize>>,
    /// Animation blend-shape index for each mesh blend shape.
    shape_to_anim: Vec<Option<usize>>,
    anim: Option<SkelAnimQuery>,
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
fn inherited_attr(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<usd::Prim>> {
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

/// Reads an (optionally indexed) primvar's flat value with its interpolation and elementSize.
fn read_primvar(r: &StageReader, prim: &usd::Prim, name: &str) -> Result<Option<(Value, String, usize)>> {
    let Some(v) = r.value(prim, name, None)? else {
        return Ok(None);
    };
    let interp = r.primvar_interpolation(prim, name, "constant")?;
    let element_size = r
        .attr_metadata(prim, name, "elementSize")?
        .and_then(|v| values::scalar(&v))
        .unwrap_or(1.0);
    if element_size.is_nan() || element_size < 1.0 {
        return Err(Error::attr(
            prim.path(),
            name,
            format!("elementSize {element_size} must be ≥ 1"),
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
    Ok(Some((v, interp, element_size as usize)))
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

        // Skeleton topology and bind/rest transforms.
        let joints = r
            .typed(&skel_prim, "joints", None, "token[]", values::token_array)?
            .unwrap_or_default();
        let nj = joints.len();
        let parents = joint_parents(&joints);
        let mats = |name: &str| -> Result<Option<Vec<DMat4>>> {
            match r.value(&skel_prim, name, None)? {
                None => Ok(None),
                Some(Value::Matrix4dVec(m)) => Ok(Some(m.iter().map(values::usd_matrix).collect())),
                Some(v) => Err(Error::attr(
                    skeleton,
                    name,
                    format!("expected matrix4d[], found {}", values::kind_name(&v)),
                )),
            }
        };
        let bind = mats("bindTransforms")?.unwrap_or_else(|| vec![DMat4::IDENTITY; nj]);
        if bind.len() != nj {
            return Err(Error::attr(
                skeleton,
                "bindTransforms",
                format!("{} matrices for {nj} joints", bind.len()),
            ));
        }
        let rest_local = match mats("restTransforms")? {
            Some(m) if m.len() == nj => m,
            Some(m) => {
                return Err(Error::attr(
                    skeleton,
                    "restTransforms",
                    format!("{} matrices for {nj} joints", m.len()),
                ))
            }
            // No rest pose: the bind pose expressed joint-locally.
            None => (0..nj)
                .map(|j| match parents[j] {
                    Some(p) => bind[p].inverse() * bind[j],
                    None => bind[j],
                })
                .collect(),
        };
        let inverse_bind: Vec<DMat4> = bind
            .iter()
            .map(|m| {
                if m.determinant().abs() > 0.0 {
                    m.inverse()
                } else {
                    DMat4::IDENTITY
                }
            })
            .collect();

        // Animation: on the Skeleton first, then inherited from the mesh.
        let anim_path = match inherited_targets(r, &skel_prim, "skel:animationSource")? {
            Some((_, t)) if !t.is_empty() => Some(t[0].clone()),
            _ => inherited_targets(r, mesh, "skel:animationSource")?.and_then(|(_, t)| t.into_iter().next()),
        };
        let anim = match &anim_path {
            None => None,
            Some(p) => {
                let a = Animation::get(&r.stage, p.as_str())
                    .map_err(|e| Error::prim(p, format!("cannot read SkelAnimation: {e}")))?
                    .ok_or_else(|| {
                        Error::attr(
                            skeleton,
                            "skel:animationSource",
                            format!("targets {p}, which is not a SkelAnimation"),
                        )
                    })?;
                SkelAnimQuery::new(a).map_err(|e| Error::prim(p, format!("cannot read SkelAnimation: {e}")))?
            }
        };
        let index_of = |names: &[String], name: &str| names.iter().position(|n| n == name);
        let anim_to_skel = anim
            .as_ref()
            .map(|a| a.joint_order().iter().map(|n| index_of(&joints, n)).collect())
            .unwrap_or_default();

        // Joint influences (possibly inherited, possibly indexed).
        let infl_prim = inherited_attr(r, mesh, "primvars:skel:jointIndices")?.ok_or_else(|| {
            Error::attr(
                &mesh_path,
                "primvars:skel:jointIndices",
                "skinned mesh has no joint influences",
            )
        })?;
        let ip = infl_prim.path().as_str().to_string();
        let (iv, interp, n) =
            read_primvar(r, &infl_prim, "primvars:skel:jointIndices")?.expect("authored attribute has a value");
        let joint_idx = values::int_array(&iv).ok_or_else(|| {
            Error::attr(
                &ip,
                "primvars:skel:jointIndices",
                format!("expected int[], found {}", values::kind_name(&iv)),
            )
        })?;
        let (wv, winterp, wn) = read_primvar(r, &infl_prim, "primvars:skel:jointWeights")?.ok_or_else(|| {
            Error::attr(
                &ip,
                "primvars:skel:jointWeights",
                "joint indices are authored but weights are not",
            )
        })?;
        let weights = values::f32_array(&wv).ok_or_else(|| {
            Error::attr(
                &ip,
                "primvars:skel:jointWeights",
                format!("expected float[], found {}", values::kind_name(&wv)),
            )
        })?;
        if winterp != interp || wn != n || weights.len() != joint_idx.len() {
            return Err(Error::attr(
                &ip,
                "primvars:skel:jointWeights",
                format!(
                    "does not match primvars:skel:jointIndices ({} values, {winterp}, elementSize {wn} vs {} values, {interp}, elementSize {n})",
                    weights.len(),
                    joint_idx.len()
                ),
            ));
        }
        let npts = rest_points.len();
        let (joint_idx, weights) = match interp.as_str() {
            "constant" | "uniform" if joint_idx.len() == n => (joint_idx.repeat(npts), weights.repeat(npts)),
            "vertex" | "varying" if joint_idx.len() == n * npts => (joint_idx, weights),
            _ => {
                return Err(Error::attr(
                    &ip,
                    "primvars:skel:jointIndices",
                    format!(
                        "{} values with {interp} interpolation and elementSize {n} do not fit a mesh of {npts} points",
                        joint_idx.len()
                    ),
                ))
            }
        };

        // Mesh joint order (skel:joints subset) → skeleton joints.
        let mesh_joints = match inherited_attr(r, mesh, "skel:joints")? {
            Some(p) => r.typed(&p, "skel:joints", None, "token[]", values::token_array)?,
            None => None,
        };
        let mesh_to_skel: Vec<Option<usize>> = match &mesh_joints {
            Some(mj) => mj.iter().map(|n| index_of(&joints, n)).collect(),
            None => (0..nj).map(Some).collect(),
        };
        let nmesh = mesh_to_skel.len();
        if let Some(bad) = joint_idx.iter().find(|&&j| j < 0 || j as usize >= nmesh) {
            return Err(Error::attr(
                &ip,
                "primvars:skel:jointIndices",
                format!("joint index {bad} is out of range ({nmesh} joints)"),
            ));
        }
        if weights.iter().any(|w| !w.is_finite()) {
            return Err(Error::attr(&ip, "primvars:skel:jointWeights", "weights must be finite"));
        }

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
        // Blend shapes, in the mesh's skel:blendShapes order.
        let shape_names = r
            .typed(mesh, "skel:blendShapes", None, "token[]", values::token_array)?
            .unwrap_or_default();
        let shape_targets = r.targets(mesh, "skel:blendShapeTargets")?;
        if shape_names.len() != shape_targets.len() {
            return Err(Error::attr(
                &mesh_path,
                "skel:blendShapeTargets",
                format!(
                    "{} targets for {} skel:blendShapes",
                    shape_targets.len(),
                    shape_names.len()
                ),
            ));
        }
        let blend_shapes = shape_targets
            .iter()
            .map(|p| read_blend_shape(r, p, npts))
            .collect::<Result<Vec<_>>>()?;
        let shape_to_anim = shape_names
            .iter()
            .map(|n| anim.as_ref().and_then(|a| index_of(a.blend_shape_order(), n)))
            .collect();

        Ok(SkelProxy {
            skeleton: skeleton.to_string(),
            animation: anim_path,
            deformer: SkelDeformer {
                rest_points: rest_points.to_vec(),
                geom_bind,
                influences: Influences {
                    per_point: n,
                    joints: joint_idx.iter().map(|&j| j as u32).collect(),
                    weights: weights.iter().map(|&w| w as f64).collect(),
                },
                method,
                blend_shapes,
            },
            parents,
            rest_local,
            inverse_bind,
            anim_to_skel,
            mesh_to_skel,
            shape_to_anim,
            anim,
        })
    }

    /// Skinning transforms (mesh joint order) and blend-shape weights at `t`.
    pub fn pose(&self, t: f64) -> Result<(Vec<DMat4>, Vec<f64>)> {
        let mut local = self.rest_local.clone();
        let mut shape_w = vec![0.0; self.shape_to_anim.len()];
        if let Some(a) = &self.anim {
            let path = self.animation.as_deref().unwrap_or("");
            if !self.anim_to_skel.is_empty() {
                let xf = a
                    .compute_joint_local_transforms(TimeCode::new(t))
                    .map_err(|e| Error::prim(path, format!("cannot read joint transforms at time {t}: {e}")))?;
                for (ai, m) in xf.iter().enumerate() {
                    if let Some(Some(j)) = self.anim_to_skel.get(ai) {
                        local[*j] = values::usd_matrix(m);
                    }
                }
            }
            if !self.shape_to_anim.is_empty() {
                let w = a
                    .compute_blend_shape_weights(TimeCode::new(t))
                    .map_err(|e| Error::attr(path, "blendShapeWeights", format!("cannot read at time {t}: {e}")))?;
                for (k, ai) in self.shape_to_anim.iter().enumerate() {
                    if let Some(ai) = ai {
                        shape_w[k] = w.get(*ai).copied().unwrap_or(0.0) as f64;
                    }
                }
            }
        }
        let skel = local_to_skel(&local, &self.parents);
        let skinning = self
            .mesh_to_skel
            .iter()
            .map(|j| match j {
                Some(j) => skel[*j] * self.inverse_bind[*j],
                None => DMat4::IDENTITY,
            })
            .collect();
        Ok((skinning, shape_w))
    }
}

fn read_blend_shape(r: &StageReader, path: &str, npts: usize) -> Result<BlendShape> {
    let prim = r
        .prim(path)?
        .ok_or_else(|| Error::prim(path, "blend shape target does not exist"))?;
    let to_d = |v: Vec<glam::Vec3>| v.into_iter().map(|p| p.as_dvec3()).collect::<Vec<_>>();
    let offsets = to_d(
        r.typed(&prim, "offsets", None, "vector3f[]", values::vec3_array)?
            .unwrap_or_default(),
    );
    let point_indices = match r.typed(&prim, "pointIndices", None, "int[]", values::int_array)? {
        None => None,
        Some(idx) => {
            if let Some(bad) = idx.iter().find(|&&i| i < 0 || i as usize >= npts) {
                return Err(Error::attr(
                    path,
                    "pointIndices",
                    format!("index {bad} out of range ({npts} points)"),
                ));
            }
            Some(idx.iter().map(|&i| i as u32).collect::<Vec<_>>())
        }
    };
    let expected = point_indices.as_ref().map_or(npts, |i| i.len());
    if offsets.len() != expected {
        return Err(Error::attr(
            path,
            "offsets",
            format!("{} offsets, expected {expected}", offsets.len()),
        ));
    }
    let shape = UsdBlendShape::get(&r.stage, path)
        .map_err(|e| Error::prim(path, format!("cannot read BlendShape: {e}")))?
        .ok_or_else(|| Error::prim(path, "not a BlendShape"))?;
    let inbetweens = shape
        .inbetweens()
        .map_err(|e| Error::prim(path, format!("cannot read inbetweens: {e}")))?
        .into_iter()
        .filter_map(|ib| {
            let w = ib.weight?;
            Some((
                w as f64,
                ib.offsets
                    .iter()
                    .map(|o| DVec3::new(o.x as f64, o.y as f64, o.z as f64))
                    .collect::<Vec<_>>(),
            ))
        })
        .collect::<Vec<_>>();
    for (w, o) in &inbetweens {
        if o.len() != expected {
            return Err(Error::prim(
                path,
                format!("inbetween at weight {w} has {} offsets, expected {expected}", o.len()),
            ));
        }
    }
    Ok(BlendShape {
        offsets,
        point_indices,
        inbetweens,
    })
}

/// Parent index of each joint from its path-encoded name ("A/B/C" → "A/B").
pub fn joint_parents(joints: &[String]) -> Vec<Option<usize>> {
    joints
        .iter()
        .map(|j| {
            let parent = j.rsplit_once('/').map(|(p, _)| p)?;
            joints.iter().position(|k| k == parent)
        })
        .collect()
}
