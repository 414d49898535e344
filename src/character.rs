//! A painted character resolved for evaluation: rest data computed once,
//! then any frame read and evaluated on demand.
//!
//! This is the one evaluator behind every front door: `bake` streams frames
//! through it into a layer, `inspect` dry-runs it, the Python package and the
//! preview server call it for single frames (with axis values overridden for
//! what-if checks). Like OpenSubdiv's stencil tables, everything that depends
//! only on the rest pose (one-rings, rest centroids, bindings, viewpoint
//! hulls, resolved cameras) is computed in [`Character::open`]; a frame then
//! costs one read ([`Character::read_frame`], serial: the stage is
//! single-threaded) and one pure evaluation ([`Character::evaluate`], safe to
//! run on many frames in parallel).

use std::path::Path;

use glam::{Affine3A, DMat4, DVec3, Vec3};

use crate::bind::{Binding, ClosestPoint};
use crate::error::{Error, Result};
use crate::keys::{combine, Source};
use crate::mesh::{bounds_f64, fan_triangulate, OneRings};
use crate::skinning::{skin_blended_points, skin_normals, to_f32, SkinningRest};
use crate::usd_io::axes::AxisFrame;
use crate::usd_io::binding_cache::BindingCache;
use crate::usd_io::scene::{LayerKeys, Proxy, Rig, Scene, StrokeNormals};
use crate::usd_io::stage::{Prim, StageReader};
use crate::usd_io::view_mesh::{check_camera, read_view_meshes, sharpness_at, ViewBlend, ViewMesh};
use crate::words::plural;

/// One stroke layer's pure data: what evaluation needs, nothing of the stage.
pub struct LayerModel {
    pub path: String,
    /// Rest positions, proxy-local.
    pub rest_points: Vec<Vec3>,
    /// The binding of every point (cached in the file, or computed).
    pub binding: Binding,
    pub keys: LayerKeys,
    /// Authored `primvars:displayOpacity`, one per curve.
    pub display_opacity: Vec<f32>,
    /// Points per stroke.
    pub curve_counts: Vec<u32>,
    /// Whether the input authors `primvars:displayOpacity:indices` (the
    /// bake blocks them: it writes one value per curve).
    pub display_indexed: bool,
    /// Rest normals the bake turns with the strokes, proxy-local, when the
    /// layer has them ([`crate::usd_io::scene::StrokeLayer::rest_normals`]).
    pub rest_normals: Option<StrokeNormals>,
}

/// One rig's pure data: the skinning stencils and its layers.
pub struct RigModel {
    pub path: String,
    pub proxy_path: String,
    /// Whether the proxy is skinned (a bake that writes it blocks `skel:skeleton`).
    pub proxy_skinned: bool,
    /// Whether the proxy has authored normals UsdSkel rewrites (a bake that
    /// writes the proxy writes them too).
    pub proxy_normals: bool,
    pub skin: SkinningRest,
    pub layers: Vec<LayerModel>,
    /// Axis prim paths, in the order of [`RigFrame::axis_values`].
    pub axes: Vec<String>,
    /// Axes (indices into `axes`) that some keyed layer needs.
    pub needed_axes: Vec<usize>,
}

/// One view-dependent mesh's pure data.
pub struct ViewModel {
    pub path: String,
    pub blend: ViewBlend,
    /// Whether the base is skinned (a bake blocks its `skel:skeleton`).
    pub skinned: bool,
    /// The camera it is viewed from.
    pub camera: String,
}

/// The pure half of a character: everything evaluation needs, thread-safe,
/// so frames evaluate in parallel while the stage stays on one thread.
pub struct Model {
    pub rigs: Vec<RigModel>,
    pub views: Vec<ViewModel>,
}

/// A painted character ready to evaluate: the stage side (prims read per
/// frame) and the pure [`Model`].
pub struct Character {
    pub reader: StageReader,
    pub model: Model,
    /// The camera for `viewDirection` axes without a source (`--camera`).
    pub camera: Option<String>,
    /// Read the deformed normals of proxies that have them with each frame
    /// (what `--bake-proxy` writes); off by default.
    pub proxy_normals: bool,
    /// Whether some layer's binding was computed here (closest point), not
    /// authored in the stage nor taken from a binding cache.
    pub binding_computed: bool,
    /// Stage side of each rig: proxy, layer prims and axes. Its layers'
    /// rest points, keys and bindings have moved into `model`.
    rigs: Vec<Rig>,
    /// Stage side of each view-dependent mesh: the base model and camera.
    views: Vec<(ViewBase, Prim)>,
}

