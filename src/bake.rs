//! `painterly bake`: read stage → evaluate every frame → write an override layer.
//!
//! Rest data is computed once per rig and layer (one-rings, rest centroids,
//! bindings: the stencil tables); each frame then costs one Procrustes per
//! proxy vertex and one 3×4 blend per stroke point. Stage reads are serial
//! (the stage is single-threaded), compute is parallel, the write is one
//! serial pass at the end.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Affine3A, DMat4, Vec3};
use openusd::gf;
use openusd::sdf::Value;

use crate::bind::{Binding, ClosestPoint};
use crate::error::{Error, Result};
use crate::frames::FrameRange;
use crate::keys::{combine, Source};
use crate::mesh::{bounds, bounds_f64, fan_triangulate, weighted_sum, OneRings};
use crate::skinning::{skin_points, to_f32, SkinningRest};
use crate::usd_io::axes::AxisFrame;
use crate::usd_io::layer::{Format, OverLayer};
use crate::usd_io::scene::{LayerKeys, Rig, Scene};
use crate::usd_io::stage::StageReader;
use crate::usd_io::view_mesh::{check_camera, read_view_meshes, ViewBlend};
use rayon::prelude::*;

/// What to bake.
#[derive(Debug, Clone, Default)]
pub struct BakeOptions {
    /// Frames to bake; default: the stage's startTimeCode..endTimeCode.
    pub frames: Option<FrameRange>,
    /// Also write every rig proxy's evaluated points (and block its skeleton).
    pub bake_proxy: bool,
    /// Camera prim for `viewDirection` axes without a source (and view-dependent meshes).
    pub camera: Option<String>,
}

/// What a bake did, for the summary line and `--json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BakeSummary {
    pub input: PathBuf,
    pub output: PathBuf,
    pub frames: usize,
    pub rigs: usize,
    pub view_meshes: usize,
    pub layers: usize,
    pub strokes: usize,
    pub points: usize,
    pub seconds: f64,
}

/// Reports progress: (steps done, total steps); called from worker threads.
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Checks an output path before any work: format, directory, not the input.
pub fn check_output(input: &Path, output: &Path) -> Result<Format> {
    let format = Format::from_path(output)?;
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::msg(format!("output directory {} does not exist", dir.display())).in_file(output));
    }
    if let (Ok(a), Ok(b)) = (input.canonicalize(), output.canonicalize()) {
        if a == b {
            return Err(Error::msg("output would overwrite the input; inputs are never modified").in_file(output));
        }
    }
    Ok(format)
}

/// The frames to bake: the option, checked against the stage's range, or
/// the stage's whole range (see [`crate::frames::resolve`]).
pub fn resolve_frames(r: &StageReader, frames: Option<FrameRange>) -> Result<Vec<f64>> {
    crate::frames::resolve(&r.metadata(), frames)
}

/// Per-rig data computed once.
struct RigBake<'a> {
    rig: &'a Rig,
    skin: SkinningRest,
    bindings: Vec<Binding>,
    needed_axes: Vec<usize>,
}

fn prepare(rig: &Rig) -> RigBake<'_> {
    let proxy = &rig.proxy;
    let rings = OneRings::new(proxy.rest.len(), &proxy.face_counts, &proxy.face_indices);
    let skin = SkinningRest::new(rings, &proxy.rest);
    let tris = fan_triangulate(&proxy.face_counts, &proxy.face_indices);
    let needs_bvh = rig.layers.iter().any(|l| l.cached_binding.is_none());
    let bvh = needs_bvh.then(|| ClosestPoint::new(&proxy.rest, &tris));
    let bindings = rig
        .layers
        .iter()
        .map(|l| match (&l.cached_binding, &bvh) {
            (Some(b), _) => b.clone(),
            (None, Some(bvh)) => bvh.bind(&l.rest_points),
            (None, None) => unreachable!("a BVH is built when a layer has no cached binding"),
        })
        .collect();
    RigBake {
        rig,
        skin,
        bindings,
        needed_axes: needed_axes(rig),
    }
}

fn affine_f32(m: DMat4) -> Affine3A {
    Affine3A::from_mat4(m.as_mat4())
}

fn extent_value(points: &[Vec3]) -> Value {
    let [lo, hi] = bounds(points).unwrap_or([Vec3::ZERO, Vec3::ZERO]);
    Value::Vec3fVec(vec![gf::vec3f(lo.x, lo.y, lo.z), gf::vec3f(hi.x, hi.y, hi.z)])
}

fn points_value(points: Vec<Vec3>) -> Value {
    Value::Vec3fVec(bytemuck::allocation::cast_vec(points))
}

