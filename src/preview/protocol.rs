//! What the preview page and the server say to each other (docs/preview.md).
//!
//! Requests are small JSON objects, checked here before they reach the
//! evaluator. Bulk data goes back as one binary buffer: a little-endian
//! `u32` magic, a `u32` header length, a JSON header (padded with spaces to
//! a multiple of 4 bytes) and a Float32 payload. The header's `arrays` maps
//! each array's name to `[offset, length]`, both counted in floats from the
//! payload's start.

use std::collections::BTreeMap;

use serde::de::{DeserializeOwned, Deserializer, Error as _};
use serde::{Deserialize, Serialize};

use crate::character::Configuration;

/// "PTLY", little-endian.
pub const MAGIC: u32 = u32::from_le_bytes(*b"PTLY");

/// The most pixels a render request may ask for (per side).
pub const MAX_RENDER_SIDE: usize = 4096;

/// One frame to evaluate.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameRequest {
    /// Echoed in the reply, so a page can match replies to requests.
    #[serde(default)]
    pub id: u64,
    /// Time code.
    pub time: f64,
    /// Axis prim path → value (axis units): the pose mode's pinned sliders.
    #[serde(default)]
    pub overrides: Configuration,
    /// World-space eye for viewDirection axes and view-dependent meshes
    /// ("view drives"); absent: the stage's cameras.
    #[serde(default)]
    pub eye: Option<[f64; 3]>,
    /// Also send the posed proxies.
    #[serde(default)]
    pub proxy: bool,
    /// Send the `--bake` layer's points at `time` instead of evaluating
    /// (overrides and eye do not apply).
    #[serde(default)]
    pub bake: bool,
}

/// The orbit camera, as the page draws it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewCamera {
    /// Eye position, world space.
    pub position: [f64; 3],
    /// The point looked at.
    pub target: [f64; 3],
    /// Up direction.
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_y: f64,
    pub near: f64,
    pub far: f64,
}

/// A `painterly render` frame of the current view.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderRequest {
    #[serde(deserialize_with = "object")]
    pub frame: FrameRequest,
    #[serde(deserialize_with = "object")]
    pub camera: ViewCamera,
    pub width: usize,
    pub height: usize,
}

/// A request the server refuses (HTTP 400).
#[derive(Debug, Clone, PartialEq)]
pub struct BadRequest(pub String);

/// What a JSON value is, in words.
fn json_kind(v: &serde_json::Value) -> &'static str {
    use serde_json::Value as V;
    match v {
        V::Null => "null",
        V::Bool(_) => "a boolean",
        V::Number(_) => "a number",
        V::String(_) => "a string",
        V::Array(_) => "an array",
        V::Object(_) => "an object",
    }
}

/// Reads a request (a [`FrameRequest`], a [`RenderRequest`]) from the JSON
/// text of a body or a websocket message. A request is a JSON object (so
/// are a render request's `frame` and `camera`, see [`object`]): serde also
/// reads a struct from an array of its fields in order (`[7, 12]` as
/// `{"id": 7, "time": 12}`), which the protocol does not speak.
pub fn from_json<T: DeserializeOwned>(text: &[u8]) -> Result<T, BadRequest> {
    let bad = |e: serde_json::Error| BadRequest(format!("bad request: {e}"));
    // A JSON text that is an object starts with `{` after whitespace.
    if text.iter().find(|b| !b" \t\r\n".contains(b)) != Some(&b'{') {
        let v: serde_json::Value = serde_json::from_slice(text).map_err(bad)?;
        return Err(BadRequest(format!(
            "bad request: expected a JSON object, found {}",
            json_kind(&v)
        )));
    }
    serde_json::from_slice(text).map_err(bad)
}

/// Reads a request's field that is a struct from a JSON object only (see
/// [`from_json`]).
fn object<'de, D: Deserializer<'de>, T: DeserializeOwned>(d: D) -> Result<T, D::Error> {
    let v = serde_json::Value::deserialize(d)?;
    if !v.is_object() {
        return Err(D::Error::custom(format!(
            "expected a JSON object, found {}",
            json_kind(&v)
        )));
    }
    T::deserialize(v).map_err(D::Error::custom)
}

fn finite(what: &str, v: &[f64]) -> Result<(), BadRequest> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(BadRequest(format!("{what} must be finite, got {v:?}")))
    }
}

impl FrameRequest {
    /// Checks numbers and axis names against the opened character.
    pub fn check(&self, axes: &[String]) -> Result<(), BadRequest> {
        finite("time", &[self.time])?;
        if let Some(e) = &self.eye {
            finite("eye", e)?;
        }
        for (path, v) in &self.overrides {
            if !axes.iter().any(|a| a == path) {
                return Err(BadRequest(format!("{path} is not an axis of this character")));
            }
            finite(path, &[*v])?;
        }
        Ok(())
    }
}