/// What a view-dependent mesh reads from the stage each frame.
struct ViewBase {
    mesh: Proxy,
    path: String,
}

/// Axis values by axis prim path, in axis units (SPEC §4).
pub type Configuration = std::collections::BTreeMap<String, f64>;

/// One rig at one frame, as read from the stage.
pub struct RigFrame {
    /// Posed proxy points, proxy-local.
    pub posed: Vec<DVec3>,
    /// The proxy's deformed normals, proxy-local, when read
    /// ([`Character::proxy_normals`]) and it has some.
    pub normals: Option<Vec<Vec3>>,
    /// Every axis of the rig (indices as `Rig::axes`); 0 for axes no keyed
    /// layer needs, unless read with [`Character::configuration`].
    pub axis_values: Vec<f64>,
    /// Per layer: proxy-local → stroke-local transform, `painterly:opacity`,
    /// the largest `widths` value (for the extent) and, when time-sampled,
    /// `primvars:displayOpacity` per curve.
    pub layers: Vec<(Affine3A, f32, f32, Option<Vec<f32>>)>,
}

/// One view-dependent mesh at one frame, as read from the stage.
pub struct ViewFrame {
    pub base: Vec<Vec3>,
    /// The camera's position in the mesh's local space.
    pub camera_local: DVec3,
    pub sharpness: f64,
}

/// Everything one frame needs, read from the stage; evaluation is pure.
pub struct FrameInput {
    pub time: f64,
    pub rigs: Vec<RigFrame>,
    pub views: Vec<ViewFrame>,
}

/// One stroke layer's result at one frame.
pub struct LayerFrame {
    /// Stroke-local points.
    pub points: Vec<Vec3>,
    /// Per curve: authored displayOpacity × layer opacity × keyed opacity.
    pub opacity: Vec<f32>,
    /// The largest `widths` value at this time: the extent's padding
    /// ([`crate::extent::curves_extent`]).
    pub max_width: f32,
    /// The points' box, [`crate::extent::point_based_extent`] of `points`.
    pub bounds: [Vec3; 2],
    /// Stroke-local normals, when the layer has rest normals.
    pub normals: Option<Vec<Vec3>>,
}

/// One frame's results.
pub struct FrameOutput {
    pub time: f64,
    /// Per stroke layer, all rigs in order.
    pub layers: Vec<LayerFrame>,
    /// Per rig: the posed proxy points (mesh-local), when asked for.
    pub proxies: Vec<Option<Vec<Vec3>>>,
    /// Per rig: the proxy's deformed normals, when asked for and read.
    pub proxy_normals: Vec<Option<Vec<Vec3>>>,
    /// Per view-dependent mesh: its points.
    pub views: Vec<Vec<Vec3>>,
}

/// The `-v` line for a stage opened from `path` since `started`.
pub(crate) fn log_opened(path: &Path, reader: &StageReader, started: std::time::Instant) {
    crate::vlog!(
        "opened {} ({}) in {:.3} s",
        path.display(),
        plural(reader.layer_count(), "layer"),
        started.elapsed().as_secs_f64()
    );
}

impl Character {
    /// Opens `path` and resolves everything that does not change per frame.
    pub fn open(path: &Path, camera: Option<&str>) -> Result<Character> {
        let started = std::time::Instant::now();
        let reader = StageReader::open(path)?;
        log_opened(path, &reader, started);
        Character::from_reader(reader, camera).map_err(|e| e.in_file(path))
    }

    /// Resolves a character on an opened stage: reads and validates every
    /// rig, layer, key and view-dependent mesh, resolves cameras, and
    /// computes the rest data (one-rings, centroids, bindings).
    pub fn from_reader(reader: StageReader, camera: Option<&str>) -> Result<Character> {
        Character::from_reader_with(reader, camera, None)
    }

