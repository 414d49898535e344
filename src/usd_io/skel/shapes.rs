//! Blend shapes as usd-core applies them: read from the mesh's
//! `skel:blendShapeTargets`, weighted by the animation's
//! `blendShapeWeights` mapped onto the mesh's `skel:blendShapes` order.

use glam::DVec3;
use openusd::usd;
use openusd_schemas::skel::BlendShape as UsdBlendShape;

use super::mapper::OrderMap;
use crate::error::{Error, Result};
use crate::skel_deform::{ignores_inbetween_at, BlendShape, Inbetween};
use crate::usd_io::stage::{HeldQuery, StageReader};
use crate::usd_io::values;

/// The animation's blend-shape weights, in the mesh's `skel:blendShapes` order.
pub(super) struct ShapeWeights {
    path: String,
    query: HeldQuery,
    map: OrderMap,
}

impl ShapeWeights {
    pub(super) fn at(&self, t: f64) -> Result<Vec<f64>> {
        let v = self
            .query
            .get_at(t)
            .map_err(|e| Error::attr(&self.path, "blendShapeWeights", format!("cannot read at time {t}: {e}")))?;
        // Unreadable at this time: usd-core applies no blend shape.
        let raw = v.as_ref().and_then(values::f32_array).unwrap_or_default();
        let mut w = Vec::new();
        self.map.remap(&raw, &mut w, 0.0);
        Ok(w.into_iter().map(f64::from).collect())
    }
}

/// The mesh's blend shapes and their animated weights, when usd-core
/// applies them: the animation has `blendShapeWeights`, the mesh names its
/// shapes, and some shape has point or normal offsets.
pub(super) fn read_shapes(
    r: &StageReader,
    mesh: &usd::Prim,
    anim: Option<&usd::Prim>,
    npts: usize,
    notes: &mut Vec<String>,
) -> Result<(Vec<BlendShape>, Option<ShapeWeights>)> {
    let mesh_path = mesh.path().as_str().to_string();
    let Some(shape_names) = r.typed(mesh, "skel:blendShapes", None, "token[]", values::token_array)? else {
        return Ok((Vec::new(), None));
    };
    let Some(anim) = anim else {
        return Ok((Vec::new(), None));
    };
    if !r.has_authored(anim, "blendShapeWeights")? {
        return Ok((Vec::new(), None));
    }
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
    let shapes = shape_targets
        .iter()
        .map(|p| read_blend_shape(r, p, npts, notes))
        .collect::<Result<Vec<_>>>()?;
    if !shapes.iter().any(|s| {
        !s.offsets.is_empty() || s.inbetweens.iter().any(|ib| !ib.offsets.is_empty()) || s.has_normal_offsets()
    }) {
        return Ok((Vec::new(), None));
    }
    let anim_shapes = r
        .typed(anim, "blendShapes", None, "token[]", values::token_array)?
        .unwrap_or_default();
    let weights = ShapeWeights {
        path: anim.path().as_str().to_string(),
        query: HeldQuery::new(anim, "blendShapeWeights")?,
        map: OrderMap::new(&anim_shapes, &shape_names),
    };
    Ok((shapes, Some(weights)))
}