/// Axes of `rig` that some keyed layer needs.
pub fn needed_axes(rig: &Rig) -> Vec<usize> {
    let mut needed: Vec<usize> = rig
        .layers
        .iter()
        .filter(|l| l.keys.uses_axes())
        .flat_map(|l| l.keys.axes.iter().copied())
        .collect();
    needed.sort_unstable();
    needed.dedup();
    needed
}

/// Values at `t` of the rig's axes listed in `needed` (0 for the others).
pub fn eval_axes(
    r: &StageReader,
    rig: &Rig,
    needed: &[usize],
    t: f64,
    proxy_to_world: DMat4,
    posed: &[glam::DVec3],
    camera: Option<&str>,
) -> Result<Vec<f64>> {
    let mut values = vec![0.0; rig.axes.len()];
    if needed.is_empty() {
        return Ok(values);
    }
    let [lo, hi] = bounds_f64(posed).unwrap_or([glam::DVec3::ZERO; 2]);
    let frame = AxisFrame {
        time: t,
        proxy_to_world,
        proxy_centre: (lo + hi) * 0.5,
        camera,
    };
    for &a in needed {
        values[a] = rig.axes[a].value(r, &frame)?;
    }
    Ok(values)
}

/// A layer's keyed rest points (None: its own `rest` points) and keyed opacity at `t`.
pub fn keyed_state(k: &LayerKeys, rest: &[Vec3], axis_values: &[f64], t: f64) -> (Option<Vec<Vec3>>, f32) {
    let x: Vec<f64> = k.axes.iter().map(|&a| axis_values[a]).collect();
    let x = if x.is_empty() { vec![0.0] } else { x };

    let pose_w = k.pose_points.as_ref().map(|c| c.interp.weights(&x));
    let time_w = k.time_points.as_ref().map(|c| c.interp.weights(t));
    let terms = combine(pose_w.as_ref(), time_w.as_ref());
    let points = if terms == [(1.0, Source::Rest)] {
        None
    } else {
        let arrays: Vec<(f64, &[Vec3])> = terms
            .iter()
            .map(|&(w, s)| {
                let v: &[Vec3] = match s {
                    Source::Rest => rest,
                    Source::Pose(i) => &k.pose_points.as_ref().expect("pose weights come from pose keys").values[i],
                    Source::Time(i) => &k.time_points.as_ref().expect("time weights come from time keys").values[i],
                };
                (w, v)
            })
            .collect();
        let mut out = vec![Vec3::ZERO; rest.len()];
        weighted_sum(&mut out, &arrays);
        Some(out)
    };

    let pose_w = k.pose_opacity.as_ref().map(|c| c.interp.weights(&x));
    let time_w = k.time_opacity.as_ref().map(|c| c.interp.weights(t));
    let opacity: f64 = combine(pose_w.as_ref(), time_w.as_ref())
        .iter()
        .map(|&(w, s)| {
            w * match s {
                Source::Rest => 1.0,
                Source::Pose(i) => k.pose_opacity.as_ref().expect("pose opacity keys").values[i] as f64,
                Source::Time(i) => k.time_opacity.as_ref().expect("time opacity keys").values[i] as f64,
            }
        })
        .sum();
    (points, opacity as f32)
}

/// One rig at one frame, as read from the stage.
struct RigFrame {
    posed: Vec<glam::DVec3>,
    axis_values: Vec<f64>,
    /// Per layer: proxy-local → stroke-local transform and `painterly:opacity`.
    layers: Vec<(Affine3A, f32)>,
}

/// Everything one frame needs, read serially from the stage.
struct FrameInput {
    time: f64,
    rigs: Vec<RigFrame>,
    /// Per view-dependent mesh: base points, the camera position (mesh-local), sharpness.
    views: Vec<(Vec<Vec3>, glam::DVec3, f64)>,
}

/// One frame's results.
struct FrameOutput {
    time: f64,
    /// Per stroke layer (all rigs, in order): points and per-curve opacity.
    layers: Vec<(Vec<Vec3>, Vec<f32>)>,
    /// Per rig: proxy points, when baking proxies.
    proxies: Vec<Option<Vec<Vec3>>>,
    views: Vec<Vec<Vec3>>,
}

/// The pure data of one rig that evaluation needs (shared across threads).
struct RigCompute<'a> {
    skin: &'a SkinningRest,
    bindings: &'a [Binding],
    /// Per layer: keys, rest points, authored opacity per curve, path.
    layers: Vec<(&'a LayerKeys, &'a [Vec3], &'a [f32], &'a str)>,
}