    /// Like [`Character::from_reader`], taking the binding of layers that
    /// have none authored from `cache` where it holds one.
    pub fn from_reader_with(
        reader: StageReader,
        camera: Option<&str>,
        cache: Option<&BindingCache>,
    ) -> Result<Character> {
        let started = std::time::Instant::now();
        // A rig or strokes from a missing asset would bake something else.
        reader.require_resolved()?;
        let mut scene = Scene::read(&reader)?;
        if let Some(cache) = cache {
            let filled = cache.fill(&mut scene.rigs);
            crate::vlog!(
                "took the binding of {} from the binding cache",
                plural(filled, "stroke layer")
            );
        }
        let binding_computed = scene
            .rigs
            .iter()
            .any(|r| r.layers.iter().any(|l| l.cached_binding.is_none()));
        let view_meshes = read_view_meshes(&reader, &reader.prim_paths()?)?;
        if let Some(c) = camera {
            reader.require_camera(c, "--camera")?;
        }
        let mut views = Vec::with_capacity(view_meshes.len());
        let mut view_models = Vec::with_capacity(view_meshes.len());
        for vm in view_meshes {
            let camera_path = vm.camera_for(camera)?.to_string();
            if camera.is_none() {
                check_camera(&reader, &camera_path, &vm.path)?;
            }
            let camera_prim = reader.require_prim(&camera_path)?;
            let ViewMesh { path, mesh, blend, .. } = vm;
            view_models.push(ViewModel {
                path: path.clone(),
                blend,
                skinned: mesh.is_skinned(),
                camera: camera_path,
            });
            views.push((ViewBase { mesh, path }, camera_prim));
        }
        crate::vlog!(
            "read {}, {}, {} in {:.3} s",
            plural(scene.rigs.len(), "rig"),
            plural(scene.rigs.iter().map(|r| r.layers.len()).sum(), "stroke layer"),
            plural(views.len(), "view-dependent mesh"),
            started.elapsed().as_secs_f64()
        );
        let started = std::time::Instant::now();
        let mut rigs = scene.rigs;
        let rig_models: Vec<RigModel> = rigs.iter_mut().map(RigModel::take_from).collect();
        crate::vlog!(
            "bound {} (rest data of {}) in {:.3} s",
            plural(rig_models.iter().map(|r| r.num_points()).sum(), "stroke point"),
            plural(rig_models.iter().map(|r| r.skin.vertex_count()).sum(), "proxy vertex"),
            started.elapsed().as_secs_f64()
        );
        Ok(Character {
            reader,
            model: Model {
                rigs: rig_models,
                views: view_models,
            },
            camera: camera.map(str::to_string),
            proxy_normals: false,
            binding_computed,
            rigs,
            views,
        })
    }

    /// Reads what frame `t` needs (serial: the stage is single-threaded).
    pub fn read_frame(&self, t: f64) -> Result<FrameInput> {
        self.read_frame_axes(t, false, None)
    }

    /// Like [`Character::read_frame`], but measures every axis, not only
    /// those a keyed layer needs (for reports and what-if overrides).
    pub fn read_frame_all_axes(&self, t: f64) -> Result<FrameInput> {
        self.read_frame_axes(t, true, None)
    }

    /// Reads frame `t` as seen from a world-space `eye` instead of the
    /// cameras: every viewDirection axis (even one with its own `source`)
    /// and every view-dependent mesh is measured from `eye` (a live
    /// preview's orbit camera; `None` keeps the cameras). Measures every
    /// axis, then applies `overrides` as [`Character::read_frame_with`] does.
    pub fn read_frame_seen_from(&self, t: f64, overrides: &Configuration, eye: Option<DVec3>) -> Result<FrameInput> {
        if let Some(e) = eye.filter(|e| !e.is_finite()) {
            return Err(Error::msg(format!("eye position {e} is not finite")));
        }
        let mut input = self.read_frame_axes(t, true, eye)?;
        self.apply_overrides(&mut input, overrides)?;
        Ok(input)
    }

