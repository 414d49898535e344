//! BasisCurves as plain data, and their tessellation into polylines (one per
//! stroke) with per-point width, colour and opacity.
//!
//! Follows UsdGeomBasisCurves: `linear` curves are their control polygons
//! (`periodic` ones closed); `cubic` curves with `bezier` (vstep 3),
//! `bspline` or `catmullRom` (vstep 1) basis are evaluated at
//! [`STEPS_PER_SPAN`] points per span; `pinned` bspline/catmullRom curves get
//! phantom end points `2·P₀ − P₁` so they reach their end points. Primvars:
//! `constant`, `uniform` (per curve), `vertex` (per control point, through
//! the same basis as the points) and `varying` (per span end, linear along
//! the span; `faceVarying` is read as `varying`).

use std::ops::{Add, Mul};

use glam::{DVec3, Vec3};

/// Points evaluated per cubic span.
pub const STEPS_PER_SPAN: usize = 8;

/// How a primvar's values map onto a prim's elements.
#[derive(Debug, Clone, PartialEq)]
pub enum Primvar<T> {
    Constant(T),
    /// One per curve (per face on a mesh).
    Uniform(Vec<T>),
    /// One per point.
    Vertex(Vec<T>),
    /// Curves: one per span end. Meshes: one per point.
    Varying(Vec<T>),
    /// One per face-vertex (meshes).
    FaceVarying(Vec<T>),
}

impl<T: Copy> Primvar<T> {
    /// The interpolation token.
    pub fn interpolation(&self) -> &'static str {
        match self {
            Primvar::Constant(_) => "constant",
            Primvar::Uniform(_) => "uniform",
            Primvar::Vertex(_) => "vertex",
            Primvar::Varying(_) => "varying",
            Primvar::FaceVarying(_) => "faceVarying",
        }
    }

    /// Number of values (1 for constant).
    pub fn len(&self) -> usize {
        match self {
            Primvar::Constant(_) => 1,
            Primvar::Uniform(v) | Primvar::Vertex(v) | Primvar::Varying(v) | Primvar::FaceVarying(v) => v.len(),
        }
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Applies `f` to every value.
    pub fn map<U>(&self, f: impl Fn(T) -> U) -> Primvar<U> {
        let m = |v: &Vec<T>| v.iter().map(|&x| f(x)).collect::<Vec<U>>();
        match self {
            Primvar::Constant(x) => Primvar::Constant(f(*x)),
            Primvar::Uniform(v) => Primvar::Uniform(m(v)),
            Primvar::Vertex(v) => Primvar::Vertex(m(v)),
            Primvar::Varying(v) => Primvar::Varying(m(v)),
            Primvar::FaceVarying(v) => Primvar::FaceVarying(m(v)),
        }
    }
}

/// `type`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurveType {
    Linear,
    Cubic,
}

/// `basis` (cubic curves).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Basis {
    Bezier,
    Bspline,
    CatmullRom,
}

/// `wrap`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrap {
    Nonperiodic,
    Periodic,
    Pinned,
}

/// One BasisCurves prim at one time, in world space.
#[derive(Debug, Clone)]
pub struct CurvesData {
    pub path: String,
    pub curve_type: CurveType,
    pub basis: Basis,
    pub wrap: Wrap,
    /// `curveVertexCounts`.
    pub counts: Vec<usize>,
    /// World-space points.
    pub points: Vec<DVec3>,
    /// World-space widths.
    pub widths: Primvar<f32>,
    /// Linear colours.
    pub colors: Primvar<Vec3>,
    pub opacities: Primvar<f32>,
}

/// One stroke as a polyline.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Polyline {
    pub points: Vec<DVec3>,
    pub widths: Vec<f32>,
    pub colors: Vec<Vec3>,
    pub opacities: Vec<f32>,
}