impl RenderRequest {
    /// Checks the frame, the camera and the image size.
    pub fn check(&self, axes: &[String]) -> Result<(), BadRequest> {
        self.frame.check(axes)?;
        let c = &self.camera;
        finite("camera.position", &c.position)?;
        finite("camera.target", &c.target)?;
        finite("camera.up", &c.up)?;
        finite("camera fov_y, near and far", &[c.fov_y, c.near, c.far])?;
        if !(c.fov_y > 0.1 && c.fov_y < 179.0) {
            return Err(BadRequest(format!(
                "camera.fov_y {} is not in (0.1, 179) degrees",
                c.fov_y
            )));
        }
        if !(c.near > 0.0 && c.far > c.near) {
            return Err(BadRequest(format!(
                "camera near {} and far {} must satisfy 0 < near < far",
                c.near, c.far
            )));
        }
        for (what, n) in [("width", self.width), ("height", self.height)] {
            if n == 0 || n > MAX_RENDER_SIDE {
                return Err(BadRequest(format!("{what} {n} is not in 1..={MAX_RENDER_SIDE}")));
            }
        }
        Ok(())
    }
}

/// Builds a binary reply: named Float32 arrays behind a JSON header.
#[derive(Default)]
pub struct Buffer {
    arrays: BTreeMap<String, [usize; 2]>,
    floats: Vec<f32>,
}

impl Buffer {
    /// Appends an array under `name`.
    pub fn push(&mut self, name: impl Into<String>, values: impl IntoIterator<Item = f32>) {
        let start = self.floats.len();
        self.floats.extend(values);
        self.arrays.insert(name.into(), [start, self.floats.len() - start]);
    }