    fn read_frame_axes(&self, t: f64, all_axes: bool, eye: Option<DVec3>) -> Result<FrameInput> {
        let r = &self.reader;
        let mut rigs = Vec::with_capacity(self.rigs.len());
        for (rig, model) in self.rigs.iter().zip(&self.model.rigs) {
            let proxy = &rig.proxy;
            let posed = proxy.posed_points(r, t)?;
            let proxy_l2w = proxy.local_to_world(r, t)?;
            let every: Vec<usize>;
            let axes = if all_axes {
                every = (0..rig.axes.len()).collect();
                &every
            } else {
                &model.needed_axes
            };
            let frame = AxisFrame {
                time: t,
                proxy_to_world: proxy_l2w,
                proxy_centre: DVec3::ZERO,
                proxy_extent: 0.0,
                camera: self.camera.as_deref(),
                eye,
            };
            let axis_values = measure_axes(r, rig, axes, &posed, frame)?;
            let mut layers = Vec::with_capacity(rig.layers.len());
            for layer in &rig.layers {
                let frame = Affine3A::from_mat4((layer.local_to_world(r, t)?.inverse() * proxy_l2w).as_mat4());
                let display = layer.display_opacity_at(r, t)?;
                layers.push((frame, layer.opacity_at(r, t)?, layer.max_width_at(t), display));
            }
            rigs.push(RigFrame {
                posed,
                normals: if self.proxy_normals {
                    proxy.posed_normals(r, t)?
                } else {
                    None
                },
                axis_values,
                layers,
            });
        }
        let mut views = Vec::with_capacity(self.views.len());
        for (base, camera) in &self.views {
            let points = base.mesh.posed_points_f32(r, t)?;
            let cam_world = match eye {
                Some(e) => e,
                None => r.local_to_world(camera, t)?.transform_point3(DVec3::ZERO),
            };
            let camera_local = base.mesh.local_to_world(r, t)?.inverse().transform_point3(cam_world);
            views.push(ViewFrame {
                base: points,
                camera_local,
                sharpness: sharpness_at(r, &base.path, t)?,
            });
        }
        Ok(FrameInput { time: t, rigs, views })
    }

    /// Reads and evaluates frame `t` (see [`Model::evaluate`]).
    pub fn evaluate(&self, t: f64, with_proxies: bool) -> Result<FrameOutput> {
        self.model.evaluate(self.read_frame(t)?, with_proxies)
    }

    /// The configuration at `t`: every axis of every rig, by prim path, in
    /// axis units (what the stage says; see SPEC §4).
    pub fn configuration(&self, t: f64) -> Result<Configuration> {
        let input = self.read_frame_all_axes(t)?;
        let mut c = Configuration::new();
        for (rig, rf) in self.model.rigs.iter().zip(&input.rigs) {
            for (path, &v) in rig.axes.iter().zip(&rf.axis_values) {
                c.insert(path.clone(), v);
            }
        }
        Ok(c)
    }

    /// Reads frame `t` with some axes set to given values instead of what
    /// the stage says (a what-if pose). Every overridden path must be an
    /// axis of some rig.
    pub fn read_frame_with(&self, t: f64, overrides: &Configuration) -> Result<FrameInput> {
        let mut input = self.read_frame(t)?;
        self.apply_overrides(&mut input, overrides)?;
        Ok(input)
    }

    fn apply_overrides(&self, input: &mut FrameInput, overrides: &Configuration) -> Result<()> {
        for (path, &value) in overrides {
            if !value.is_finite() {
                return Err(Error::prim(path, format!("axis value {value} is not finite")));
            }
            let mut found = false;
            for (rig, rf) in self.model.rigs.iter().zip(&mut input.rigs) {
                if let Some(i) = rig.axes.iter().position(|a| a == path) {
                    rf.axis_values[i] = value;
                    found = true;
                }
            }
            if !found {
                return Err(Error::prim(path, "is not an axis of any rig in this character"));
            }
        }
        Ok(())
    }

    /// Every axis prim path of every rig, each once, in rig then axis order
    /// (the keys of [`Character::configuration`]).
    pub fn axes(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for a in self.model.rigs.iter().flat_map(|r| &r.axes) {
            if !out.contains(a) {
                out.push(a.clone());
            }
        }
        out
    }

    /// Evaluates frame `t` with axis values overridden (a what-if pose, see
    /// [`Character::read_frame_with`]); with no overrides, exactly
    /// [`Character::evaluate`].
    pub fn evaluate_with(&self, t: f64, overrides: &Configuration, with_proxies: bool) -> Result<FrameOutput> {
        self.model.evaluate(self.read_frame_with(t, overrides)?, with_proxies)
    }
}

impl Model {
    /// Number of stroke layers over all rigs.
    pub fn num_layers(&self) -> usize {
        self.rigs.iter().map(|r| r.layers.len()).sum()
    }