fn read_frame(
    r: &StageReader,
    rigs: &[RigBake],
    views: &[crate::usd_io::view_mesh::ViewMesh],
    t: f64,
    camera: Option<&str>,
) -> Result<FrameInput> {
    let mut rig_frames = Vec::with_capacity(rigs.len());
    for rb in rigs {
        let proxy = &rb.rig.proxy;
        let posed = proxy.posed_points(r, t)?;
        let proxy_l2w = proxy.local_to_world(r, t)?;
        let axis_values = eval_axes(r, rb.rig, &rb.needed_axes, t, proxy_l2w, &posed, camera)?;
        let mut layers = Vec::with_capacity(rb.rig.layers.len());
        for layer in &rb.rig.layers {
            let frame = affine_f32(layer.local_to_world(r, t)?.inverse() * proxy_l2w);
            layers.push((frame, layer.opacity_at(r, t)?));
        }
        rig_frames.push(RigFrame {
            posed,
            axis_values,
            layers,
        });
    }
    let mut view_frames = Vec::with_capacity(views.len());
    for vm in views {
        let base = vm.mesh.posed_points_f32(r, t)?;
        let cam = r.require_prim(vm.camera_for(camera)?)?;
        let cam_world = r.local_to_world(&cam, t)?.transform_point3(glam::DVec3::ZERO);
        let cam_local = vm.mesh.local_to_world(r, t)?.inverse().transform_point3(cam_world);
        view_frames.push((base, cam_local, vm.sharpness_at(r, t)?));
    }
    Ok(FrameInput {
        time: t,
        rigs: rig_frames,
        views: view_frames,
    })
}

fn evaluate_frame(
    rigs: &[RigCompute],
    views: &[&ViewBlend],
    input: FrameInput,
    bake_proxy: bool,
) -> Result<FrameOutput> {
    let t = input.time;
    let mut layers = Vec::new();
    let mut proxies = Vec::with_capacity(rigs.len());
    for (rc, rf) in rigs.iter().zip(input.rigs) {
        let motions = to_f32(&rc.skin.vertex_motions(&rf.posed));
        for ((binding, &(keys, rest, display, path)), (frame, opacity)) in
            rc.bindings.iter().zip(&rc.layers).zip(rf.layers)
        {
            let (keyed, keyed_opacity) = keyed_state(keys, rest, &rf.axis_values, t);
            let mut out = vec![Vec3::ZERO; rest.len()];
            skin_points(binding, &motions, &frame, keyed.as_deref().unwrap_or(rest), &mut out);
            if let Some(i) = out.iter().position(|p| !p.is_finite()) {
                return Err(Error::prim(path, format!("baked point {i} is not finite at time {t}")));
            }
            let o = opacity * keyed_opacity;
            layers.push((out, display.iter().map(|d| d * o).collect()));
        }
        proxies.push(bake_proxy.then(|| rf.posed.iter().map(|p| p.as_vec3()).collect()));
    }
    let mut view_out = Vec::with_capacity(views.len());
    for (vb, (base, cam, sharpness)) in views.iter().zip(input.views) {
        let out = vb.evaluate(t, &base, cam, sharpness)?;
        if let Some(i) = out.iter().position(|p| !p.is_finite()) {
            return Err(Error::msg(format!(
                "view-dependent point {i} is not finite at time {t}"
            )));
        }
        view_out.push(out);
    }
    Ok(FrameOutput {
        time: t,
        layers,
        proxies,
        views: view_out,
    })
}

/// Bakes `input` into `output`.
pub fn bake(input: &Path, output: &Path, opts: &BakeOptions, progress: Progress) -> Result<BakeSummary> {
    let started = Instant::now();
    check_output(input, output)?;
    let r = StageReader::open(input)?;
    r.require_resolved().map_err(|e| e.in_file(input))?;
    let result = bake_stage(&r, output, opts, progress, started);
    result.map_err(|e| e.in_file(input))
}

