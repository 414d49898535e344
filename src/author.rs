//! The artist's side (Bassett §3.1, §3.3): bind strokes painted in any pose,
//! set keys, smudge and expand. The CLI's `bind`, `key`, `smudge` and
//! `expand` commands are thin wrappers over these functions, so tools,
//! scripts and a painting UI share one implementation. One check is still
//! the CLI's own: a brush that moved no point is refused before anything is
//! saved ([`brush`] returns 0, which a painting UI may well accept).
//!
//! Every function edits through an [`EditSession`] (an edit layer over the
//! input, or the input in place) and leaves saving to the caller:
//!
//! ```no_run
//! use painterly::author::{bind, BindOptions};
//! use painterly::usd_io::edit::{EditSession, EditTarget};
//! # fn main() -> painterly::Result<()> {
//! let session = EditSession::open("fish.usda".as_ref(), &EditTarget::Layer("fish_edits.usda".into()))?;
//! bind(&session, &BindOptions { layers: vec![], time: Some(24.0) })?;
//! session.save()?;
//! # Ok(()) }
//! ```

use glam::{DAffine3, DMat3, DMat4, DVec3, Vec3};

use crate::bind::{Binding, ClosestPoint};
use crate::character::eval_axes;
use crate::error::{Error, Result};
use crate::interp::InterpError;
use crate::keys::TimeKeyError;
use crate::mesh::{fan_triangulate, OneRings};
use crate::skinning::SkinningRest;
use crate::tools::{self, Falloff};
use crate::usd_io::edit::{Authored, EditSession};
use crate::usd_io::scene::{layer_axes, Rig, Scene, StrokeLayer};
use crate::usd_io::stage::StageReader;
use crate::usd_io::values;
use crate::words::plural;

/// A rig posed at one time: proxy points, per-vertex motions, transform.
pub struct PosedRig {
    /// Proxy-local posed points.
    pub posed: Vec<DVec3>,
    /// Per-vertex rigid motions from the rest pose (identity at rest).
    pub motions: Vec<DAffine3>,
    /// Proxy local-to-world.
    pub proxy_to_world: DMat4,
    /// Fan triangles of the proxy.
    pub triangles: Vec<[u32; 3]>,
    /// The time the transforms were read at.
    pub time: f64,
}

impl PosedRig {
    /// The inverse of `proxy_to_world`, which takes painted world points
    /// into the proxy's space. A proxy whose transform has no inverse (a
    /// zero scale flattens it) is refused here, naming `proxy`: its inverse
    /// would carry NaN into the binding and the rest points.
    pub fn world_to_proxy(&self, proxy: &str) -> Result<DMat4> {
        // A determinant of 0 (or one whose reciprocal overflows) leaves
        // infinities and NaN in the inverse: the one test needed.
        let inverse = self.proxy_to_world.inverse();
        if inverse.is_finite() {
            return Ok(inverse);
        }
        Err(Error::prim(
            proxy,
            format!(
                "its world transform at time {} has no inverse (determinant {}), so painted points cannot be taken into the proxy's space",
                self.time,
                self.proxy_to_world.determinant()
            ),
        ))
    }
}

/// The first point of `points` that is not finite as f32 (what is written).
fn first_non_finite(points: impl IntoIterator<Item = Vec3>) -> Option<usize> {
    points.into_iter().position(|p| !p.is_finite())
}

/// Poses `rig` at `time`, or in its rest pose when `time` is None (transforms
/// are then read at `xform_time`).
pub fn pose_rig(r: &StageReader, rig: &Rig, time: Option<f64>, xform_time: f64) -> Result<PosedRig> {
    let p = &rig.proxy;
    let triangles = fan_triangulate(&p.face_counts, &p.face_indices);
    let (posed, motions) = match time {
        None => (p.rest.clone(), vec![DAffine3::IDENTITY; p.rest.len()]),
        Some(t) => {
            let posed = p.posed_points(r, t)?;
            let rings = OneRings::new(p.rest.len(), &p.face_counts, &p.face_indices);
            let motions = SkinningRest::new(rings, &p.rest).vertex_motions(&posed);
            (posed, motions)
        }
    };
    let t = time.unwrap_or(xform_time);
    Ok(PosedRig {
        posed,
        motions,
        proxy_to_world: p.local_to_world(r, t)?,
        triangles,
        time: t,
    })
}

/// The blended motion Σ w M_v of eq. 1, in f64.
pub fn blended_motion(motions: &[DAffine3], vertices: [u32; 3], weights: [f32; 3]) -> DAffine3 {
    let mut m3 = DMat3::ZERO;
    let mut t = DVec3::ZERO;
    for (v, w) in vertices.iter().zip(weights) {
        let m = &motions[*v as usize];
        m3 += m.matrix3 * w as f64;
        t += m.translation * w as f64;
    }
    DAffine3::from_mat3_translation(m3, t)
}

fn invert(m: &DAffine3, layer: &str, i: usize) -> Result<DAffine3> {
    let det = m.matrix3.determinant();
    if !(det.is_finite() && det.abs() > 1e-12) {
        return Err(Error::prim(
            layer,
            format!("point {i}: the skinning blend is singular here, so it cannot be taken back to rest space"),
        ));
    }
    Ok(m.inverse())
}

/// Reads the scene and the input's time range; checks `time` lies inside it.
fn scene_at(session: &EditSession, time: Option<f64>) -> Result<(Scene, f64)> {
    let scene = Scene::read(&session.reader)?;
    let meta = &session.input_meta;
    let start = meta.start_time_code.unwrap_or(0.0);
    if let Some(t) = time {
        if !t.is_finite() {
            return Err(Error::usage(format!("--time {t} is not a finite number")));
        }
        if let (Some(s), Some(e)) = (meta.start_time_code, meta.end_time_code) {
            if t < s - 1e-9 || t > e + 1e-9 {
                return Err(Error::msg(format!(
                    "--time {t} is outside the stage's time range {s}:{e} (startTimeCode:endTimeCode)"
                )));
            }
        }
    }
    Ok((scene, start))
}

/// Finds a stroke layer by prim path: (rig index, layer index).
fn find_layer(r: &StageReader, scene: &Scene, path: &str) -> Result<(usize, usize)> {
    for (ri, rig) in scene.rigs.iter().enumerate() {
        if let Some(li) = rig.layers.iter().position(|l| l.path == path) {
            return Ok((ri, li));
        }
    }
    if r.user_prim("--layer", path)?.is_none() {
        return Err(Error::prim(
            path,
            "prim does not exist (--layer names a stroke layer's prim path)",
        ));
    }
    Err(Error::prim(
        path,
        "is not a stroke layer (a BasisCurves with PainterlyStrokeLayerAPI under a rig with PainterlyRigAPI)",
    ))
}