    /// Evaluates a frame: skinned, keyed stroke points and opacities, proxy
    /// points (when `with_proxies`), view-dependent meshes. Pure: no stage
    /// access, so frames can be evaluated in parallel.
    pub fn evaluate(&self, input: FrameInput, with_proxies: bool) -> Result<FrameOutput> {
        let t = input.time;
        let mut layers = Vec::with_capacity(self.num_layers());
        let mut proxies = Vec::with_capacity(self.rigs.len());
        let mut proxy_normals = Vec::with_capacity(self.rigs.len());
        for (rig, rf) in self.rigs.iter().zip(input.rigs) {
            let motions = to_f32(&rig.skin.vertex_motions(&rf.posed));
            for (layer, (frame, opacity, max_width, display)) in rig.layers.iter().zip(rf.layers) {
                let rest = &layer.rest_points;
                let (keyed, keyed_opacity) = keyed_state(&layer.keys, rest, &rf.axis_values, t);
                let mut points = vec![Vec3::ZERO; rest.len()];
                let skinned = skin_blended_points(&layer.binding, &motions, &frame, &keyed, &mut points);
                if !skinned.finite {
                    let i = points.iter().position(|p| !p.is_finite()).unwrap_or(0);
                    return Err(Error::prim(
                        &layer.path,
                        format!("baked point {i} is not finite at time {t}"),
                    ));
                }
                let normals = layer
                    .rest_normals
                    .as_ref()
                    .map(|n| skin_normals(&layer.binding, &motions, &frame, &n.rest));
                let o = opacity * keyed_opacity;
                layers.push(LayerFrame {
                    points,
                    opacity: display
                        .as_deref()
                        .unwrap_or(&layer.display_opacity)
                        .iter()
                        .map(|d| d * o)
                        .collect(),
                    max_width,
                    bounds: skinned.extent,
                    normals,
                });
            }
            proxies.push(with_proxies.then(|| rf.posed.iter().map(|p| p.as_vec3()).collect()));
            proxy_normals.push(rf.normals.filter(|_| with_proxies));
        }
        let mut views = Vec::with_capacity(self.views.len());
        for (view, vf) in self.views.iter().zip(input.views) {
            let out = view.blend.evaluate(t, &vf.base, vf.camera_local, vf.sharpness)?;
            if let Some(i) = out.iter().position(|p| !p.is_finite()) {
                return Err(Error::prim(
                    &view.path,
                    format!("view-dependent point {i} is not finite at time {t}"),
                ));
            }
            views.push(out);
        }
        Ok(FrameOutput {
            time: t,
            layers,
            proxies,
            proxy_normals,
            views,
        })
    }
}

impl RigModel {
    /// Moves a rig's pure data out of it and computes its rest data:
    /// one-rings and centroids, and a binding per layer (the layer's cached
    /// one, else the closest point on the rest proxy).
    fn take_from(rig: &mut Rig) -> RigModel {
        let proxy = &rig.proxy;
        let rings = OneRings::new(proxy.rest.len(), &proxy.face_counts, &proxy.face_indices);
        let skin = SkinningRest::new(rings, &proxy.rest);
        let needs_bvh = rig.layers.iter().any(|l| l.cached_binding.is_none());
        let bvh = needs_bvh.then(|| {
            let tris = fan_triangulate(&proxy.face_counts, &proxy.face_indices);
            ClosestPoint::new(&proxy.rest, &tris)
        });
        let needed_axes = needed_axes(rig);
        // Every uncached layer's points in one query batch: one parallel
        // job instead of one per layer, and one spatial order over the
        // whole rig, so each query starts from a near neighbour's triangle.
        let fresh = bvh
            .as_ref()
            .map(|bvh| {
                let uncached = rig.layers.iter().filter(|l| l.cached_binding.is_none());
                let all: Vec<Vec3> = uncached.flat_map(|l| l.rest_points.iter().copied()).collect();
                bvh.bind(&all)
            })
            .unwrap_or_default();
        let (mut vertices, mut weights) = (fresh.vertices.into_iter(), fresh.weights.into_iter());
        let layers = rig
            .layers
            .iter_mut()
            .map(|l| {
                let rest_points = std::mem::take(&mut l.rest_points);
                let binding = match l.cached_binding.take() {
                    Some(b) => b,
                    None => Binding {
                        vertices: vertices.by_ref().take(rest_points.len()).collect(),
                        weights: weights.by_ref().take(rest_points.len()).collect(),
                    },
                };
                LayerModel {
                    path: l.path.clone(),
                    rest_points,
                    binding,
                    keys: std::mem::take(&mut l.keys),
                    display_opacity: std::mem::take(&mut l.display_opacity),
                    curve_counts: l.curve_counts.clone(),
                    display_indexed: l.display_indexed,
                    rest_normals: l.rest_normals.take(),
                }
            })
            .collect();
        RigModel {
            path: rig.path.clone(),
            proxy_path: rig.proxy.path.clone(),
            proxy_skinned: rig.proxy.is_skinned(),
            proxy_normals: rig.proxy.has_deformed_normals(),
            skin,
            layers,
            axes: rig.axes.iter().map(|a| a.path.clone()).collect(),
            needed_axes,
        }
    }