/// What is wrong with a curves prim: attribute and message.
pub type CurvesProblem = (&'static str, String);

impl CurvesData {
    /// Cubic spans of a curve of `n` control points (linear curves: segments).
    fn spans(&self, n: usize) -> usize {
        match (self.curve_type, self.basis, self.wrap) {
            (CurveType::Linear, _, Wrap::Periodic) => n,
            (CurveType::Linear, _, _) => n.saturating_sub(1),
            (CurveType::Cubic, Basis::Bezier, Wrap::Periodic) => n / 3,
            (CurveType::Cubic, Basis::Bezier, _) => n.saturating_sub(1) / 3,
            (CurveType::Cubic, _, Wrap::Periodic) => n,
            (CurveType::Cubic, _, Wrap::Pinned) => n.saturating_sub(1),
            (CurveType::Cubic, _, Wrap::Nonperiodic) => n.saturating_sub(3),
        }
    }

    /// `varying` values of a curve of `n` control points.
    fn varying_len(&self, n: usize) -> usize {
        let s = self.spans(n);
        if self.wrap == Wrap::Periodic {
            s
        } else {
            s + 1
        }
    }

    /// Checks counts against points and primvar lengths.
    pub fn validate(&self) -> Result<(), CurvesProblem> {
        let total: usize = self.counts.iter().sum();
        if total != self.points.len() {
            return Err((
                "curveVertexCounts",
                format!("counts sum to {total}, but there are {} points", self.points.len()),
            ));
        }
        let varying: usize = self.counts.iter().map(|&n| self.varying_len(n)).sum();
        let check = |name: &'static str, len: usize, interp: &str| -> Result<(), CurvesProblem> {
            let want = match interp {
                "constant" => 1,
                "uniform" => self.counts.len(),
                "vertex" => self.points.len(),
                _ => varying,
            };
            if len == want {
                Ok(())
            } else {
                Err((
                    name,
                    format!(
                        "{len} values with {interp} interpolation, expected {want} ({} curves, {} points)",
                        self.counts.len(),
                        self.points.len()
                    ),
                ))
            }
        };
        check("widths", self.widths.len(), self.widths.interpolation())?;
        check("primvars:displayColor", self.colors.len(), self.colors.interpolation())?;
        check(
            "primvars:displayOpacity",
            self.opacities.len(),
            self.opacities.interpolation(),
        )?;
        Ok(())
    }

    /// Every curve as a polyline (call [`CurvesData::validate`] first).
    /// Cubic curves too short for one span yield an empty polyline.
    pub fn polylines(&self) -> Vec<Polyline> {
        let mut out = Vec::with_capacity(self.counts.len());
        let (mut offset, mut var_offset) = (0, 0);
        for (c, &n) in self.counts.iter().enumerate() {
            let nv = self.varying_len(n);
            out.push(self.polyline(c, offset, n, var_offset));
            offset += n;
            var_offset += nv;
        }
        out
    }

    fn polyline(&self, c: usize, o: usize, n: usize, vo: usize) -> Polyline {
        let pts = &self.points[o..o + n];
        let spans = self.spans(n);
        let nv = self.varying_len(n);
        if self.curve_type == CurveType::Linear {
            // The control points, closed when periodic.
            let mut idx: Vec<usize> = (0..n).collect();
            if self.wrap == Wrap::Periodic && n > 2 {
                idx.push(0);
            }
            let vary = |i: usize| vo + i % nv.max(1);
            return Polyline {
                points: idx.iter().map(|&i| pts[i]).collect(),
                widths: idx.iter().map(|&i| attr(&self.widths, c, o + i, vary(i))).collect(),
                colors: idx.iter().map(|&i| attr(&self.colors, c, o + i, vary(i))).collect(),
                opacities: idx.iter().map(|&i| attr(&self.opacities, c, o + i, vary(i))).collect(),
            };
        }
        if spans == 0 {
            // Too few points for one cubic span: not a drawable curve.
            return Polyline::default();
        }
        // Control indices (into the curve) of each span's four points; -1 / n
        // stand for the pinned phantom points.
        let step = if self.basis == Basis::Bezier { 3 } else { 1 };
        let ctrl = |s: usize, k: usize| -> isize {
            match self.wrap {
                Wrap::Periodic => ((s * step + k) % n) as isize,
                Wrap::Pinned if self.basis != Basis::Bezier => (s + k) as isize - 1,
                _ => (s * step + k) as isize,
            }
        };
        fn fetch<T: Copy + Add<Output = T> + Mul<f32, Output = T>>(vals: &dyn Fn(usize) -> T, n: usize, i: isize) -> T {
            if i < 0 {
                vals(0) * 2.0 + vals(1) * -1.0
            } else if i as usize >= n {
                vals(n - 1) * 2.0 + vals(n - 2) * -1.0
            } else {
                vals(i as usize)
            }
        }
        let basis = self.basis;
        let mut line = Polyline::default();
        for s in 0..spans {
            let last = s + 1 == spans;
            let steps = if last { STEPS_PER_SPAN + 1 } else { STEPS_PER_SPAN };
            for k in 0..steps {
                let t = k as f32 / STEPS_PER_SPAN as f32;
                let w = weights(basis, t);
                let idx = [ctrl(s, 0), ctrl(s, 1), ctrl(s, 2), ctrl(s, 3)];
                let pos_of = |i: usize| pts[i];
                let mut p = DVec3::ZERO;
                for j in 0..4 {
                    let q = if idx[j] < 0 {
                        pos_of(0) * 2.0 - pos_of(1)
                    } else if idx[j] as usize >= n {
                        pos_of(n - 1) * 2.0 - pos_of(n - 2)
                    } else {
                        pos_of(idx[j] as usize)
                    };
                    p += q * w[j] as f64;
                }
                line.points.push(p);
                let va = vo + s % nv.max(1);
                let vb = vo + (s + 1) % nv.max(1);
                macro_rules! eval {
                    ($pv:expr) => {{
                        match $pv {
                            Primvar::Vertex(v) => {
                                let get = |i: usize| v[o + i];
                                (1..4).fold(fetch(&get, n, idx[0]) * w[0], |acc, j| {
                                    acc + fetch(&get, n, idx[j]) * w[j]
                                })
                            }
                            Primvar::Varying(v) | Primvar::FaceVarying(v) => v[va] * (1.0 - t) + v[vb] * t,
                            other => attr(other, c, 0, 0),
                        }
                    }};
                }
                line.widths.push(eval!(&self.widths).max(0.0));
                line.colors.push(eval!(&self.colors));
                line.opacities.push(eval!(&self.opacities).clamp(0.0, 1.0));
            }
        }
        line
    }
}