    /// The reply: magic, header length, header (`header` plus `arrays`), payload.
    pub fn finish(self, header: serde_json::Value) -> Vec<u8> {
        let mut header = match header {
            serde_json::Value::Object(m) => m,
            other => {
                let mut m = serde_json::Map::new();
                m.insert("value".into(), other);
                m
            }
        };
        header.insert(
            "arrays".into(),
            serde_json::to_value(&self.arrays).unwrap_or(serde_json::Value::Null),
        );
        let mut json = serde_json::to_vec(&header).unwrap_or_else(|_| b"{}".to_vec());
        while json.len() % 4 != 0 {
            json.push(b' ');
        }
        let mut out = Vec::with_capacity(8 + json.len() + 4 * self.floats.len());
        out.extend_from_slice(&MAGIC.to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(&json);
        out.extend_from_slice(bytemuck::cast_slice(&self.floats));
        out
    }
}

/// Reads a reply back (tests and tools): the header and the payload.
pub fn decode(bytes: &[u8]) -> Option<(serde_json::Value, Vec<f32>)> {
    let word = |i: usize| {
        bytes
            .get(i..i + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if word(0)? != MAGIC {
        return None;
    }
    let n = word(4)? as usize;
    let header = serde_json::from_slice(bytes.get(8..8 + n)?).ok()?;
    let payload = bytes.get(8 + n..)?;
    if payload.len() % 4 != 0 {
        return None;
    }
    let floats = payload
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Some((header, floats))
}

/// One pose key's mark on its axis's slider.
#[derive(Debug, Clone, Serialize)]
pub struct KeyMark {
    /// The key prim.
    pub key: String,
    /// Its coordinate on this axis (axis units, as authored).
    pub coordinate: f64,
}

/// One axis and its slider.
#[derive(Debug, Clone, Serialize)]
pub struct AxisInfo {
    pub path: String,
    pub rig: String,
    pub kind: String,
    /// Slider range: the keys' coordinates and the values over the
    /// timeline, padded.
    pub min: f64,
    pub max: f64,
    pub keys: Vec<KeyMark>,
}

/// One stroke layer: where it lives and Bassett's Table I counts.
#[derive(Debug, Clone, Serialize)]
pub struct LayerInfo {
    pub path: String,
    pub rig: String,
    pub strokes: usize,
    pub points: usize,
    pub pose_position_keys: usize,
    pub pose_opacity_keys: usize,
    pub time_keys: usize,
    pub sentinels: usize,
    /// Points per stroke.
    pub curve_counts: Vec<u32>,
    /// Axis paths its pose keys are placed on, in coordinate order.
    pub axes: Vec<String>,
}

/// A polygon mesh's topology and look.
#[derive(Debug, Clone, Serialize)]
pub struct MeshInfo {
    pub path: String,
    pub face_counts: Vec<u32>,
    pub face_indices: Vec<u32>,
    /// Smooth normals (subdivision surfaces) or faceted.
    pub smooth: bool,
    /// Linear display colour (the first authored one).
    pub color: [f32; 3],
    /// For view-dependent meshes: the camera they are seen from.
    pub camera: Option<String>,
}

/// A problem `painterly inspect` reports.
#[derive(Debug, Clone, Serialize)]
pub struct ProblemInfo {
    pub prim: Option<String>,
    pub attribute: Option<String>,
    pub message: String,
}

/// Where the page's orbit camera starts.
#[derive(Debug, Clone, Serialize)]
pub struct StartView {
    pub position: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub fov_y: f64,
    /// Width over height of the frame the view starts on: the USD camera's
    /// apertures, or 1 (a square around the bounds). A pane narrower than
    /// this widens `fov_y` so the whole frame stays in view (CameraUtil's
    /// `Fit`).
    pub aspect: f64,
    /// The USD camera it came from, if any.
    pub camera: Option<String>,
}

/// Everything about the opened character that does not change per frame.
#[derive(Debug, Clone, Serialize)]
pub struct SceneInfo {
    pub file: String,
    pub start: f64,
    pub end: f64,
    pub frames_per_second: f64,
    pub up_axis: String,
    pub layers: Vec<LayerInfo>,
    pub axes: Vec<AxisInfo>,
    pub proxies: Vec<MeshInfo>,
    pub views: Vec<MeshInfo>,
    pub problems: Vec<ProblemInfo>,
    pub view: StartView,
    /// Scene bounds (world), for the orbit's zoom range.
    pub bounds: [[f64; 3]; 2],
    /// The `--bake` layer, when given.
    pub bake: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_round_trip_with_aligned_payload() {
        let mut b = Buffer::default();
        b.push("a", [1.0, 2.0, 3.0]);
        b.push("b", [4.5]);
        let bytes = b.finish(serde_json::json!({"time": 3}));
        let n = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
        assert_eq!(n % 4, 0);
        let (h, f) = decode(&bytes).unwrap();
        assert_eq!(f, [1.0, 2.0, 3.0, 4.5]);
        assert_eq!(h["time"], 3);
        assert_eq!(h["arrays"]["a"], serde_json::json!([0, 3]));
        assert_eq!(h["arrays"]["b"], serde_json::json!([3, 1]));
        assert!(decode(b"nope").is_none());
    }

    #[test]
    fn requests_are_checked() {
        let axes = vec!["/A/x".to_string()];
        let ok: FrameRequest = serde_json::from_str(r#"{"time": 3, "overrides": {"/A/x": 0.5}}"#).unwrap();
        assert!(ok.check(&axes).is_ok());
        let unknown: FrameRequest = serde_json::from_str(r#"{"time": 3, "overrides": {"/A/y": 0.5}}"#).unwrap();
        assert!(unknown.check(&axes).is_err());
        assert!(serde_json::from_str::<FrameRequest>(r#"{"time": 3, "bogus": 1}"#).is_err());
        let r: RenderRequest = serde_json::from_str(
            r#"{"frame": {"time": 1}, "camera": {"position": [0,0,5], "target": [0,0,0], "up": [0,1,0],
                "fov_y": 45, "near": 0.1, "far": 100}, "width": 0, "height": 10}"#,
        )
        .unwrap();
        assert!(r.check(&axes).unwrap_err().0.contains("width"));
    }

    /// Requests are JSON objects, and so are a render request's frame and
    /// camera: serde's reading of a struct from an array of its fields in
    /// order (`[7, 12]` as id 7, time 12) is refused.
    #[test]
    fn requests_are_json_objects_only() {
        let frame = from_json::<FrameRequest>(b" \n{\"id\": 7, \"time\": 12}").unwrap();
        assert_eq!((frame.id, frame.time), (7, 12.0));
        assert!(
            serde_json::from_str::<FrameRequest>("[7, 12]").is_ok(),
            "what from_json refuses"
        );
        let err = |text: &str| from_json::<FrameRequest>(text.as_bytes()).unwrap_err().0;
        for (text, found) in [
            ("[7, 12]", "an array"),
            (" [7, 12, {}, null, false, false]", "an array"),
            ("12", "a number"),
            ("\"time\"", "a string"),
            ("null", "null"),
            ("true", "a boolean"),
        ] {
            assert_eq!(
                err(text),
                format!("bad request: expected a JSON object, found {found}"),
                "{text}"
            );
        }
        assert!(
            err("[7, 12").starts_with("bad request: EOF while parsing a list"),
            "{}",
            err("[7, 12")
        );
        assert!(err("").starts_with("bad request: EOF while parsing a value"));
        let cam = r#"{"position": [0,0,5], "target": [0,0,0], "up": [0,1,0], "fov_y": 45, "near": 0.1, "far": 100}"#;
        let render = |frame: &str, camera: &str| {
            from_json::<RenderRequest>(
                format!(r#"{{"frame": {frame}, "camera": {camera}, "width": 8, "height": 8}}"#).as_bytes(),
            )
            .map(|r| (r.frame.time, r.camera.far))
        };
        assert_eq!(render(r#"{"time": 2}"#, cam), Ok((2.0, 100.0)));
        let refused = |r: Result<(f64, f64), BadRequest>| r.unwrap_err().0;
        assert!(refused(render("[0, 2]", cam)).starts_with("bad request: expected a JSON object, found an array"));
        assert!(
            refused(render(r#"{"time": 2}"#, "[[0,0,5], [0,0,0], [0,1,0], 45, 0.1, 100]"))
                .starts_with("bad request: expected a JSON object, found an array")
        );
        assert!(refused(render(r#"{"time": 2, "bogus": 1}"#, cam)).contains("unknown field `bogus`"));
    }

    fn render_request(camera: serde_json::Value, width: usize, height: usize) -> RenderRequest {
        serde_json::from_value(serde_json::json!({
            "frame": {"time": 1}, "camera": camera, "width": width, "height": height
        }))
        .unwrap()
    }

    fn camera(fov_y: f64, near: f64, far: f64) -> serde_json::Value {
        serde_json::json!({"position": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0],
            "fov_y": fov_y, "near": near, "far": far})
    }

    #[test]
    fn render_bounds_are_open_where_documented() {
        // fov_y in the open interval (0.1, 179) degrees, 0 < near < far, and
        // 1..=MAX_RENDER_SIDE pixels a side: each bound and its neighbour.
        let axes: Vec<String> = Vec::new();
        let verdict = |c: serde_json::Value, w: usize, h: usize| render_request(c, w, h).check(&axes).map_err(|e| e.0);
        let err = |c, w, h| verdict(c, w, h).unwrap_err();
        assert!(verdict(camera(45.0, 0.1, 100.0), 64, 64).is_ok());
        assert!(err(camera(0.1, 0.1, 100.0), 64, 64).contains("fov_y 0.1 is not in"));
        assert!(verdict(camera(0.1001, 0.1, 100.0), 64, 64).is_ok());
        assert!(err(camera(179.0, 0.1, 100.0), 64, 64).contains("fov_y 179"));
        assert!(verdict(camera(178.99, 0.1, 100.0), 64, 64).is_ok());
        assert!(err(camera(45.0, 0.0, 100.0), 64, 64).contains("near 0 and far 100"));
        assert!(err(camera(45.0, 2.0, 2.0), 64, 64).contains("0 < near < far"));
        assert!(err(camera(45.0, 2.0, 1.0), 64, 64).contains("0 < near < far"));
        assert!(verdict(camera(45.0, 1e-9, 2e-9), MAX_RENDER_SIDE, 1).is_ok());
        assert!(err(camera(45.0, 0.1, 100.0), MAX_RENDER_SIDE + 1, 1).contains("width 4097"));
        assert!(err(camera(45.0, 0.1, 100.0), 1, 0).contains("height 0 is not in 1..=4096"));
        assert!(err(camera(45.0, 0.1, 100.0), 1, MAX_RENDER_SIDE + 1).contains("height 4097"));
    }

    #[test]
    fn numbers_that_json_cannot_carry_are_refused_too() {
        // serde_json refuses 1e999 and JSON has no NaN, so these come only
        // from requests built in Rust (the evaluator's own, other front doors).
        assert!(serde_json::from_str::<FrameRequest>(r#"{"time": 1e999}"#).is_err());
        let axes = vec!["/A/x".to_string()];
        let frame = |time: f64, eye: Option<[f64; 3]>, x: f64| FrameRequest {
            id: 0,
            time,
            overrides: [("/A/x".to_string(), x)].into_iter().collect(),
            eye,
            proxy: false,
            bake: false,
        };
        assert!(frame(1.0, Some([0.0, 1.0, 2.0]), 0.5).check(&axes).is_ok());
        let msg = |f: FrameRequest| f.check(&axes).unwrap_err().0;
        assert_eq!(msg(frame(f64::NAN, None, 0.5)), "time must be finite, got [NaN]");
        assert!(msg(frame(1.0, Some([0.0, f64::INFINITY, 0.0]), 0.5)).starts_with("eye must be finite"));
        assert!(msg(frame(1.0, None, f64::NEG_INFINITY)).starts_with("/A/x must be finite"));
        let mut r = render_request(camera(45.0, 0.1, 100.0), 8, 8);
        r.camera.up[2] = f64::NAN;
        assert!(r.check(&axes).unwrap_err().0.starts_with("camera.up must be finite"));
        let mut r = render_request(camera(45.0, 0.1, 100.0), 8, 8);
        r.camera.far = f64::INFINITY;
        assert!(r
            .check(&axes)
            .unwrap_err()
            .0
            .starts_with("camera fov_y, near and far must be finite"));
    }
}