    /// Stroke points over all layers.
    pub fn num_points(&self) -> usize {
        self.layers.iter().map(|l| l.rest_points.len()).sum()
    }
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
    posed: &[DVec3],
    camera: Option<&str>,
) -> Result<Vec<f64>> {
    let frame = AxisFrame {
        time: t,
        proxy_to_world,
        proxy_centre: DVec3::ZERO,
        proxy_extent: 0.0,
        camera,
        eye: None,
    };
    measure_axes(r, rig, needed, posed, frame)
}

/// Values of the rig's axes listed in `needed` (0 for the others),
/// measured against `frame`, whose `proxy_centre` is set from `posed`.
pub fn measure_axes(
    r: &StageReader,
    rig: &Rig,
    needed: &[usize],
    posed: &[DVec3],
    frame: AxisFrame,
) -> Result<Vec<f64>> {
    let mut values = vec![0.0; rig.axes.len()];
    if needed.is_empty() {
        return Ok(values);
    }
    let [lo, hi] = bounds_f64(posed).unwrap_or([DVec3::ZERO; 2]);
    let frame = AxisFrame {
        proxy_centre: (lo + hi) * 0.5,
        proxy_extent: (hi - lo).length(),
        ..frame
    };
    let mut reads = crate::usd_io::axes::FrameReads::default();
    for &a in needed {
        values[a] = rig.axes[a].value(r, &frame, &mut reads)?;
    }
    Ok(values)
}

/// One channel's blend: (weight, source) terms.
type Terms = Vec<(f64, Source)>;

/// The blend terms of a layer's two channels at one configuration and time:
/// (position terms, opacity terms).
fn key_terms(k: &LayerKeys, axis_values: &[f64], t: f64) -> (Terms, Terms) {
    let x = k.configuration(axis_values);
    let pose_w = k.pose_points.as_ref().map(|c| c.interp.weights(&x));
    let time_w = k.time_points.as_ref().map(|c| c.interp.weights(t));
    let points = combine(pose_w.as_ref(), time_w.as_ref());
    let pose_w = k.pose_opacity.as_ref().map(|c| c.interp.weights(&x));
    let time_w = k.time_opacity.as_ref().map(|c| c.interp.weights(t));
    let opacity = combine(pose_w.as_ref(), time_w.as_ref());
    (points, opacity)
}