/// A primvar's value for curve `c`, point `i`, varying index `v`.
fn attr<T: Copy>(p: &Primvar<T>, c: usize, i: usize, v: usize) -> T {
    match p {
        Primvar::Constant(x) => *x,
        Primvar::Uniform(a) => a[c],
        Primvar::Vertex(a) => a[i],
        Primvar::Varying(a) | Primvar::FaceVarying(a) => a[v],
    }
}

/// Cubic basis weights at `t` in [0, 1].
pub fn weights(basis: Basis, t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    let u = 1.0 - t;
    match basis {
        Basis::Bezier => [u * u * u, 3.0 * t * u * u, 3.0 * t2 * u, t3],
        Basis::Bspline => [
            u * u * u / 6.0,
            (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
            (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0,
        ],
        Basis::CatmullRom => [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curves(curve_type: CurveType, basis: Basis, wrap: Wrap, pts: Vec<DVec3>) -> CurvesData {
        CurvesData {
            path: "/C".into(),
            curve_type,
            basis,
            wrap,
            counts: vec![pts.len()],
            widths: Primvar::Vertex((0..pts.len()).map(|i| i as f32).collect()),
            colors: Primvar::Constant(Vec3::ONE),
            opacities: Primvar::Uniform(vec![0.5]),
            points: pts,
        }
    }

    fn line_pts(n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| DVec3::new(i as f64, (i * i) as f64 * 0.1, 0.0))
            .collect()
    }

    #[test]
    fn linear_curves_are_their_control_points() {
        let c = curves(CurveType::Linear, Basis::Bezier, Wrap::Nonperiodic, line_pts(4));
        c.validate().unwrap();
        let p = &c.polylines()[0];
        assert_eq!(p.points, line_pts(4));
        assert_eq!(p.widths, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(p.opacities, vec![0.5; 4]);
        let closed = curves(CurveType::Linear, Basis::Bezier, Wrap::Periodic, line_pts(4));
        assert_eq!(closed.polylines()[0].points.len(), 5);
    }

    #[test]
    fn cubic_curves_reach_their_ends() {
        let bez = curves(CurveType::Cubic, Basis::Bezier, Wrap::Nonperiodic, line_pts(7));
        bez.validate().unwrap();
        let p = &bez.polylines()[0];
        assert_eq!(p.points.len(), 2 * STEPS_PER_SPAN + 1);
        assert_eq!(p.points[0], line_pts(7)[0]);
        assert!((p.points[p.points.len() - 1] - line_pts(7)[6]).length() < 1e-6);
        assert!((p.points[STEPS_PER_SPAN] - line_pts(7)[3]).length() < 1e-6);
        // Pinned catmullRom passes through every control point, ends included.
        let cr = curves(CurveType::Cubic, Basis::CatmullRom, Wrap::Pinned, line_pts(5));
        cr.validate().unwrap();
        let p = &cr.polylines()[0];
        for (k, want) in line_pts(5).iter().enumerate() {
            assert!((p.points[k * STEPS_PER_SPAN] - *want).length() < 1e-6, "{k}");
        }
        assert!((p.widths[2 * STEPS_PER_SPAN] - 2.0).abs() < 1e-5);
        // Bases are partitions of unity.
        for b in [Basis::Bezier, Basis::Bspline, Basis::CatmullRom] {
            for t in [0.0, 0.3, 1.0] {
                assert!((weights(b, t).iter().sum::<f32>() - 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn mismatched_primvars_are_reported() {
        let mut c = curves(CurveType::Linear, Basis::Bezier, Wrap::Nonperiodic, line_pts(4));
        c.widths = Primvar::Vertex(vec![1.0; 3]);
        assert_eq!(c.validate().unwrap_err().0, "widths");
        c.widths = Primvar::Constant(1.0);
        c.counts = vec![5];
        assert_eq!(c.validate().unwrap_err().0, "curveVertexCounts");
    }
}