fn read_blend_shape(r: &StageReader, path: &str, npts: usize, notes: &mut Vec<String>) -> Result<BlendShape> {
    let prim = r
        .prim(path)?
        .ok_or_else(|| Error::prim(path, "blend shape target does not exist"))?;
    let to_d = |v: Vec<glam::Vec3>| v.into_iter().map(|p| p.as_dvec3()).collect::<Vec<_>>();
    let offsets = to_d(
        r.typed(&prim, "offsets", None, "vector3f[]", values::vec3_array)?
            .unwrap_or_default(),
    );
    // An empty pointIndices array means dense offsets to usd-core.
    let point_indices = match r.typed(&prim, "pointIndices", None, "int[]", values::int_array)? {
        Some(idx) if !idx.is_empty() => {
            if let Some(bad) = idx.iter().find(|&&i| i < 0 || i as usize >= npts) {
                return Err(Error::attr(
                    path,
                    "pointIndices",
                    format!("index {bad} out of range ({npts} points)"),
                ));
            }
            Some(idx.iter().map(|&i| i as u32).collect::<Vec<_>>())
        }
        _ => None,
    };
    let expected = point_indices.as_ref().map_or(npts, |i| i.len());
    if offsets.is_empty() {
        let has_normals = r.has_authored(&prim, "normalOffsets")?;
        notes.push(format!(
            "blend shape {path} has no offsets{}: it moves no point, as in usd-core",
            if has_normals { " (only normalOffsets)" } else { "" }
        ));
    } else if offsets.len() != expected {
        return Err(Error::attr(
            path,
            "offsets",
            format!("{} offsets, expected {expected}", offsets.len()),
        ));
    }
    let shape = UsdBlendShape::get(&r.stage, path)
        .map_err(|e| Error::prim(path, format!("cannot read BlendShape: {e}")))?
        .ok_or_else(|| Error::prim(path, "not a BlendShape"))?;
    let mut inbetweens = Vec::new();
    for ib in shape
        .inbetweens()
        .map_err(|e| Error::prim(path, format!("cannot read inbetweens: {e}")))?
    {
        let attr = format!("inbetweens:{}", ib.name);
        let Some(w) = ib.weight else {
            notes.push(format!("{path}.{attr} has no weight: usd-core ignores it"));
            continue;
        };
        let w = w as f64;
        if ignores_inbetween_at(w) {
            notes.push(format!(
                "{path}.{attr} has weight {w}: usd-core ignores inbetweens at 0 and 1"
            ));
            continue;
        }
        if !w.is_finite() {
            return Err(Error::attr(path, &attr, format!("weight {w} is not finite")));
        }
        let offsets: Vec<DVec3> = ib
            .offsets
            .iter()
            .map(|o| DVec3::new(o.x as f64, o.y as f64, o.z as f64))
            .collect();
        if offsets.is_empty() {
            notes.push(format!(
                "{path}.{attr} has no offsets: it moves no point, as in usd-core"
            ));
        } else if offsets.len() != expected {
            return Err(Error::attr(
                path,
                &attr,
                format!(
                    "inbetween at weight {w} has {} offsets, expected {expected}",
                    offsets.len()
                ),
            ));
        }
        let normal_offsets = checked_normal_offsets(
            path,
            &attr,
            ib.normal_offsets
                .iter()
                .map(|o| DVec3::new(o.x as f64, o.y as f64, o.z as f64))
                .collect(),
            expected,
            notes,
        );
        inbetweens.push(Inbetween {
            weight: w,
            offsets,
            normal_offsets,
        });
    }
    let normal_offsets = r
        .typed(&prim, "normalOffsets", None, "vector3f[]", values::vec3_array)?
        .unwrap_or_default()
        .into_iter()
        .map(|p| p.as_dvec3())
        .collect();
    let normal_offsets = checked_normal_offsets(path, "normalOffsets", normal_offsets, expected, notes);
    Ok(BlendShape {
        offsets,
        normal_offsets,
        point_indices,
        inbetweens,
    })
}