/// A layer's keyed rest points as weighted arrays (weights summing to 1; a
/// layer without keys: `rest` with weight 1), for
/// [`skin_blended_points`], and its keyed opacity at `t`.
pub fn keyed_state<'a>(
    k: &'a LayerKeys,
    rest: &'a [Vec3],
    axis_values: &[f64],
    t: f64,
) -> (Vec<(f64, &'a [Vec3])>, f32) {
    let (point_terms, opacity_terms) = key_terms(k, axis_values, t);
    let points = point_terms
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
    let opacity: f64 = opacity_terms
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

/// How much each key weighs in a layer's blend right now (Bassett Fig. 9's
/// basis functions at the current configuration), per channel: key prim path
/// (or `None` for the layer's own rest value) and weight. Weights of a
/// channel sum to 1.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KeyWeights {
    pub position: Vec<(Option<String>, f64)>,
    pub opacity: Vec<(Option<String>, f64)>,
}

/// The key weights of a layer at a configuration (`axis_values` in the
/// rig's axis order) and time.
pub fn key_weights(k: &LayerKeys, axis_values: &[f64], t: f64) -> KeyWeights {
    let (points, opacity) = key_terms(k, axis_values, t);
    let name = |s: Source, pose: Option<&Vec<String>>, time: Option<&Vec<String>>| match s {
        Source::Rest => None,
        Source::Pose(i) => pose.map(|p| p[i].clone()),
        Source::Time(i) => time.map(|p| p[i].clone()),
    };
    KeyWeights {
        position: points
            .into_iter()
            .map(|(w, s)| {
                let n = name(
                    s,
                    k.pose_points.as_ref().map(|c| &c.paths),
                    k.time_points.as_ref().map(|c| &c.paths),
                );
                (n, w)
            })
            .collect(),
        opacity: opacity
            .into_iter()
            .map(|(w, s)| {
                let n = name(
                    s,
                    k.pose_opacity.as_ref().map(|c| &c.paths),
                    k.time_opacity.as_ref().map(|c| &c.paths),
                );
                (n, w)
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::memory::open_bytes;

    /// A static quad proxy, one stroke keyed to a knob animated 0 → 1 over
    /// frames 1..11: pose keys at knob 0 ("low") and knob 1 ("high").
    const KNOB: &str = r#"#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 11
)
def Xform "World" {
    def Scope "Controls" {
        double knob.timeSamples = { 1: 0, 11: 1 }
    }
    def Mesh "Proxy" {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    }
    def Xform "Paint" (prepend apiSchemas = ["PainterlyRigAPI"]) {
        rel painterly:proxy = </World/Proxy>
        def PainterlyAxis "knob" {
            uniform token kind = "attribute"
            rel source = </World/Controls.knob>
        }
        def BasisCurves "Hair" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"]) {
            int[] curveVertexCounts = [3]
            point3f[] points = [(0.25, 0.25, 0), (0.5, 0.5, 0), (0.75, 0.5, 0)]
            def PainterlyPoseKey "low" {
                float[] coordinates = [0]
                point3f[] points = [(0.25, 0.25, 0), (0.5, 0.5, 0), (0.75, 0.5, 0)]
            }
            def PainterlyPoseKey "high" {
                float[] coordinates = [1]
                point3f[] points = [(0.25, 0.75, 0), (0.5, 0.75, 0.5), (0.75, 0.75, 0)]
            }
        }
    }
}
"#;

    fn cfg(pairs: &[(&str, f64)]) -> Configuration {
        pairs.iter().map(|&(a, v)| (a.to_string(), v)).collect()
    }

    fn knob() -> Character {
        let path = std::env::temp_dir().join("painterly_configuration_test.usda");
        let r = open_bytes(KNOB.as_bytes().to_vec(), &path).unwrap();
        Character::from_reader(r, None).unwrap()
    }

    fn close(a: &[Vec3], b: &[[f32; 3]]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| (*p - Vec3::from(*q)).abs().max_element() < 1e-6)
    }

    const LOW: [[f32; 3]; 3] = [[0.25, 0.25, 0.0], [0.5, 0.5, 0.0], [0.75, 0.5, 0.0]];
    const HIGH: [[f32; 3]; 3] = [[0.25, 0.75, 0.0], [0.5, 0.75, 0.5], [0.75, 0.75, 0.0]];

    #[test]
    fn configuration_reads_every_axis_from_the_stage() {
        let ch = knob();
        assert_eq!(ch.axes(), ["/World/Paint/knob"]);
        // USD's linear interpolation of the knob's samples: (6 - 1) / 10.
        assert_eq!(ch.configuration(6.0).unwrap(), cfg(&[("/World/Paint/knob", 0.5)]));
        assert_eq!(ch.configuration(11.0).unwrap().get("/World/Paint/knob"), Some(&1.0));
    }

    #[test]
    fn overrides_replace_the_stage_value_and_nothing_else() {
        let ch = knob();
        // Without overrides: the same bits as a bake's evaluation.
        let plain = ch.evaluate(6.0, false).unwrap();
        let same = ch.evaluate_with(6.0, &Configuration::new(), false).unwrap();
        assert_eq!(plain.layers[0].points, same.layers[0].points);
        // The stage's own value as an override changes nothing.
        let echo = ch.evaluate_with(6.0, &ch.configuration(6.0).unwrap(), false).unwrap();
        assert_eq!(plain.layers[0].points, echo.layers[0].points);
        // At frame 1 the knob is 0 (the "low" key); overridden to 1 the
        // stroke takes the "high" key's shape (smooth Voronoi interpolates
        // its keys; the static proxy does not move it), and back.
        assert!(close(&ch.evaluate(1.0, false).unwrap().layers[0].points, &LOW));
        let high = cfg(&[("/World/Paint/knob", 1.0)]);
        assert!(close(
            &ch.evaluate_with(1.0, &high, false).unwrap().layers[0].points,
            &HIGH
        ));
        let low = cfg(&[("/World/Paint/knob", 0.0)]);
        assert!(close(
            &ch.evaluate_with(11.0, &low, false).unwrap().layers[0].points,
            &LOW
        ));
        assert!(close(&ch.evaluate(11.0, false).unwrap().layers[0].points, &HIGH));
    }

    #[test]
    fn overrides_of_unknown_axes_or_non_finite_values_are_errors() {
        let ch = knob();
        let e = ch
            .evaluate_with(1.0, &cfg(&[("/World/Paint/nope", 1.0)]), false)
            .err()
            .unwrap();
        assert_eq!(e.prim.as_deref(), Some("/World/Paint/nope"));
        assert!(e.message.contains("not an axis"), "{e}");
        let e = ch
            .evaluate_with(1.0, &cfg(&[("/World/Paint/knob", f64::NAN)]), false)
            .err()
            .unwrap();
        assert!(e.message.contains("not finite"), "{e}");
    }

    /// Two curves with authored per-curve displayOpacity, an animated
    /// `painterly:opacity` and opacity keys on the knob (SPEC §4: the baked
    /// opacity is their product, per curve).
    const OPACITY: &str = r#"#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 11
)
def Xform "World" {
    def Scope "Controls" {
        double knob.timeSamples = { 1: 0, 11: 1 }
    }
    def Mesh "Proxy" {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    }
    def Xform "Paint" (prepend apiSchemas = ["PainterlyRigAPI"]) {
        rel painterly:proxy = </World/Proxy>
        def PainterlyAxis "knob" {
            uniform token kind = "attribute"
            rel source = </World/Controls.knob>
        }
        def BasisCurves "Hair" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"]) {
            int[] curveVertexCounts = [2, 2]
            point3f[] points = [(0.25, 0.25, 0), (0.5, 0.5, 0), (0.5, 0.25, 0), (0.75, 0.5, 0)]
            float[] primvars:displayOpacity = [0.5, 0.8] (interpolation = "uniform")
            float painterly:opacity.timeSamples = { 1: 0.5, 11: 0.25 }
            def PainterlyPoseKey "faint" {
                float[] coordinates = [0]
                float opacity = 0.4
            }
            def PainterlyPoseKey "full" {
                float[] coordinates = [1]
                float opacity = 1
            }
        }
    }
}
"#;

    #[test]
    fn baked_opacity_is_display_times_layer_times_keyed() {
        let path = std::env::temp_dir().join("painterly_opacity_test.usda");
        let ch = Character::from_reader(open_bytes(OPACITY.as_bytes().to_vec(), &path).unwrap(), None).unwrap();
        // At a key the keyed opacity is that key's (smooth Voronoi
        // interpolates); painterly:opacity is USD-interpolated linearly.
        for (t, layer, keyed) in [(1.0, 0.5, 0.4), (11.0, 0.25, 1.0)] {
            let out = ch.evaluate(t, false).unwrap();
            let got = &out.layers[0].opacity;
            let want = [0.5 * layer * keyed, 0.8 * layer * keyed];
            assert_eq!(got.len(), 2);
            for (g, w) in got.iter().zip(want) {
                assert!((*g as f64 - w).abs() < 1e-6, "t {t}: {got:?} != {want:?}");
            }
        }
        // Halfway the layer opacity is (0.5 + 0.25) / 2 and the keyed one
        // lies strictly between the keys': the product still scales both
        // curves alike.
        let mid = ch.evaluate(6.0, false).unwrap();
        let o = &mid.layers[0].opacity;
        let keyed = o[0] as f64 / (0.5 * 0.375);
        assert!(keyed > 0.4 && keyed < 1.0, "{o:?}");
        assert!((o[1] as f64 - 0.8 * 0.375 * keyed).abs() < 1e-6, "{o:?}");
    }
}
