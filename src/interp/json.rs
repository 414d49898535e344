//! JSON front end of the interpolators: the body of `painterly interpolate`,
//! which lets tests in other languages compare weights with a reference.
//!
//! Input (stdin of the subcommand):
//! `{"method": "smoothVoronoi" | "rbf" | "shepard", "radius": 1.0,
//!   "keys": [[x00, x01, ...], ...], "points": [[...], ...]}`;
//! `radius` is optional (RBF only, default 1.0). Output:
//! `{"weights": [[w_0, ..., w_{n-1}], ...]}`, one row per point, numbers
//! printed with full round-trip precision.

use super::{Interpolator, Method};
use serde::{Deserialize, Serialize};

/// Largest request read from stdin: a request is a few keys and the points
/// of a plot, and reading without a bound would let `/dev/zero` take all
/// memory.
pub const MAX_REQUEST_BYTES: u64 = 64 << 20;

/// Largest answer, in weights (points × keys): each is about 20 bytes of
/// JSON, so this keeps the answer near 100 MB.
pub const MAX_WEIGHTS: usize = 4_000_000;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Input {
    method: String,
    #[serde(default)]
    radius: Option<f64>,
    keys: Vec<Vec<f64>>,
    points: Vec<Vec<f64>>,
}

#[derive(Serialize)]
struct Output {
    weights: Vec<Vec<f64>>,
}

/// Parses the request, interpolates every point and returns the response
/// JSON; the error string names the problem (bad JSON, unknown method,
/// inconsistent dimensions, invalid keys).
pub fn run_json(input: &str) -> Result<String, String> {
    let req: Input = serde_json::from_str(input).map_err(|e| format!("invalid input JSON: {e}"))?;
    let radius = req.radius.unwrap_or(1.0);
    let method = Method::from_token(&req.method, radius).ok_or_else(|| {
        format!(
            "unknown method {:?} (expected \"smoothVoronoi\", \"rbf\" or \"shepard\")",
            req.method
        )
    })?;
    let dim = req.keys.first().map_or(0, Vec::len);
    if !req.keys.is_empty() && dim == 0 {
        return Err("the keys have no coordinates".into());
    }
    if let Some((k, key)) = req.keys.iter().enumerate().find(|(_, k)| k.len() != dim) {
        return Err(format!("key {k} has {} coordinates, key 0 has {dim}", key.len()));
    }
    let count = req.points.len().saturating_mul(req.keys.len());
    if count > MAX_WEIGHTS {
        return Err(format!(
            "{} points × {} keys is {count} weights; painterly interpolate answers at most {MAX_WEIGHTS} \
             per request (send the points in several requests)",
            req.points.len(),
            req.keys.len()
        ));
    }
    crate::vlog!(
        "interpolate: {} keys of {dim} coordinates, {} points, method {}",
        req.keys.len(),
        req.points.len(),
        req.method
    );
    let flat: Vec<f64> = req.keys.concat();
    let started = std::time::Instant::now();
    let interp = Interpolator::new(method, dim, &flat).map_err(|e| e.to_string())?;
    let mut weights = Vec::with_capacity(req.points.len());
    for (p, point) in req.points.iter().enumerate() {
        if point.len() != dim {
            return Err(format!(
                "point {p} has {} coordinates, the keys have {dim}",
                point.len()
            ));
        }
        let w = interp.weights_vec(point);
        if let Some(problem) = super::query_problem(point, &w) {
            return Err(format!("point {p} {problem}"));
        }
        weights.push(w);
    }
    crate::vlog!("interpolate: weights in {:.3} s", started.elapsed().as_secs_f64());
    serde_json::to_string(&Output { weights }).map_err(|e| format!("cannot write output: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let out = run_json(
            r#"{"method": "smoothVoronoi", "keys": [[0, 0], [1, 0], [0, 1]],
                "points": [[0, 0], [0.25, 0.25]]}"#,
        )
        .unwrap();
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        let w = v["weights"].as_array().unwrap();
        assert_eq!(w.len(), 2);
        assert_eq!(w[0], serde_json::json!([1.0, 0.0, 0.0]));
        let s: f64 = w[1].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).sum();
        assert!((s - 1.0).abs() < 1e-12);

        let out = run_json(r#"{"method": "rbf", "radius": 0.5, "keys": [[0], [1]], "points": [[0.5]]}"#).unwrap();
        assert!(out.contains("0.5"), "{out}");

        let err = |s: &str| run_json(s).unwrap_err();
        assert!(err("not json").contains("invalid input JSON"));
        assert!(err(r#"{"method": "linear", "keys": [[0]], "points": []}"#).contains("linear"));
        assert!(err(r#"{"method": "shepard", "keys": [[0], [1, 2]], "points": []}"#).contains("key 1"));
        assert!(err(r#"{"method": "shepard", "keys": [[0], [1]], "points": [[1, 2]]}"#).contains("point 0"));
        assert!(err(r#"{"method": "shepard", "keys": [], "points": []}"#).contains("no keys"));
        assert!(err(r#"{"method": "shepard", "keys": [[0], [0]], "points": []}"#).contains("keys 0 and 1"));
        assert!(err(r#"{"method": "rbf", "radius": -1, "keys": [[0], [1]], "points": []}"#).contains("radius"));
        assert!(err(r#"{"method": "rbf", "raduis": 1, "keys": [[0]], "points": []}"#).contains("raduis"));
    }

    #[test]
    fn an_answer_over_the_weight_limit_is_refused_before_any_weight() {
        // 2,000,001 points × 2 keys = 4,000,002 weights, one past the limit;
        // 2,000,000 points are exactly at it and answered.
        let request = |n: usize| {
            let points = vec!["[0.5]"; n].join(",");
            format!(r#"{{"method": "shepard", "keys": [[0], [1]], "points": [{points}]}}"#)
        };
        let e = run_json(&request(2_000_001)).unwrap_err();
        assert_eq!(
            e,
            "2000001 points × 2 keys is 4000002 weights; painterly interpolate answers at most 4000000 \
             per request (send the points in several requests)"
        );
        assert!(run_json(&request(2_000_000)).is_ok());
    }
}