fn bake_stage(
    r: &StageReader,
    output: &Path,
    opts: &BakeOptions,
    progress: Progress,
    started: Instant,
) -> Result<BakeSummary> {
    let scene = Scene::read(r)?;
    let view_meshes = read_view_meshes(r, &r.prim_paths()?)?;
    let times = resolve_frames(r, opts.frames)?;
    if let Some(c) = &opts.camera {
        r.require_camera(c, "--camera")?;
    }
    for vm in &view_meshes {
        let cam = vm.camera_for(opts.camera.as_deref())?;
        if opts.camera.is_none() {
            check_camera(r, cam, &format!("{}.painterly:camera", vm.path))?;
        }
    }
    let rigs: Vec<RigBake> = scene.rigs.iter().map(prepare).collect();

    // Read: everything each frame needs from the stage, serially (the stage
    // is single-threaded).
    let mut inputs = Vec::with_capacity(times.len());
    for (fi, &t) in times.iter().enumerate() {
        inputs.push(read_frame(r, &rigs, &view_meshes, t, opts.camera.as_deref())?);
        progress(fi + 1, 2 * times.len());
    }

    // Evaluate: frames in parallel over pure data.
    let done = std::sync::atomic::AtomicUsize::new(times.len());
    let computes: Vec<RigCompute> = rigs
        .iter()
        .map(|rb| RigCompute {
            skin: &rb.skin,
            bindings: &rb.bindings,
            layers: rb
                .rig
                .layers
                .iter()
                .map(|l| {
                    (
                        &l.keys,
                        l.rest_points.as_slice(),
                        &l.display_opacity[..],
                        l.path.as_str(),
                    )
                })
                .collect(),
        })
        .collect();
    let blends: Vec<&ViewBlend> = view_meshes.iter().map(|v| &v.blend).collect();
    let outputs: Vec<FrameOutput> = inputs
        .into_par_iter()
        .map(|input| {
            let out = evaluate_frame(&computes, &blends, input, opts.bake_proxy);
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, 2 * times.len());
            out
        })
        .collect::<Result<_>>()?;

    // Assemble samples per attribute, moving the arrays.
    let nlayers: usize = rigs.iter().map(|rb| rb.rig.layers.len()).sum();
    let mut pts_samples: Vec<Vec<(f64, Value)>> = vec![Vec::with_capacity(times.len()); nlayers];
    let mut ext_samples: Vec<Vec<(f64, Value)>> = vec![Vec::with_capacity(times.len()); nlayers];
    let mut opa_samples: Vec<Vec<(f64, Value)>> = vec![Vec::with_capacity(times.len()); nlayers];
    let mut proxy_pts: Vec<Vec<(f64, Value)>> = vec![Vec::new(); rigs.len()];
    let mut proxy_ext: Vec<Vec<(f64, Value)>> = vec![Vec::new(); rigs.len()];
    let mut view_pts: Vec<Vec<(f64, Value)>> = vec![Vec::with_capacity(times.len()); view_meshes.len()];
    let mut view_ext: Vec<Vec<(f64, Value)>> = vec![Vec::with_capacity(times.len()); view_meshes.len()];
    for out in outputs {
        let t = out.time;
        for (li, (pts, opa)) in out.layers.into_iter().enumerate() {
            ext_samples[li].push((t, extent_value(&pts)));
            pts_samples[li].push((t, points_value(pts)));
            opa_samples[li].push((t, Value::FloatVec(opa)));
        }
        for (ri, pts) in out.proxies.into_iter().enumerate() {
            if let Some(pts) = pts {
                proxy_ext[ri].push((t, extent_value(&pts)));
                proxy_pts[ri].push((t, points_value(pts)));
            }
        }
        for (vi, pts) in out.views.into_iter().enumerate() {
            view_ext[vi].push((t, extent_value(&pts)));
            view_pts[vi].push((t, points_value(pts)));
        }
    }

    let mut layer_out = OverLayer::new(r.metadata());
    let mut li = 0;
    let (mut strokes, mut points) = (0, 0);
    for (ri, rb) in rigs.iter().enumerate() {
        for layer in &rb.rig.layers {
            layer_out.set_samples(
                &layer.path,
                "points",
                "point3f[]",
                std::mem::take(&mut pts_samples[li]),
                vec![],
            );
            layer_out.set_samples(
                &layer.path,
                "extent",
                "float3[]",
                std::mem::take(&mut ext_samples[li]),
                vec![],
            );
            layer_out.set_samples(
                &layer.path,
                "primvars:displayOpacity",
                "float[]",
                std::mem::take(&mut opa_samples[li]),
                vec![("interpolation", Value::Token("uniform".into()))],
            );
            strokes += layer.curve_counts.len();
            points += layer.num_points();
            li += 1;
        }
        if opts.bake_proxy {
            let path = &rb.rig.proxy.path;
            layer_out.set_samples(path, "points", "point3f[]", std::mem::take(&mut proxy_pts[ri]), vec![]);
            layer_out.set_samples(path, "extent", "float3[]", std::mem::take(&mut proxy_ext[ri]), vec![]);
            if rb.rig.proxy.is_skinned() {
                layer_out.block_relationship(path, "skel:skeleton");
            }
        }
    }
    for (vi, vm) in view_meshes.iter().enumerate() {
        layer_out.set_samples(
            &vm.path,
            "points",
            "point3f[]",
            std::mem::take(&mut view_pts[vi]),
            vec![],
        );
        layer_out.set_samples(
            &vm.path,
            "extent",
            "float3[]",
            std::mem::take(&mut view_ext[vi]),
            vec![],
        );
        if vm.mesh.is_skinned() {
            layer_out.block_relationship(&vm.path, "skel:skeleton");
        }
    }
    layer_out.write(output)?;
    Ok(BakeSummary {
        input: r.file.clone(),
        output: output.to_path_buf(),
        frames: times.len(),
        rigs: rigs.len(),
        view_meshes: view_meshes.len(),
        layers: nlayers,
        strokes,
        points,
        seconds: started.elapsed().as_secs_f64(),
    })
}