/// Normal offsets, unless their count does not fit the shape: usd-core then
/// cannot apply them (only meshes with authored normals care, so a note).
fn checked_normal_offsets(
    path: &str,
    attr: &str,
    offsets: Vec<DVec3>,
    expected: usize,
    notes: &mut Vec<String>,
) -> Vec<DVec3> {
    if offsets.is_empty() || offsets.len() == expected {
        return offsets;
    }
    notes.push(format!(
        "{path}.{attr} has {} normal offsets, expected {expected}: usd-core applies none of this shape's normal offsets",
        offsets.len()
    ));
    Vec::new()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use crate::error::Result;
    use crate::usd_io::skel::SkelProxy;
    use crate::usd_io::testutil::stage_from_usda;

    /// The 3-point mesh /R/M, (0,0,0) (1,0,0) (0,1,0), under one blend
    /// shape whose BlendShape prim has the lines `shape`, at weight `w`.
    fn proxy(shape: &str, w: f64) -> Result<SkelProxy> {
        let r = stage_from_usda(&format!(
            r#"#usda 1.0
def SkelRoot "R"
{{
    def Skeleton "Skel"
    {{
        rel skel:animationSource = </R/Skel/Anim>
        def SkelAnimation "Anim"
        {{
            uniform token[] blendShapes = ["s"]
            float[] blendShapeWeights = [{w}]
        }}
    }}
    def Mesh "M"
    {{
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        rel skel:skeleton = </R/Skel>
        uniform token[] skel:blendShapes = ["s"]
        rel skel:blendShapeTargets = </R/M/s>
        def BlendShape "s"
        {{
            {shape}
        }}
    }}
}}
"#
        ));
        let mesh = r.prim("/R/M").unwrap().unwrap();
        let rest = [DVec3::ZERO, DVec3::X, DVec3::Y];
        SkelProxy::read(&r, &mesh, "/R/Skel", &rest)
    }

    /// The points of [`proxy`].
    fn shaped(shape: &str, w: f64) -> Result<Vec<DVec3>> {
        proxy(shape, w)?.deform(0.0)
    }

    // Expected points below are usd-core's UsdSkel.BakeSkinning of the same
    // stage (with the weight time-sampled).
    const MOVED: [DVec3; 3] = [DVec3::new(0.0, 0.0, 1.0), DVec3::X, DVec3::new(2.0, 1.0, 0.0)];

    #[test]
    fn empty_point_indices_mean_dense_offsets() {
        let shape = "uniform vector3f[] offsets = [(0, 0, 2), (0, 0, 0), (4, 0, 0)]
            uniform int[] pointIndices = []";
        assert_eq!(shaped(shape, 0.5).unwrap(), MOVED);
    }

    #[test]
    fn sparse_offsets_may_include_point_zero() {
        let shape = "uniform vector3f[] offsets = [(0, 0, 2), (4, 0, 0)]
            uniform int[] pointIndices = [0, 2]";
        assert_eq!(shaped(shape, 0.5).unwrap(), MOVED);
    }

    #[test]
    fn point_indices_outside_the_mesh_are_refused() {
        // usd-core warns "Out of range point index" and applies none of the
        // mesh's blend shapes; we refuse the rig (bad input), naming the
        // attribute.
        for idx in ["[0, 3]", "[-1, 0]"] {
            let shape = format!(
                "uniform vector3f[] offsets = [(0, 0, 2), (4, 0, 0)]
                uniform int[] pointIndices = {idx}"
            );
            let e = shaped(&shape, 0.5).unwrap_err();
            assert_eq!(e.attribute.as_deref(), Some("pointIndices"), "{idx}");
        }
    }

    #[test]
    fn inbetween_of_a_shape_without_offsets_still_moves_points() {
        // The primary shape counts as zero offsets: weight 0.25 is half-way
        // to the inbetween at 0.5.
        let shape = "uniform vector3f[] inbetweens:half = [(0, 0, 2), (0, 0, 0), (0, 0, 0)] (weight = 0.5)";
        assert_eq!(shaped(shape, 0.5).unwrap()[0], DVec3::new(0.0, 0.0, 2.0));
        assert_eq!(shaped(shape, 0.25).unwrap()[0], DVec3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn inbetweens_at_0_and_1_are_skipped_before_any_check() {
        // usd-core skips inbetweens closer than a float 1e-6 to weight 0 or 1, so their
        // offset counts (1 here, for 3 points) do not matter: the shape
        // is its primary alone, linear in the weight.
        let shape = "uniform vector3f[] offsets = [(0, 0, 2), (0, 0, 0), (4, 0, 0)]
            uniform vector3f[] inbetweens:one = [(9, 9, 9)] (weight = 1)
            uniform vector3f[] inbetweens:tiny = [(9, 9, 9)] (weight = 1e-7)
            uniform vector3f[] inbetweens:zero = [(9, 9, 9)] (weight = 0)";
        let p = proxy(shape, 0.5).unwrap();
        assert_eq!(p.deform(0.0).unwrap(), MOVED);
        for ib in ["one", "tiny", "zero"] {
            assert!(
                p.notes
                    .iter()
                    .any(|n| n.contains(&format!("inbetweens:{ib} has weight"))),
                "{ib}: {:?}",
                p.notes
            );
        }
    }
}