/// Options of [`bind`].
#[derive(Debug, Clone, Default)]
pub struct BindOptions {
    /// Stroke layer prim paths; empty = every layer.
    pub layers: Vec<String>,
    /// The pose the strokes were painted in; None = the rest pose (the rest
    /// positions are bound where they are, see [`bind`]).
    pub time: Option<f64>,
}

/// What [`bind`] did: (layer path, points bound) per layer.
pub type BindReport = Vec<(String, usize)>;

/// Binds layers painted in the pose at `time`: each point of the layer's
/// `points` (stroke-local, as painted: what is drawn at `time`) is bound to
/// the closest point of the posed proxy; its rest position is the inverse
/// of the skinning blend applied to it (SPEC §3). Authors
/// `painterly:restPoints`, `painterly:bindVertices` and
/// `painterly:bindWeights`. Baking at `time` then gives back the painted
/// positions. A layer with position keys is refused with a `time`: its keys,
/// not its rest points, are what a bake draws.
///
/// Without a `time` the rest positions are bound as a bake reads them
/// (`painterly:restPoints`, else the default `points` as proxy-local
/// coordinates, SPEC §3) to the closest point of the rest proxy, and stay
/// where they are: the binding a bake would compute, stored (and any stored
/// one replaced). No transform is read.
pub fn bind(session: &EditSession, opts: &BindOptions) -> Result<BindReport> {
    let r = &session.reader;
    let (scene, start) = scene_at(session, opts.time)?;
    for l in &opts.layers {
        find_layer(r, &scene, l)?;
    }
    // As bake: a stage with nothing to bind is an error, not an empty layer.
    if scene.rigs.iter().all(|rig| rig.layers.is_empty()) {
        return Err(Error::msg(
            "nothing to bind: no stroke layer (PainterlyStrokeLayerAPI under a prim with PainterlyRigAPI)",
        ));
    }
    if let Some(t) = opts.time {
        for layer in scene.rigs.iter().flat_map(|rig| &rig.layers) {
            if opts.layers.is_empty() || opts.layers.contains(&layer.path) {
                refuse_keyed_bind(layer, t)?;
            }
        }
    }
    let mut report = Vec::new();
    for rig in &scene.rigs {
        let chosen: Vec<&StrokeLayer> = rig
            .layers
            .iter()
            .filter(|l| opts.layers.is_empty() || opts.layers.contains(&l.path))
            .collect();
        if chosen.is_empty() {
            continue;
        }
        if opts.time.is_none() {
            report.extend(bind_rest(session, rig, &chosen)?);
            continue;
        }
        let pose = pose_rig(r, rig, opts.time, start)?;
        let world_to_proxy = pose.world_to_proxy(&rig.proxy.path)?;
        let bvh = ClosestPoint::new(&pose.posed, &pose.triangles);
        // Every chosen layer's painted points in proxy space, bound in one
        // call (one parallel job and one Morton order over the rig, as a
        // bake binds); each point's answer depends on it alone.
        let mut proxy_pts: Vec<DVec3> = Vec::new();
        let mut ends = Vec::with_capacity(chosen.len());
        for layer in &chosen {
            let painted = layer.points.as_ref().ok_or_else(|| {
                Error::attr(
                    &layer.path,
                    "points",
                    "bind needs the painted `points` (a default value)",
                )
            })?;
            let to_proxy = world_to_proxy * layer.local_to_world(r, pose.time)?;
            let start = proxy_pts.len();
            proxy_pts.extend(painted.iter().map(|p| to_proxy.transform_point3(p.as_dvec3())));
            // A proxy scaled down by 1e-100 has an inverse, but it takes the
            // points past f32, and the binding needs finite points.
            if let Some(i) = first_non_finite(proxy_pts[start..].iter().map(|p| p.as_vec3())) {
                return Err(Error::attr(
                    &layer.path,
                    "points",
                    format!("point {i} is not finite in the space of the proxy {}: its transform scales the points past the float range", rig.proxy.path),
                ));
            }
            ends.push(proxy_pts.len());
        }
        let f32pts: Vec<Vec3> = proxy_pts.iter().map(|p| p.as_vec3()).collect();
        let all = bvh.bind(&f32pts);
        let mut start = 0;
        for (layer, end) in chosen.into_iter().zip(ends) {
            let binding = Binding {
                vertices: all.vertices[start..end].to_vec(),
                weights: all.weights[start..end].to_vec(),
            };
            let mut rest = Vec::with_capacity(end - start);
            for (i, p) in proxy_pts[start..end].iter().enumerate() {
                let m = blended_motion(&pose.motions, binding.vertices[i], binding.weights[i]);
                rest.push(invert(&m, &layer.path, i)?.transform_point3(*p).as_vec3());
            }
            if let Some(i) = first_non_finite(rest.iter().copied()) {
                return Err(Error::attr(
                    &layer.path,
                    "points",
                    format!(
                        "point {i}: its rest position is not finite (the skinning blend takes it past the float range)"
                    ),
                ));
            }
            session.set_binding(&layer.path, &rest, &binding)?;
            report.push((layer.path.clone(), rest.len()));
            start = end;
        }
    }
    Ok(report)
}

/// `bind` in the rest pose: each chosen layer's rest points, as a bake reads
/// them, bound to the closest point of the rest proxy in one call (as a bake
/// binds), and stored with the binding, unchanged.
fn bind_rest(session: &EditSession, rig: &Rig, chosen: &[&StrokeLayer]) -> Result<BindReport> {
    let triangles = fan_triangulate(&rig.proxy.face_counts, &rig.proxy.face_indices);
    let all: Vec<Vec3> = chosen.iter().flat_map(|l| l.rest_points.iter().copied()).collect();
    let all = ClosestPoint::new(&rig.proxy.rest, &triangles).bind(&all);
    let mut report = Vec::with_capacity(chosen.len());
    let mut start = 0;
    for layer in chosen {
        let end = start + layer.rest_points.len();
        let binding = Binding {
            vertices: all.vertices[start..end].to_vec(),
            weights: all.weights[start..end].to_vec(),
        };
        session.set_binding(&layer.path, &layer.rest_points, &binding)?;
        report.push((layer.path.clone(), layer.rest_points.len()));
        start = end;
    }
    Ok(report)
}

/// Refuses `bind --time` on a layer with position keys: the keys, not the
/// rest points, shape its bake, so baking at `time` would not give back the
/// painted points, and the new binding would re-skin every key.
fn refuse_keyed_bind(layer: &StrokeLayer, time: f64) -> Result<()> {
    let k = &layer.keys;
    let keys: Vec<&str> = k
        .pose_points
        .iter()
        .flat_map(|c| &c.paths)
        .chain(k.time_points.iter().flat_map(|c| &c.paths))
        .map(String::as_str)
        .collect();
    if keys.is_empty() {
        return Ok(());
    }
    Err(Error::prim(
        &layer.path,
        format!(
            "has position keys ({}), which shape its bake instead of its rest points: bind --time {time} would not \
             give back the painted points, and its new binding would re-skin every key. Bind the strokes before \
             keying them, or edit a key in the pose with `smudge --key`/`expand --key` (--layer names the layers \
             to bind)",
            keys.join(", ")
        ),
    ))
}

/// Which kind of key [`key`] sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyKind {
    /// A configuration-space `PainterlyPoseKey` at the configuration at `time`.
    Pose,
    /// A normal `PainterlyTimeKey` at `time`.
    Time,
    /// A sentinel `PainterlyTimeKey` at `time` (no data).
    Sentinel,
}

/// Options of [`key`].
#[derive(Debug, Clone)]
pub struct KeyOptions {
    pub layer: String,
    pub time: f64,
    pub kind: KeyKind,
    /// Key prim name; default: the first free `keyN` / `timeN` / `sentinelN`.
    pub name: Option<String>,
    /// Capture the layer's current rest positions.
    pub points: bool,
    /// Opacity value to key.
    pub opacity: Option<f32>,
    /// Replace a key of the same name, or at the same coordinates/time.
    pub replace: bool,
    /// Camera for `viewDirection` axes without a source.
    pub camera: Option<String>,
}

/// Sets a key on a layer; returns the key prim's path.
///
/// Pose keys capture the configuration at `time` (every axis of the layer,
/// in axis units: SPEC 1.1 §4 stores coordinates before `scale`), time keys
/// capture `time`; both capture the layer's current rest
/// positions (`points`) and/or an `opacity`. A key whose coordinates (or time)
/// coincide with an existing key of the same channel is refused unless
/// `replace`, which then rewrites that key: it holds only what this call
/// sets, every other key attribute blocked.
pub fn key(session: &EditSession, opts: &KeyOptions) -> Result<String> {
    if let Some(c) = &opts.camera {
        session.reader.require_camera(c, "--camera")?;
    }
    if let Some(name) = &opts.name {
        check_prim_name(name)?;
    }
    check_key_data(opts)?;
    let r = &session.reader;
    let (mut scene, _) = scene_at(session, Some(opts.time))?;
    let (ri, li) = find_layer(r, &scene, &opts.layer)?;
    if opts.kind != KeyKind::Sentinel && !opts.points && opts.opacity.is_none() {
        return Err(Error::prim(
            &opts.layer,
            "nothing to key: pass --points and/or --opacity VALUE",
        ));
    }
    let (existing, unread) = existing_keys(r, &opts.layer)?;
    let place = key_place(r, &mut scene.rigs[ri], li, opts)?;
    let path = key_path(opts, &existing, &unread, &place)?;
    check_channels_stay_readable(opts, &existing, &place, &path)?;
    write_key(
        session,
        &path,
        place.ty,
        &place.coords,
        opts,
        &scene.rigs[ri].layers[li].rest_points,
    )?;
    if let Some(old) = existing.iter().find(|e| e.path == path) {
        clear_unset(session, old, opts, &place)?;
    }
    Ok(path)
}

/// A replaced key holds only what the command that replaced it sets: every
/// other key attribute it carried (a time key's `time` or `sentinel` on a
/// pose key, a pose key's `coordinates` on a time key, a sentinel's data,
/// and the other channel's value when the key moves) is blocked, as
/// usd-core's `Block()` does, so the key neither keeps an old shape at its
/// new place nor carries data a sentinel may not. A key rewritten where it
/// is (the same coordinates or time, kind and sentinel flag) keeps the
/// channel the command does not set: `--opacity V` there changes its
/// opacity and keeps its (perhaps sculpted) points.
fn clear_unset(session: &EditSession, old: &ExistingKey, opts: &KeyOptions, place: &KeyPlace) -> Result<()> {
    let data = opts.kind != KeyKind::Sentinel;
    let stays = data && old.ty == place.ty && !old.sentinel && old.coords == place.coords;
    let sets = |name: &str| match name {
        "coordinates" => opts.kind == KeyKind::Pose,
        "time" | "sentinel" => opts.kind != KeyKind::Pose,
        "points" => data && (opts.points || stays),
        "opacity" => data && (opts.opacity.is_some() || stays),
        _ => false,
    };
    for (name, ty) in KEY_ATTRS {
        if old.authored.contains(&name) && !sets(name) {
            session.block(&old.path, name, ty)?;
        }
    }
    Ok(())
}

/// A key already on the layer, as far as collisions need it.
struct ExistingKey {
    path: String,
    ty: String,
    /// A pose key's coordinates, or a time key's time.
    coords: Vec<f64>,
    points: bool,
    opacity: bool,
    sentinel: bool,
    /// The key attributes ([`KEY_ATTRS`]) with an authored value.
    authored: Vec<&'static str>,
}

/// Every attribute a key prim may carry, with its type: what a replaced key
/// loses when the command that replaces it does not set it.
const KEY_ATTRS: [(&str, &str); 5] = [
    ("coordinates", "float[]"),
    ("time", "double"),
    ("sentinel", "bool"),
    ("points", "point3f[]"),
    ("opacity", "float"),
];

/// A child a bake does not read (deactivated, an `over`, a `class`): its
/// path and why. It holds its name but keys nothing.
type UnreadChild = (String, &'static str);

/// The keys (and other children) of a layer prim that a bake reads, and
/// the children it does not.
fn existing_keys(r: &StageReader, layer_path: &str) -> Result<(Vec<ExistingKey>, Vec<UnreadChild>)> {
    let layer_prim = r.require_prim(layer_path)?;
    let mut existing = Vec::new();
    let mut unread = Vec::new();
    for c in layer_prim
        .children()
        .map_err(|e| Error::prim(layer_path, format!("cannot list children: {e}")))?
    {
        if let Some(why) = r.unread_reason(&c)? {
            unread.push((c.path().as_str().to_string(), why));
            continue;
        }
        let ty = r.type_name(&c)?;
        let coords = match ty.as_str() {
            "PainterlyPoseKey" => r
                .typed(&c, "coordinates", None, "float[]", values::f32_array)?
                .unwrap_or_default()
                .iter()
                .map(|&x| x as f64)
                .collect(),
            "PainterlyTimeKey" => vec![r.typed(&c, "time", None, "double", values::scalar)?.unwrap_or(f64::NAN)],
            _ => Vec::new(),
        };
        // `sentinel` means something on a time key only: the bake reads a
        // pose key that authors it as a pose key, and so must `key`.
        let sentinel =
            ty == "PainterlyTimeKey" && r.typed(&c, "sentinel", None, "bool", values::scalar)?.unwrap_or(0.0) != 0.0;
        let mut authored = Vec::new();
        for (name, _) in KEY_ATTRS {
            if r.has_authored(&c, name)? {
                authored.push(name);
            }
        }
        existing.push(ExistingKey {
            points: authored.contains(&"points"),
            opacity: authored.contains(&"opacity"),
            sentinel,
            authored,
            path: c.path().as_str().to_string(),
            ty,
            coords,
        });
    }
    Ok((existing, unread))
}

/// Where a new key goes: its prim type, and its coordinates in
/// configuration space (a pose key, with its axes' scales) or its time (a
/// time key or sentinel; no scales).
struct KeyPlace {
    ty: &'static str,
    coords: Vec<f64>,
    scales: Vec<f64>,
}

/// Where the new key lives (see [`KeyPlace`]).
fn key_place(r: &StageReader, rig: &mut Rig, li: usize, opts: &KeyOptions) -> Result<KeyPlace> {
    match opts.kind {
        KeyKind::Pose => {
            let all_paths = r.prim_paths()?;
            // layer_axes may add axes to the rig's table: lend it the layer apart.
            let layers = std::mem::take(&mut rig.layers);
            let axes = layer_axes(r, &all_paths, rig, &layers[li]);
            rig.layers = layers;
            let axes = axes?;
            let pose = pose_rig(r, rig, Some(opts.time), opts.time)?;
            let values = eval_axes(
                r,
                rig,
                &axes,
                opts.time,
                pose.proxy_to_world,
                &pose.posed,
                opts.camera.as_deref(),
            )?;
            // Coordinates are stored as float[]: compare and write the f32 values.
            Ok(KeyPlace {
                ty: "PainterlyPoseKey",
                coords: axes.iter().map(|&a| values[a] as f32 as f64).collect(),
                scales: axes.iter().map(|&a| rig.axes[a].scale).collect(),
            })
        }
        KeyKind::Time | KeyKind::Sentinel => Ok(KeyPlace {
            ty: "PainterlyTimeKey",
            coords: vec![opts.time],
            scales: Vec::new(),
        }),
    }
}

/// What a key holds, before any file is read: an opacity is a value in
/// [0, 1] (Bassett §3.3; the bake multiplies it into `displayOpacity`), and
/// a sentinel holds no data (SPEC §5), so points or an opacity asked of one
/// would be dropped.
fn check_key_data(opts: &KeyOptions) -> Result<()> {
    if let Some(o) = opts.opacity {
        if !o.is_finite() {
            return Err(Error::usage(format!("--opacity {o} is not finite")));
        }
        if !(0.0..=1.0).contains(&o) {
            return Err(Error::usage(format!(
                "--opacity {o} is outside [0, 1] (0 transparent, 1 opaque)"
            )));
        }
    }
    if opts.kind == KeyKind::Sentinel && (opts.points || opts.opacity.is_some()) {
        return Err(Error::usage(
            "a sentinel holds no data: --sentinel takes neither --points nor --opacity",
        ));
    }
    Ok(())
}

/// A key's name is one prim name: `a/b` would define a prim outside the
/// layer, where bake and inspect never look for keys.
fn check_prim_name(name: &str) -> Result<()> {
    if crate::usd_io::is_prim_name(name) {
        return Ok(());
    }
    Err(Error::usage(format!(
        "--name {name:?} is not a prim name: letters, digits and _, not starting with a digit"
    )))
}

/// The new key's path: the key it replaces (one of the same name, or at the
/// same coordinates or time in a channel it sets, with `replace`), the name
/// asked for, or the first free `keyN` / `timeN` / `sentinelN`.
fn key_path(opts: &KeyOptions, existing: &[ExistingKey], unread: &[UnreadChild], place: &KeyPlace) -> Result<String> {
    let (ty, coords) = (place.ty, &place.coords);
    let layer_path = &opts.layer;
    let mut replace_path: Option<String> = None;
    if let Some(name) = &opts.name {
        let p = format!("{layer_path}/{name}");
        if let Some((_, why)) = unread.iter().find(|(q, _)| *q == p) {
            return Err(Error::prim(
                &p,
                format!("a prim of this name exists but is {why}, so a bake would not read a key there: pick another --name"),
            ));
        }
        if let Some(e) = existing.iter().find(|e| e.path == p) {
            if !opts.replace {
                return Err(Error::prim(
                    &p,
                    "a key of this name exists: pass --replace to overwrite it",
                ));
            }
            if e.ty != ty {
                return Err(Error::prim(&p, format!("exists as a {:?} prim, not a {ty}", e.ty)));
            }
            replace_path = Some(p);
        }
    }
    let (meets_points, meets_opacity) = match opts.kind {
        KeyKind::Pose => (
            pose_keys_met(existing, place, |e| e.points),
            pose_keys_met(existing, place, |e| e.opacity),
        ),
        KeyKind::Time => (
            time_keys_met(existing, place, |e| e.points),
            time_keys_met(existing, place, |e| e.opacity),
        ),
        KeyKind::Sentinel => (Vec::new(), Vec::new()),
    };
    for (i, e) in existing.iter().enumerate().filter(|(_, e)| e.ty == ty) {
        let clash = match opts.kind {
            KeyKind::Sentinel => e.sentinel && e.coords == *coords,
            KeyKind::Time | KeyKind::Pose => {
                (opts.points && meets_points.contains(&i)) || (opts.opacity.is_some() && meets_opacity.contains(&i))
            }
        };
        if clash {
            if !opts.replace && ty == "PainterlyPoseKey" && coords.is_empty() {
                // Without axes every pose key sits at the one empty configuration.
                return Err(Error::attr(
                    layer_path,
                    "painterly:axes",
                    format!(
                        "the layer has no axes, so a pose key at any time meets {}: give the layer axes, or key the timeline with --time-key",
                        e.path
                    ),
                ));
            }
            if !opts.replace {
                let place = match (ty == "PainterlyPoseKey", e.coords == *coords) {
                    (false, true) => "time",
                    // What the bake's time interpolation refuses as one time.
                    (false, false) => "time (the times meet within 1e-12 of the span of the time keys between their sentinels)",
                    (true, true) => "coordinates",
                    // What the bake's interpolation refuses as one point.
                    (true, false) => {
                        "configuration (the coordinates meet once each axis is multiplied by its scale, within 1e-12 of the keys' extent)"
                    }
                };
                return Err(Error::prim(
                    &e.path,
                    format!("already keys this layer at the same {place}: pass --replace to overwrite it"),
                ));
            }
            if replace_path.as_ref().is_some_and(|p| *p != e.path) {
                return Err(Error::prim(&e.path, "--replace would overwrite two different keys"));
            }
            replace_path = Some(e.path.clone());
        }
    }
    Ok(match replace_path {
        Some(p) => p,
        None => match &opts.name {
            Some(n) => format!("{layer_path}/{n}"),
            None => {
                let stem = match opts.kind {
                    KeyKind::Pose => "key",
                    KeyKind::Time => "time",
                    KeyKind::Sentinel => "sentinel",
                };
                (1..)
                    .map(|i| format!("{layer_path}/{stem}{i}"))
                    .find(|p| !existing.iter().any(|e| e.path == *p) && !unread.iter().any(|(q, _)| q == p))
                    .expect("a free name")
            }
        },
    })
}

/// The existing pose keys (indices into `existing`) of the channel `in_channel`
/// selects that sit at the new key's point as a bake reads them: coordinates
/// times the axes' scales (SPEC 1.1 §4), one point when closer than the
/// interpolation's duplicate tolerance ([`crate::interp::same_point_as`]).
/// With no axes every key of the channel is at the one point.
fn pose_keys_met(existing: &[ExistingKey], place: &KeyPlace, in_channel: impl Fn(&ExistingKey) -> bool) -> Vec<usize> {
    let dim = place.coords.len();
    let (members, mut layout) = pose_layout(existing, place, in_channel, None);
    if dim == 0 {
        return members;
    }
    layout.extend(scaled(&place.coords, &place.scales));
    crate::interp::same_point_as(dim, &layout, members.len())
        .into_iter()
        .map(|j| members[j])
        .collect()
}

/// A pose channel as the bake reads it, for a key placed at `place`: its
/// keys with as many coordinates (indices into `existing`, leaving out the
/// key at `without`) and their coordinates times the axes' scales
/// (SPEC 1.1 §4), flat.
fn pose_layout(
    existing: &[ExistingKey],
    place: &KeyPlace,
    in_channel: impl Fn(&ExistingKey) -> bool,
    without: Option<&str>,
) -> (Vec<usize>, Vec<f64>) {
    let members: Vec<usize> = (0..existing.len())
        .filter(|&i| {
            let e = &existing[i];
            e.ty == "PainterlyPoseKey"
                && !e.sentinel
                && in_channel(e)
                && e.coords.len() == place.coords.len()
                && Some(e.path.as_str()) != without
        })
        .collect();
    let layout = members
        .iter()
        .flat_map(|&i| scaled(&existing[i].coords, &place.scales))
        .collect();
    (members, layout)
}

/// Coordinates times their axes' scales.
fn scaled(coords: &[f64], scales: &[f64]) -> Vec<f64> {
    coords.iter().zip(scales).map(|(c, s)| c * s).collect()
}

/// The existing time keys (indices into `existing`) of the channel
/// `in_channel` selects that sit at the new key's time as a bake reads them
/// ([`crate::keys::same_time_as`]: the same time, or one the interpolation
/// of their group between sentinels counts as the same).
fn time_keys_met(existing: &[ExistingKey], place: &KeyPlace, in_channel: impl Fn(&ExistingKey) -> bool) -> Vec<usize> {
    let (members, mut times, sentinels) = time_layout(existing, in_channel, None);
    times.push(place.coords[0]);
    crate::keys::same_time_as(&times, &sentinels, members.len())
        .into_iter()
        .map(|j| members[j])
        .collect()
}

/// A time channel as the bake reads it: its keys (indices into `existing`,
/// leaving out the key at `without`), their times, and the times of its
/// sentinels (but the one at `without`).
fn time_layout(
    existing: &[ExistingKey],
    in_channel: impl Fn(&ExistingKey) -> bool,
    without: Option<&str>,
) -> (Vec<usize>, Vec<f64>, Vec<f64>) {
    let is_time = |e: &ExistingKey| e.ty == "PainterlyTimeKey" && e.coords.len() == 1;
    let members: Vec<usize> = (0..existing.len())
        .filter(|&i| {
            let e = &existing[i];
            is_time(e) && !e.sentinel && in_channel(e) && Some(e.path.as_str()) != without
        })
        .collect();
    let times = members.iter().map(|&i| existing[i].coords[0]).collect();
    let sentinels = existing
        .iter()
        .filter(|e| is_time(e) && e.sentinel && Some(e.path.as_str()) != without)
        .map(|e| e.coords[0])
        .collect();
    (members, times, sentinels)
}

/// The two channels of a layer's keys: name, whether the command sets it,
/// and which keys are in it.
type KeyChannels = [(&'static str, bool, fn(&ExistingKey) -> bool); 2];

/// Refuses a key that would leave a channel it sets unreadable by the bake
/// although the channel was readable before: the duplicate tolerance is
/// relative to the layout's extent, so a key far from the others can make
/// two existing keys count as one point. (A new sentinel only splits runs
/// of time keys, which never brings two keys within tolerance; replacing a
/// sentinel, which joins runs, is [`check_sentinel_move`]'s.)
fn check_channels_stay_readable(
    opts: &KeyOptions,
    existing: &[ExistingKey],
    place: &KeyPlace,
    path: &str,
) -> Result<()> {
    let channels: KeyChannels = [
        ("position", opts.points, |e| e.points),
        ("opacity", opts.opacity.is_some(), |e| e.opacity),
    ];
    if existing.iter().any(|e| e.path == path && e.sentinel) {
        return check_sentinel_move(opts, existing, place, path, channels);
    }
    for (channel, _, in_channel) in channels.into_iter().filter(|c| c.1) {
        let (members, old, new) = match opts.kind {
            KeyKind::Sentinel => return Ok(()),
            KeyKind::Time => {
                // A sentinel the new key replaces splits the runs before, not after.
                let (members, times, after) = time_layout(existing, in_channel, Some(path));
                let (_, _, before) = time_layout(existing, in_channel, None);
                let mut with_new = times.clone();
                with_new.push(place.coords[0]);
                (members, time_clash(&times, &before), time_clash(&with_new, &after))
            }
            KeyKind::Pose => {
                let dim = place.coords.len();
                if dim == 0 {
                    continue;
                }
                let (members, mut layout) = pose_layout(existing, place, in_channel, Some(path));
                let pair = |l: &[f64]| match crate::interp::validate_keys(dim, l) {
                    Err(InterpError::DuplicateKeys { first, second }) => Some(Unreadable::Clash(first, second)),
                    Err(InterpError::TooManyKeys { count }) => Some(Unreadable::TooMany(count)),
                    _ => None,
                };
                let old = pair(&layout);
                layout.extend(scaled(&place.coords, &place.scales));
                (members, old, pair(&layout))
            }
        };
        let name = |k: usize| members.get(k).map_or(path, |&i| existing[i].path.as_str());
        match (old, new) {
            (None, Some(Unreadable::Clash(a, b))) => {
                return Err(Error::prim(
                    &opts.layer,
                    format!(
                        "the new key {path} would widen the layer's {channel} keys so far that {} and {} count as \
                         one (within 1e-12 of the keys' extent), and the bake would refuse the layer",
                        name(a),
                        name(b)
                    ),
                ));
            }
            (None, Some(Unreadable::TooMany(count))) => {
                let group = if opts.kind == KeyKind::Time {
                    "time keys with no sentinel between them"
                } else {
                    "pose keys"
                };
                return Err(Error::prim(
                    &opts.layer,
                    format!(
                        "the new key {path} would make {count} {channel} {group}; painterly interpolates at most {} \
                         at once, and the bake would refuse the layer: split them over layers or sentinels",
                        crate::interp::MAX_KEYS
                    ),
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Why the bake would refuse a channel's keys, where a key command can
/// cause it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unreadable {
    /// Two keys (indices into the channel's members) count as one.
    Clash(usize, usize),
    /// More keys in one interpolation than [`crate::interp::MAX_KEYS`].
    TooMany(usize),
}

/// Why the bake would refuse a time channel, if it would for a reason a key
/// command can cause.
fn time_clash(times: &[f64], sentinels: &[f64]) -> Option<Unreadable> {
    match crate::keys::TimeChannel::new(times, sentinels) {
        Err(TimeKeyError::SameTime { first, second } | TimeKeyError::CloseTimes { first, second }) => {
            Some(Unreadable::Clash(first, second))
        }
        Err(TimeKeyError::TooMany { count }) => Some(Unreadable::TooMany(count)),
        _ => None,
    }
}

/// Refuses replacing the sentinel at `path` when a channel, either one,
/// would become unreadable by the bake: moving a sentinel takes away the
/// split where it was, so runs of time keys on both sides join (and
/// sentinels split the points and the opacity keys alike), and a wider run
/// widens the tolerance until two keys meet. Compares each channel's
/// layout with every current sentinel against the one without the replaced
/// sentinel, plus the new key (a sentinel at its time, or a time key in the
/// channels it sets).
fn check_sentinel_move(
    opts: &KeyOptions,
    existing: &[ExistingKey],
    place: &KeyPlace,
    path: &str,
    channels: KeyChannels,
) -> Result<()> {
    let new_time = place.coords[0];
    for (channel, sets, in_channel) in channels {
        let (all, times_all, sentinels_all) = time_layout(existing, in_channel, None);
        let old = time_clash(&times_all, &sentinels_all);
        let (members, mut times, mut sentinels) = time_layout(existing, in_channel, Some(path));
        match opts.kind {
            KeyKind::Sentinel => sentinels.push(new_time),
            KeyKind::Time if sets => times.push(new_time),
            _ => {}
        }
        debug_assert_eq!(all, members, "a sentinel is no member of a channel");
        let name = |k: usize| members.get(k).map_or(path, |&i| existing[i].path.as_str());
        let what = if opts.kind == KeyKind::Sentinel {
            "a sentinel"
        } else {
            "a time key"
        };
        let joined = match (old, time_clash(&times, &sentinels)) {
            (None, Some(Unreadable::Clash(a, b))) => format!(
                "so that {} and {} count as one (within 1e-12 of the span of the time keys between their \
                 sentinels)",
                name(a),
                name(b)
            ),
            (None, Some(Unreadable::TooMany(count))) => format!(
                "into {count} keys, more than the {} painterly interpolates at once",
                crate::interp::MAX_KEYS
            ),
            _ => continue,
        };
        return Err(Error::prim(
            &opts.layer,
            format!(
                "replacing the sentinel {path} with {what} at time {new_time} would take away the split it makes \
                 and join runs of the layer's {channel} keys {joined}, and the bake would refuse the layer"
            ),
        ));
    }
    Ok(())
}

/// Defines the key prim and sets its attributes (a sentinel holds no data).
fn write_key(
    session: &EditSession,
    path: &str,
    ty: &str,
    coords: &[f64],
    opts: &KeyOptions,
    rest_points: &[Vec3],
) -> Result<()> {
    session.define(path, ty)?;
    match opts.kind {
        KeyKind::Pose => {
            let c: Vec<f32> = coords.iter().map(|&x| x as f32).collect();
            session.set(path, "coordinates", Authored::Floats(&c))?;
        }
        KeyKind::Time | KeyKind::Sentinel => {
            session.set(path, "time", Authored::Double(opts.time))?;
            session.set(path, "sentinel", Authored::Bool(opts.kind == KeyKind::Sentinel))?;
        }
    }
    if opts.kind != KeyKind::Sentinel {
        if opts.points {
            session.set(path, "points", Authored::Points(rest_points))?;
        }
        if let Some(o) = opts.opacity {
            session.set(path, "opacity", Authored::Float(o))?;
        }
    }
    Ok(())
}

/// Which brush [`brush`] applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Brush {
    /// Move points along the tool path's tangent.
    Smudge,
    /// Move points along the proxy surface normal at their bound position.
    Expand,
}

/// Options of [`brush`].
#[derive(Debug, Clone)]
pub struct BrushOptions {
    pub layer: String,
    /// The tool path in world space (at least two points).
    pub path: Vec<DVec3>,
    pub radius: f64,
    pub strength: f64,
    pub falloff: Falloff,
    /// The pose the brush is applied in; None = the rest pose.
    pub time: Option<f64>,
    /// Edit this key's points (a PainterlyPoseKey or PainterlyTimeKey child)
    /// instead of the layer's rest points.
    pub key: Option<String>,
    /// Only these strokes (inclusive ranges of curve indices, as
    /// [`tools::parse_strokes`] gives them); None = all.
    pub strokes: Option<Vec<(usize, usize)>>,
}

/// Applies smudge or expand (Bassett §3.3) in the pose at `time`; the
/// displacement is taken back to rest space through the inverse of each
/// point's skinning blend. A layer bound on the fly gets the binding the
/// edit used stored with its new rest points when the bake would otherwise
/// bind them differently (`binding_to_store` says when). Returns the number of
/// points moved.
pub fn brush(session: &EditSession, brush: Brush, opts: &BrushOptions) -> Result<usize> {
    let r = &session.reader;
    check_brush_options(opts)?;
    let (scene, start) = scene_at(session, opts.time)?;
    let (ri, li) = find_layer(r, &scene, &opts.layer)?;
    let rig = &scene.rigs[ri];
    let layer = &rig.layers[li];
    let (target_prim, target_attr, mut target) = brush_target(r, layer, opts.key.as_deref())?;

    let pose = pose_rig(r, rig, opts.time, start)?;
    // Refuses a proxy flattened to nothing before any work; the linear
    // part's inverse takes world displacements and normals across.
    pose.world_to_proxy(&rig.proxy.path)?;
    let to_proxy = DMat3::from_mat4(pose.proxy_to_world).inverse();
    // The binding every point is converted through: the stored one, else
    // the one a bake computes from the rest points as they are now (key
    // points share their layer's binding, SPEC §4).
    let binding = match &layer.cached_binding {
        Some(b) => b.clone(),
        None => ClosestPoint::new(
            &rig.proxy.rest,
            &fan_triangulate(&rig.proxy.face_counts, &rig.proxy.face_indices),
        )
        .bind(&layer.rest_points),
    };
    let store_binding = binding_to_store(layer, opts);
    let selected = selected_points(layer, opts.strokes.as_deref())?;
    // Posed world positions of the target points.
    let blends: Vec<DAffine3> = (0..target.len())
        .map(|i| blended_motion(&pose.motions, binding.vertices[i], binding.weights[i]))
        .collect();
    let world: Vec<DVec3> = target
        .iter()
        .zip(&blends)
        .map(|(p, m)| pose.proxy_to_world.transform_point3(m.transform_point3(p.as_dvec3())))
        .collect();
    let disp = match brush {
        Brush::Smudge => tools::smudge(&world, &opts.path, opts.radius, opts.strength, opts.falloff),
        Brush::Expand => {
            let left_handed = r.left_handed(&r.require_prim(&rig.proxy.path)?)?;
            let normals = world_normals(&pose, &binding, to_proxy, left_handed);
            tools::expand(&world, &normals, &opts.path, opts.radius, opts.strength, opts.falloff)
        }
    };
    // Each world displacement back to rest space through its point's motion.
    // Moved: points whose stored value changes (a displacement below a
    // float's precision at a point reaches it but moves nothing).
    let (mut moved, mut reached) = (0, 0);
    for i in 0..target.len() {
        if !selected[i] || disp[i] == DVec3::ZERO {
            continue;
        }
        let inv = invert(&blends[i], &layer.path, i)?;
        let d_rest = inv.matrix3 * (to_proxy * disp[i]);
        let before = target[i];
        target[i] += d_rest.as_vec3();
        reached += 1;
        moved += usize::from(target[i] != before);
    }
    if moved == 0 && reached > 0 {
        return Err(Error::prim(
            &layer.path,
            format!(
                "the brush moves {} by less than a float's precision (--strength is too small): \
                 nothing changed, nothing written",
                plural(reached, "point")
            ),
        ));
    }
    if let Some(i) = first_non_finite(target.iter().copied()) {
        return Err(Error::attr(
            &target_prim,
            target_attr,
            format!("point {i}: the brush moves it past the float range in the proxy's space"),
        ));
    }
    if store_binding {
        // target is the layer's rest points here.
        session.set_binding(&layer.path, &target, &binding)?;
    } else {
        session.set(&target_prim, target_attr, Authored::Points(&target))?;
    }
    Ok(moved)
}

/// Whether [`brush`] must store the binding it converted through: a layer
/// without a stored binding is bound on the fly from its rest points, so
/// moving them can bind them to other triangles, and the bake would skin
/// each moved point (and every key point) by another blend than the one the
/// edit was taken back through. Needed when the brush moves the rest points
/// in a pose (`--time`: the bake at that time must show the displacement as
/// brushed) or on a layer with position keys (the rest points then anchor
/// the keys' binding, and re-binding would move key shapes the brush did
/// not touch). A `--key` edit leaves the rest points, hence the on-the-fly
/// binding, as they were; a rest-pose edit of an unkeyed layer is exact
/// whatever the binding (every motion is the identity there), and its
/// points are then bound where they now lie, as painted there.
fn binding_to_store(layer: &StrokeLayer, opts: &BrushOptions) -> bool {
    let keyed = layer.keys.pose_points.is_some() || layer.keys.time_points.is_some();
    layer.cached_binding.is_none() && opts.key.is_none() && (opts.time.is_some() || keyed)
}

/// The tool path, radius and strength a brush needs, before any file work.
fn check_brush_options(opts: &BrushOptions) -> Result<()> {
    if let Some(problem) = tools::tool_path_problem(&opts.path) {
        return Err(Error::msg(format!("the tool path {problem}")));
    }
    if !(opts.radius.is_finite() && opts.radius > 0.0) {
        return Err(Error::usage(format!("--radius {} must be positive", opts.radius)));
    }
    if !opts.strength.is_finite() {
        return Err(Error::usage(format!("--strength {} is not finite", opts.strength)));
    }
    if opts.strength == 0.0 {
        return Err(Error::usage("--strength 0 moves nothing: give a non-zero strength"));
    }
    Ok(())
}

/// The array a brush edits: (prim, attribute, points) of the key `key`
/// (a path, or a name under the layer) or else the layer's rest points.
fn brush_target(r: &StageReader, layer: &StrokeLayer, key: Option<&str>) -> Result<(String, &'static str, Vec<Vec3>)> {
    let Some(k) = key else {
        return Ok((layer.path.clone(), "painterly:restPoints", layer.rest_points.clone()));
    };
    let kp = if k.starts_with('/') {
        k.to_string()
    } else {
        format!("{}/{k}", layer.path)
    };
    let prim = r
        .user_prim("--key", &kp)?
        .ok_or_else(|| Error::prim(&kp, format!("no such key under {}", layer.path)))?;
    check_key_prim(r, &prim, &kp, &layer.path)?;
    let pts = r
        .typed(&prim, "points", None, "point3f[]", values::vec3_array)?
        .ok_or_else(|| Error::attr(&kp, "points", "this key has no points to edit"))?;
    if pts.len() != layer.rest_points.len() {
        return Err(Error::attr(&kp, "points", "point count differs from the layer's"));
    }
    Ok((kp, "points", pts))
}

/// `--key` names a key of the layer whose points a bake reads: a
/// PainterlyPoseKey or PainterlyTimeKey child of it, not a sentinel, not
/// one a bake skips. Any other prim with as many points (the layer itself,
/// whose `points` are stroke-local) would be edited as rest-space key
/// points that no bake reads as such.
fn check_key_prim(r: &StageReader, prim: &crate::usd_io::stage::Prim, kp: &str, layer: &str) -> Result<()> {
    let ty = r.type_name(prim)?;
    let what = if kp == layer {
        format!("the stroke layer itself ({})", crate::words::prim_of_type(&ty))
    } else {
        crate::words::prim_of_type(&ty)
    };
    let is_key = ty == "PainterlyPoseKey" || ty == "PainterlyTimeKey";
    let child = kp.rsplit_once('/').is_some_and(|(parent, _)| parent == layer);
    if !(is_key && child) {
        return Err(Error::prim(
            kp,
            format!(
                "is {what}, not a key of {layer}: --key names a PainterlyPoseKey or PainterlyTimeKey child of the layer"
            ),
        ));
    }
    if let Some(why) = r.unread_reason(prim)? {
        return Err(Error::prim(kp, format!("is {why}: a bake does not read this key")));
    }
    if ty == "PainterlyTimeKey" && r.typed(prim, "sentinel", None, "bool", values::scalar)?.unwrap_or(0.0) != 0.0 {
        return Err(Error::prim(
            kp,
            "is a sentinel: it carries no points (a bake ignores any authored there)",
        ));
    }
    Ok(())
}

/// Per point of the layer, whether `--strokes` selects it (all without it).
fn selected_points(layer: &StrokeLayer, strokes: Option<&[(usize, usize)]>) -> Result<Vec<bool>> {
    let npoints = layer.rest_points.len();
    let Some(strokes) = strokes else {
        return Ok(vec![true; npoints]);
    };
    let ncurves = layer.curve_counts.len();
    // The first selected index past the layer's strokes, if any.
    if let Some(s) = strokes
        .iter()
        .filter(|r| r.1 >= ncurves)
        .map(|r| r.0.max(ncurves))
        .min()
    {
        return Err(Error::prim(
            &layer.path,
            format!("--strokes {s} is out of range (the layer has {ncurves} strokes)"),
        ));
    }
    let mut selected = vec![false; npoints];
    let mut starts = Vec::with_capacity(ncurves + 1);
    let mut acc = 0usize;
    for &c in &layer.curve_counts {
        starts.push(acc);
        acc += c as usize;
    }
    starts.push(acc);
    for &(a, b) in strokes {
        selected[starts[a]..starts[b + 1]].iter_mut().for_each(|x| *x = true);
    }
    Ok(selected)
}

/// World-space unit normals at the bound points: the posed proxy's vertex
/// normals (on the side its `orientation` faces) blended by the binding's
/// weights. `to_proxy` is the inverse of the proxy's linear part, whose
/// transpose carries normals to world space (a mirroring transform keeps
/// them on the side they face in the proxy's space).
fn world_normals(pose: &PosedRig, binding: &Binding, to_proxy: DMat3, left_handed: bool) -> Vec<DVec3> {
    let vn = tools::vertex_normals(&pose.posed, &pose.triangles, left_handed);
    let normal_m = to_proxy.transpose();
    binding
        .vertices
        .iter()
        .zip(&binding.weights)
        .map(|(tri, weights)| {
            let n = tri
                .iter()
                .zip(weights)
                .fold(DVec3::ZERO, |a, (&v, &w)| a + vn[v as usize] * w as f64);
            (normal_m * n).normalize_or_zero()
        })
        .collect()
}

/// Reads a tool path from a BasisCurves prim: its first curve's points at
/// `time` (default value when None), in world space.
pub fn path_from_prim(r: &StageReader, prim_path: &str, time: Option<f64>, xform_time: f64) -> Result<Vec<DVec3>> {
    let prim = r
        .user_prim("--path-prim", prim_path)?
        .ok_or_else(|| Error::prim(prim_path, "prim does not exist"))?;
    // A mesh's points would make a path through its vertices in index order.
    let ty = r.type_name(&prim)?;
    if ty != "BasisCurves" {
        return Err(Error::prim(
            prim_path,
            format!(
                "the tool path prim is {}, not a BasisCurves (--path-prim takes a curve)",
                crate::words::prim_of_type(&ty)
            ),
        ));
    }
    let pts = r
        .typed(&prim, "points", time, "point3f[]", values::vec3_array)?
        .ok_or_else(|| Error::attr(prim_path, "points", "the tool path prim has no points"))?;
    let n = r
        .typed(&prim, "curveVertexCounts", None, "int[]", values::int_array)?
        .and_then(|c| c.first().copied())
        .map_or(pts.len(), |c| (c.max(0) as usize).min(pts.len()));
    let m = r.local_to_world(&prim, time.unwrap_or(xform_time))?;
    Ok(pts[..n].iter().map(|p| m.transform_point3(p.as_dvec3())).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_key_past_the_interpolation_limit_is_refused() {
        let key = |i: usize| ExistingKey {
            path: format!("/L/k{i}"),
            ty: "PainterlyPoseKey".into(),
            coords: vec![i as f64],
            points: true,
            opacity: false,
            sentinel: false,
            authored: vec!["coordinates", "points"],
        };
        let opts = KeyOptions {
            layer: "/L".into(),
            time: 1.0,
            kind: KeyKind::Pose,
            name: None,
            points: true,
            opacity: None,
            replace: false,
            camera: None,
        };
        let place = KeyPlace {
            ty: "PainterlyPoseKey",
            coords: vec![0.5],
            scales: vec![1.0],
        };
        let keys = |n: usize| (0..n).map(key).collect::<Vec<_>>();
        assert!(check_channels_stay_readable(&opts, &keys(299), &place, "/L/new").is_ok());
        let e = check_channels_stay_readable(&opts, &keys(300), &place, "/L/new").unwrap_err();
        assert_eq!(
            (e.prim.as_deref(), e.message.as_str()),
            (
                Some("/L"),
                "the new key /L/new would make 301 position pose keys; painterly interpolates at most 300 at \
                 once, and the bake would refuse the layer: split them over layers or sentinels"
            )
        );
        // Already past the limit: the key does not make it so (the bake's error names it).
        assert!(check_channels_stay_readable(&opts, &keys(301), &place, "/L/new").is_ok());
        // Replacing one of 300 keeps 300.
        assert!(check_channels_stay_readable(&opts, &keys(300), &place, "/L/k7").is_ok());
    }

    #[test]
    fn a_singular_or_non_finite_blend_is_refused_naming_the_point() {
        // Two rotations half a turn apart about z: their even blend flattens x and y.
        let (a, b) = (
            DMat3::from_rotation_z(1.0),
            DMat3::from_rotation_z(1.0 + std::f64::consts::PI),
        );
        let flat = DAffine3::from_mat3_translation((a + b) * 0.5, DVec3::X);
        let infinite =
            DAffine3::from_mat3_translation(DMat3::from_diagonal(DVec3::new(f64::MAX, 4.0, 1.0)), DVec3::ZERO);
        for (m, what) in [(flat, "singular"), (infinite, "infinite determinant")] {
            let e = invert(&m, "/Paint/L", 7).expect_err(what).to_string();
            assert!(
                e.contains("/Paint/L") && e.contains("point 7") && e.contains("singular"),
                "{what}: {e}"
            );
        }
        let turn = DAffine3::from_mat3_translation(a * 2.0, DVec3::Y);
        let p = DVec3::new(0.3, -1.0, 2.0);
        let back = invert(&turn, "/Paint/L", 0)
            .unwrap()
            .transform_point3(turn.transform_point3(p));
        assert!((back - p).length() < 1e-12);
    }

    #[test]
    fn an_unnamed_key_takes_the_first_free_name_after_an_existing_one() {
        // Only the key this test names exists when the unnamed one is set: a
        // broken free-name search then returns it at once instead of scanning
        // forever (the fixture's Hair layer has no children of its own).
        use crate::usd_io::edit::EditTarget;
        let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/blowfish.usda");
        let dir = crate::test_dir::ScratchDir::new("author-names");
        let target = EditTarget::Layer(dir.join("e.usda"));
        let time_key = |time, name: Option<&str>| KeyOptions {
            layer: "/Blowfish/Paint/Hair".into(),
            time,
            kind: KeyKind::Time,
            name: name.map(String::from),
            points: true,
            opacity: None,
            replace: false,
            camera: None,
        };
        let session = EditSession::open(&input, &target).unwrap();
        assert_eq!(
            key(&session, &time_key(2.0, Some("time1"))).unwrap(),
            "/Blowfish/Paint/Hair/time1"
        );
        session.save().unwrap();
        // The CLI's help: "default: key1, time1, sentinel1, ...", the first free one.
        let session = EditSession::open(&input, &target).unwrap();
        assert_eq!(
            key(&session, &time_key(3.0, None)).unwrap(),
            "/Blowfish/Paint/Hair/time2"
        );
    }
}
