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

impl CurveType {
    /// The `type` token's value.
    pub fn from_token(t: &str) -> Option<CurveType> {
        Some(match t {
            "linear" => CurveType::Linear,
            "cubic" => CurveType::Cubic,
            _ => return None,
        })
    }
}

impl Basis {
    /// The `basis` token's value.
    pub fn from_token(t: &str) -> Option<Basis> {
        Some(match t {
            "bezier" => Basis::Bezier,
            "bspline" => Basis::Bspline,
            "catmullRom" => Basis::CatmullRom,
            _ => return None,
        })
    }
}

impl Wrap {
    /// The `wrap` token's value.
    pub fn from_token(t: &str) -> Option<Wrap> {
        Some(match t {
            "nonperiodic" => Wrap::Nonperiodic,
            "periodic" => Wrap::Periodic,
            "pinned" => Wrap::Pinned,
            _ => return None,
        })
    }
}

/// Cubic spans of a curve of `n` control points (linear curves: segments),
/// as UsdGeomBasisCurves counts them.
pub fn spans(curve_type: CurveType, basis: Basis, wrap: Wrap, n: usize) -> usize {
    match (curve_type, basis, wrap) {
        (CurveType::Linear, _, Wrap::Periodic) => n,
        (CurveType::Linear, _, _) => n.saturating_sub(1),
        (CurveType::Cubic, Basis::Bezier, Wrap::Periodic) => n / 3,
        (CurveType::Cubic, Basis::Bezier, _) => n.saturating_sub(1) / 3,
        (CurveType::Cubic, _, Wrap::Periodic) => n,
        (CurveType::Cubic, _, Wrap::Pinned) => n.saturating_sub(1),
        (CurveType::Cubic, _, Wrap::Nonperiodic) => n.saturating_sub(3),
    }
}

/// `varying` values of a curve of `n` control points: one per span end.
pub fn varying_len(curve_type: CurveType, basis: Basis, wrap: Wrap, n: usize) -> usize {
    let s = spans(curve_type, basis, wrap, n);
    if wrap == Wrap::Periodic {
        s
    } else {
        s + 1
    }
}

/// How many values usd-core's `ComputeVaryingDataSize` expects of a
/// `varying` primvar on one curve of `n` vertices: what a file's author
/// validates against. It treats `pinned` as `nonperiodic` and gives a linear
/// periodic curve n + 1, so it differs from [`varying_len`] (the span ends
/// drawn) there.
pub fn usd_varying_data_size(curve_type: CurveType, basis: Basis, wrap: Wrap, n: usize) -> usize {
    match (curve_type, basis, wrap) {
        (CurveType::Linear, _, Wrap::Periodic) => n + 1,
        (CurveType::Linear, _, _) => n,
        (CurveType::Cubic, Basis::Bezier, Wrap::Periodic) => n / 3,
        (CurveType::Cubic, _, Wrap::Periodic) => n,
        (CurveType::Cubic, Basis::Bezier, _) => n.saturating_sub(4) / 3 + 2,
        (CurveType::Cubic, _, _) => n.saturating_sub(2),
    }
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
        spans(self.curve_type, self.basis, self.wrap, n)
    }

    /// `varying` values of a curve of `n` control points.
    fn varying_len(&self, n: usize) -> usize {
        varying_len(self.curve_type, self.basis, self.wrap, n)
    }

    /// Takes `varying` primvars authored with usd-core's count
    /// ([`usd_varying_data_size`]) where it differs from the span ends
    /// drawn ([`varying_len`]): a pinned B-spline or Catmull-Rom curve of n
    /// points has n - 2 values (its span ends were it not pinned: control
    /// points 1 to n - 2), drawn at n span ends (control points 0 to n - 1),
    /// so the end spans the pinning adds take the nearest value; a linear
    /// periodic curve has n + 1, the last closing the loop on the first
    /// point, which is drawn with the first. Other lengths are left for
    /// [`Self::validate`] to report.
    pub fn adopt_usd_varying(&mut self) {
        let (ty, basis, wrap) = (self.curve_type, self.basis, self.wrap);
        // Per curve: (usd-core's count, the span ends drawn).
        let sizes: Vec<(usize, usize)> = self
            .counts
            .iter()
            .map(|&n| {
                (
                    usd_varying_data_size(ty, basis, wrap, n),
                    varying_len(ty, basis, wrap, n),
                )
            })
            .collect();
        let usd: usize = sizes.iter().map(|s| s.0).sum();
        let drawn: usize = sizes.iter().map(|s| s.1).sum();
        if usd == drawn || sizes.iter().any(|s| s.0 == 0) {
            return;
        }
        // For each drawn span end, the authored value it takes.
        let mut idx = Vec::with_capacity(drawn);
        let mut o = 0;
        for &(have, want) in &sizes {
            let last = o + have - 1;
            for k in 0..want {
                let j = if (ty, wrap) == (CurveType::Cubic, Wrap::Pinned) {
                    k.saturating_sub(1)
                } else {
                    k
                };
                idx.push((o + j).min(last));
            }
            o += have;
        }
        fn take<T: Copy>(p: &mut Primvar<T>, usd: usize, idx: &[usize]) {
            if let Primvar::Varying(v) | Primvar::FaceVarying(v) = p {
                if v.len() == usd && !v.is_empty() {
                    *v = idx.iter().map(|&i| v[i]).collect();
                }
            }
        }
        take(&mut self.widths, usd, &idx);
        take(&mut self.colors, usd, &idx);
        take(&mut self.opacities, usd, &idx);
    }

    /// A `varying` primvar (one value per span end, as drawn) at each
    /// control point, for a viewer that draws curves through their control
    /// points: a control point takes the value at the curve parameter
    /// nearest to it, interpolated between the span ends around it
    /// (Bézier: point i at a third of the way per point; B-spline and
    /// Catmull-Rom: span s runs from point s + 1 to s + 2, pinned from s to
    /// s + 1; linear: one per point).
    pub fn varying_at_points<T: Copy + Add<Output = T> + Mul<f32, Output = T>>(&self, v: &[T]) -> Vec<T> {
        let mut out = Vec::with_capacity(self.points.len());
        let mut vo = 0;
        for &n in &self.counts {
            let nv = self.varying_len(n);
            for i in 0..n {
                if nv == 0 || v.len() < vo + nv {
                    break;
                }
                let u = match (self.curve_type, self.basis, self.wrap) {
                    (CurveType::Linear, _, _) => i as f32,
                    (CurveType::Cubic, Basis::Bezier, _) => i as f32 / 3.0,
                    (CurveType::Cubic, _, Wrap::Pinned) => i as f32,
                    (CurveType::Cubic, _, Wrap::Periodic) => ((i + n - 1) % n) as f32,
                    (CurveType::Cubic, _, Wrap::Nonperiodic) => i as f32 - 1.0,
                };
                let periodic = self.wrap == Wrap::Periodic;
                let u = if periodic { u } else { u.clamp(0.0, (nv - 1) as f32) };
                let a = u.floor() as usize;
                let t = u - a as f32;
                let at = |k: usize| {
                    if periodic {
                        v[vo + k % nv]
                    } else {
                        v[vo + k.min(nv - 1)]
                    }
                };
                out.push(if t == 0.0 {
                    at(a)
                } else {
                    at(a) * (1.0 - t) + at(a + 1) * t
                });
            }
            vo += nv;
        }
        out
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
        // What usd-core counts (and the message names); see [`Self::adopt_usd_varying`].
        let usd_varying: usize = self
            .counts
            .iter()
            .map(|&n| usd_varying_data_size(self.curve_type, self.basis, self.wrap, n))
            .sum();
        let check = |name: &'static str, len: usize, interp: &str| -> Result<(), CurvesProblem> {
            // Varying: the span ends drawn (usd-core's count once adopted).
            let (want, named) = match interp {
                "constant" => (1, 1),
                "uniform" => (self.counts.len(), self.counts.len()),
                "vertex" => (self.points.len(), self.points.len()),
                _ => (varying, usd_varying),
            };
            if len == want {
                Ok(())
            } else {
                Err((
                    name,
                    format!(
                        "{len} values with {interp} interpolation, expected {named} ({} curves, {} points)",
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

    /// Why some of these curves draw nothing, when they do not: too few
    /// points for one span of their type and basis (a linear curve needs
    /// two, a cubic one its basis's minimum), or no positive width along
    /// the evaluated curve (negative widths draw as 0; a Bézier curve's
    /// points past its last whole span, and a Catmull-Rom curve's negative
    /// weights, can leave a positive control width unseen). `lines` are
    /// this prim's [`CurvesData::polylines`], which the caller draws too.
    pub fn undrawn(&self, lines: &[Polyline]) -> Option<String> {
        let (mut short, mut thin) = (0, 0);
        for (line, &n) in lines.iter().zip(&self.counts) {
            if n == 0 {
                continue;
            }
            if line.points.len() < 2 {
                short += 1;
            } else if line.widths.iter().all(|&w| w <= 0.0) {
                thin += 1;
            }
        }
        let mut why = Vec::new();
        if short > 0 {
            why.push(format!("{short} with too few points for one span"));
        }
        if thin > 0 {
            why.push(format!("{thin} without a positive width"));
        }
        (!why.is_empty()).then(|| {
            format!(
                "{}: {} of {} draw nothing ({})",
                self.path,
                short + thin,
                crate::words::plural(self.counts.len(), "curve"),
                why.join(", ")
            )
        })
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

    #[test]
    fn varying_data_size_is_usd_cores() {
        // usd-core 26.11's BasisCurves.ComputeVaryingDataSize for one curve
        // of n = 4..=10 vertices (printed with usd-core, 2026-12-07).
        use {Basis::*, CurveType::*, Wrap::*};
        let table: [(CurveType, Basis, Wrap, [usize; 7]); 8] = [
            (Cubic, Bezier, Nonperiodic, [2, 2, 2, 3, 3, 3, 4]),
            (Cubic, Bezier, Periodic, [1, 1, 2, 2, 2, 3, 3]),
            (Cubic, Bezier, Pinned, [2, 2, 2, 3, 3, 3, 4]),
            (Cubic, Bspline, Nonperiodic, [2, 3, 4, 5, 6, 7, 8]),
            (Cubic, CatmullRom, Periodic, [4, 5, 6, 7, 8, 9, 10]),
            (Cubic, CatmullRom, Pinned, [2, 3, 4, 5, 6, 7, 8]),
            (Linear, Bezier, Nonperiodic, [4, 5, 6, 7, 8, 9, 10]),
            (Linear, Bspline, Periodic, [5, 6, 7, 8, 9, 10, 11]),
        ];
        for (ty, basis, wrap, want) in table {
            let got: Vec<usize> = (4..=10).map(|n| usd_varying_data_size(ty, basis, wrap, n)).collect();
            assert_eq!(got, want, "{ty:?} {basis:?} {wrap:?}");
        }
    }

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
    fn varying_primvars_with_usd_core_s_count_are_drawn() {
        // A pinned Catmull-Rom curve of 5 points: usd-core counts 3 varying
        // values (those of control points 1 to 3); the pinned curve draws 4
        // spans, 5 span ends, the ends taking the nearest value. Render and
        // preview refused these (the count drawn, 5, was required).
        let mut c = curves(CurveType::Cubic, Basis::CatmullRom, Wrap::Pinned, line_pts(5));
        c.widths = Primvar::Varying(vec![1.0, 2.0, 3.0]);
        c.colors = Primvar::Varying(vec![Vec3::X, Vec3::Y, Vec3::Z]);
        assert!(c.validate().is_err());
        c.adopt_usd_varying();
        assert_eq!(c.widths, Primvar::Varying(vec![1.0, 1.0, 2.0, 3.0, 3.0]));
        assert_eq!(
            c.colors,
            Primvar::Varying(vec![Vec3::X, Vec3::X, Vec3::Y, Vec3::Z, Vec3::Z])
        );
        assert_eq!(c.validate(), Ok(()));
        // The count drawn is taken as it is.
        let mut d = curves(CurveType::Cubic, Basis::CatmullRom, Wrap::Pinned, line_pts(5));
        d.widths = Primvar::Varying(vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        d.adopt_usd_varying();
        assert_eq!(d.widths, Primvar::Varying(vec![1.0, 2.0, 3.0, 4.0, 5.0]));
        // A linear periodic curve of 3 points: usd-core counts 4, the last
        // closing the loop; 3 are drawn.
        let mut l = curves(CurveType::Linear, Basis::Bezier, Wrap::Periodic, line_pts(3));
        l.widths = Primvar::Varying(vec![1.0, 2.0, 3.0, 1.0]);
        l.adopt_usd_varying();
        assert_eq!(l.widths, Primvar::Varying(vec![1.0, 2.0, 3.0]));
        assert_eq!(l.validate(), Ok(()));
        // Other lengths are left to validate, which names usd-core's count.
        let mut bad = curves(CurveType::Cubic, Basis::Bspline, Wrap::Pinned, line_pts(6));
        bad.widths = Primvar::Varying(vec![1.0; 7]);
        bad.adopt_usd_varying();
        assert_eq!(
            bad.validate(),
            Err((
                "widths",
                "7 values with varying interpolation, expected 4 (1 curves, 6 points)".to_string()
            ))
        );
    }

    #[test]
    fn undrawn_names_the_curves_that_draw_nothing() {
        let mut c = curves(CurveType::Cubic, Basis::Bspline, Wrap::Nonperiodic, line_pts(9));
        c.opacities = Primvar::Constant(1.0);
        // A nonperiodic B-spline needs 4 points; the middle one has them
        // but no width.
        c.counts = vec![3, 4, 2];
        c.widths = Primvar::Uniform(vec![1.0, 0.0, 1.0]);
        assert_eq!(
            c.undrawn(&c.polylines()).unwrap(),
            "/C: 3 of 3 curves draw nothing (2 with too few points for one span, 1 without a positive width)"
        );
        c.widths = Primvar::Constant(1.0);
        c.counts = vec![4, 5];
        assert_eq!(c.undrawn(&c.polylines()), None);
        // Empty curves are no problem; a periodic B-spline of 3 points has 3 spans.
        c.counts = vec![0, 3, 0, 6];
        c.wrap = Wrap::Periodic;
        assert_eq!(c.undrawn(&c.polylines()), None);
        c.wrap = Wrap::Nonperiodic;
        c.counts = vec![9];
        c.widths = Primvar::Varying(vec![0.0; 7]);
        assert_eq!(
            c.undrawn(&c.polylines()).unwrap(),
            "/C: 1 of 1 curve draw nothing (1 without a positive width)"
        );
        // A Bézier curve of 5 points is one span of 4: the fifth point's
        // width is never seen.
        let mut b = curves(CurveType::Cubic, Basis::Bezier, Wrap::Nonperiodic, line_pts(5));
        b.widths = Primvar::Vertex(vec![0.0, 0.0, 0.0, 0.0, 0.5]);
        assert_eq!(
            b.undrawn(&b.polylines()).unwrap(),
            "/C: 1 of 1 curve draw nothing (1 without a positive width)"
        );
        // A linear curve of one point is no segment.
        let mut l = curves(CurveType::Linear, Basis::Bezier, Wrap::Nonperiodic, line_pts(3));
        l.opacities = Primvar::Constant(1.0);
        l.widths = Primvar::Constant(1.0);
        l.counts = vec![1, 2];
        assert_eq!(
            l.undrawn(&l.polylines()).unwrap(),
            "/C: 1 of 2 curves draw nothing (1 with too few points for one span)"
        );
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

    // UsdGeomBasisCurves' segment counts and the bases' matrix forms, written
    // out here independently of `spans` and `weights`.

    /// Segments of a curve of n vertices (UsdGeomBasisCurves' table).
    fn segments(ty: CurveType, basis: Basis, wrap: Wrap, n: usize) -> usize {
        match (ty, wrap) {
            (CurveType::Linear, Wrap::Periodic) => n,
            (CurveType::Linear, _) => n - 1,
            (CurveType::Cubic, Wrap::Periodic) if basis == Basis::Bezier => n / 3,
            (CurveType::Cubic, _) if basis == Basis::Bezier => (n - 4) / 3 + 1,
            (CurveType::Cubic, Wrap::Periodic) => n,
            (CurveType::Cubic, Wrap::Pinned) => n - 1,
            (CurveType::Cubic, Wrap::Nonperiodic) => n - 3,
        }
    }

    const BASES: [Basis; 3] = [Basis::Bezier, Basis::Bspline, Basis::CatmullRom];
    const WRAPS: [Wrap; 3] = [Wrap::Nonperiodic, Wrap::Periodic, Wrap::Pinned];

    #[test]
    fn varying_primvars_have_one_value_per_segment_end() {
        for ty in [CurveType::Linear, CurveType::Cubic] {
            for basis in BASES {
                for wrap in WRAPS {
                    // Lengths valid for the basis (Bezier: 3k + 1, or 3k periodic).
                    for n in [4usize, 6, 7, 9, 10] {
                        let bezier = ty == CurveType::Cubic && basis == Basis::Bezier;
                        let fits = match wrap {
                            Wrap::Periodic => n % 3 == 0,
                            _ => n % 3 == 1,
                        };
                        if bezier && !fits {
                            continue;
                        }
                        let segs = segments(ty, basis, wrap, n);
                        let want = if wrap == Wrap::Periodic { segs } else { segs + 1 };
                        // Two curves: the varying count is the sum.
                        let mut c = curves(ty, basis, wrap, line_pts(n));
                        c.counts = vec![n, n];
                        c.points = [line_pts(n), line_pts(n)].concat();
                        c.widths = Primvar::Varying(vec![1.0; 2 * want]);
                        c.opacities = Primvar::Uniform(vec![1.0; 2]);
                        let case = format!("{ty:?} {basis:?} {wrap:?} n = {n}");
                        assert_eq!(c.validate(), Ok(()), "{case}");
                        c.widths = Primvar::Varying(vec![1.0; 2 * want + 1]);
                        let (attr, msg) = c.validate().unwrap_err();
                        assert_eq!(attr, "widths", "{case}");
                        // The message names usd-core's count (checked
                        // against usd-core in varying_data_size_is_usd_cores).
                        let expected = format!(
                            "{} values with varying interpolation, expected {} (2 curves, {} points)",
                            2 * want + 1,
                            2 * usd_varying_data_size(ty, basis, wrap, n),
                            2 * n
                        );
                        assert_eq!(msg, expected, "{case}");
                    }
                }
            }
        }
    }

    #[test]
    fn every_primvar_and_interpolation_is_checked() {
        let c = curves(CurveType::Linear, Basis::Bezier, Wrap::Nonperiodic, line_pts(4));
        let bad = |c: CurvesData| c.validate().unwrap_err();
        let with_colors = |colors| CurvesData { colors, ..c.clone() };
        assert_eq!(
            bad(with_colors(Primvar::Uniform(vec![Vec3::ONE; 2]))).0,
            "primvars:displayColor"
        );
        assert_eq!(with_colors(Primvar::Vertex(vec![Vec3::ONE; 4])).validate(), Ok(()));
        assert_eq!(with_colors(Primvar::FaceVarying(vec![Vec3::ONE; 4])).validate(), Ok(()));
        let with_opacity = |opacities| CurvesData { opacities, ..c.clone() };
        let (attr, msg) = bad(with_opacity(Primvar::Vertex(vec![1.0; 5])));
        assert_eq!(attr, "primvars:displayOpacity");
        assert_eq!(
            msg,
            "5 values with vertex interpolation, expected 4 (1 curves, 4 points)"
        );
        let (_, msg) = bad(with_opacity(Primvar::Uniform(vec![])));
        assert_eq!(
            msg,
            "0 values with uniform interpolation, expected 1 (1 curves, 4 points)"
        );
        assert_eq!(with_opacity(Primvar::Constant(0.5)).validate(), Ok(()));
        let (attr, msg) = bad(CurvesData {
            counts: vec![2, 3],
            ..c.clone()
        });
        assert_eq!(attr, "curveVertexCounts");
        assert_eq!(msg, "counts sum to 5, but there are 4 points");
        // Primvar helpers.
        let v = Primvar::Varying(vec![1.0f32, 2.0]);
        assert_eq!((v.len(), v.is_empty()), (2, false));
        assert!(Primvar::<f32>::Uniform(vec![]).is_empty());
        assert!(!Primvar::Constant(0.0f32).is_empty());
        assert_eq!(v.map(|x| x * 3.0), Primvar::Varying(vec![3.0, 6.0]));
        assert_eq!(Primvar::Constant(2.0f32).map(|x| x + 1.0), Primvar::Constant(3.0));
        assert_eq!(Primvar::Uniform(vec![1.0f32]).map(|x| -x), Primvar::Uniform(vec![-1.0]));
        assert_eq!(Primvar::Vertex(vec![1.0f32]).map(|x| -x), Primvar::Vertex(vec![-1.0]));
        assert_eq!(
            Primvar::FaceVarying(vec![1.0f32]).map(|x| -x),
            Primvar::FaceVarying(vec![-1.0])
        );
    }

    /// The basis matrix: row k holds the coefficients of t^k for the four
    /// control points.
    fn basis_matrix(b: Basis) -> [[f64; 4]; 4] {
        match b {
            Basis::Bezier => [
                [1.0, 0.0, 0.0, 0.0],
                [-3.0, 3.0, 0.0, 0.0],
                [3.0, -6.0, 3.0, 0.0],
                [-1.0, 3.0, -3.0, 1.0],
            ],
            Basis::Bspline => [
                [1.0, 4.0, 1.0, 0.0],
                [-3.0, 0.0, 3.0, 0.0],
                [3.0, -6.0, 3.0, 0.0],
                [-1.0, 3.0, -3.0, 1.0],
            ]
            .map(|r| r.map(|x| x / 6.0)),
            Basis::CatmullRom => [
                [0.0, 2.0, 0.0, 0.0],
                [-1.0, 0.0, 1.0, 0.0],
                [2.0, -5.0, 4.0, -1.0],
                [-1.0, 3.0, -3.0, 1.0],
            ]
            .map(|r| r.map(|x| x / 2.0)),
        }
    }

    fn matrix_weights(b: Basis, t: f64) -> [f64; 4] {
        let m = basis_matrix(b);
        let powers = [1.0, t, t * t, t * t * t];
        std::array::from_fn(|j| (0..4).map(|k| powers[k] * m[k][j]).sum())
    }

    #[test]
    fn weights_are_the_bases_matrix_forms() {
        for b in BASES {
            for k in 0..=16 {
                let t = k as f64 / 16.0;
                let (got, want) = (weights(b, t as f32), matrix_weights(b, t));
                for j in 0..4 {
                    assert!(
                        (got[j] as f64 - want[j]).abs() < 1e-6,
                        "{b:?} t = {t}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }

    /// The curve's points, vertex-interpolated widths and varying-interpolated
    /// opacities, evaluated from the table above: spans of four control
    /// vertices (mod n when periodic; pinned curves add 2P₀ − P₁ before and
    /// 2Pₙ₋₁ − Pₙ₋₂ after), STEPS_PER_SPAN samples each, t = 1 closing the last.
    fn reference(basis: Basis, wrap: Wrap, pts: &[DVec3], w: &[f64], op: &[f64]) -> Vec<(DVec3, f64, f64)> {
        let n = pts.len();
        let segs = segments(CurveType::Cubic, basis, wrap, n);
        let vertex = |i: isize| -> (DVec3, f64) {
            if wrap == Wrap::Periodic {
                let i = i.rem_euclid(n as isize) as usize;
                (pts[i], w[i])
            } else if i < 0 {
                (2.0 * pts[0] - pts[1], 2.0 * w[0] - w[1])
            } else if i as usize >= n {
                (2.0 * pts[n - 1] - pts[n - 2], 2.0 * w[n - 1] - w[n - 2])
            } else {
                (pts[i as usize], w[i as usize])
            }
        };
        let mut out = Vec::new();
        for s in 0..segs {
            let first: isize = match (basis, wrap) {
                (Basis::Bezier, _) => 3 * s as isize,
                (_, Wrap::Pinned) => s as isize - 1,
                _ => s as isize,
            };
            let last = s + 1 == segs;
            for k in 0..STEPS_PER_SPAN + usize::from(last) {
                let t = k as f64 / STEPS_PER_SPAN as f64;
                let m = matrix_weights(basis, t);
                let (mut p, mut width) = (DVec3::ZERO, 0.0);
                for (j, mj) in m.iter().enumerate() {
                    let (q, wq) = vertex(first + j as isize);
                    p += q * *mj;
                    width += wq * mj;
                }
                let nv = op.len();
                let o = op[s % nv] * (1.0 - t) + op[(s + 1) % nv] * t;
                out.push((p, width.max(0.0), o.clamp(0.0, 1.0)));
            }
        }
        out
    }

    #[test]
    fn cubic_curves_follow_their_basis_wrap_and_primvars() {
        use crate::interp::testutil::Lcg;
        let mut rng = Lcg::new(5);
        for basis in BASES {
            for wrap in WRAPS {
                let n = match (basis, wrap) {
                    (Basis::Bezier, Wrap::Periodic) => 9,
                    (Basis::Bezier, _) => 10,
                    _ => 7,
                };
                // Two curves, so every offset into points and primvars counts.
                let mut pts = Vec::new();
                let mut widths = Vec::new();
                for _ in 0..2 * n {
                    pts.push(DVec3::new(
                        rng.uniform(-5.0, 5.0),
                        rng.uniform(-5.0, 5.0),
                        rng.uniform(-5.0, 5.0),
                    ));
                    // Some negative: clamped to 0 after interpolation.
                    widths.push(rng.uniform(-0.2, 1.0) as f32);
                }
                let segs = segments(CurveType::Cubic, basis, wrap, n);
                let nv = if wrap == Wrap::Periodic { segs } else { segs + 1 };
                let opacities: Vec<f32> = (0..2 * nv).map(|_| rng.uniform(-0.3, 1.3) as f32).collect();
                let c = CurvesData {
                    path: "/C".into(),
                    curve_type: CurveType::Cubic,
                    basis,
                    wrap,
                    counts: vec![n, n],
                    points: pts.clone(),
                    widths: Primvar::Vertex(widths.clone()),
                    colors: Primvar::Uniform(vec![Vec3::X, Vec3::Y]),
                    opacities: Primvar::Varying(opacities.clone()),
                };
                c.validate().unwrap();
                let lines = c.polylines();
                assert_eq!(lines.len(), 2);
                for (curve, line) in lines.iter().enumerate() {
                    let r =
                        |v: &[f32], len: usize| v[curve * len..][..len].iter().map(|&x| x as f64).collect::<Vec<_>>();
                    let want = reference(basis, wrap, &pts[curve * n..][..n], &r(&widths, n), &r(&opacities, nv));
                    let case = format!("{basis:?} {wrap:?} curve {curve}");
                    assert_eq!(line.points.len(), want.len(), "{case}");
                    assert_eq!(line.points.len(), segs * STEPS_PER_SPAN + 1, "{case}");
                    for (k, (p, w, o)) in want.iter().enumerate() {
                        assert!((line.points[k] - *p).length() < 1e-5, "{case} sample {k}");
                        assert!(
                            (line.widths[k] as f64 - w).abs() < 1e-5,
                            "{case} sample {k}: {} vs {w}",
                            line.widths[k]
                        );
                        assert!((line.opacities[k] as f64 - o).abs() < 1e-5, "{case} sample {k}");
                    }
                    assert!(line.colors.iter().all(|&c| c == [Vec3::X, Vec3::Y][curve]), "{case}");
                }
            }
        }
    }

    #[test]
    fn linear_curves_take_primvars_per_vertex_and_segment_end() {
        // Two periodic triangles: closed, the varying value of vertex i is
        // value i (one per segment end, the last end being the first).
        let pts = [line_pts(3), line_pts(3)].concat();
        let c = CurvesData {
            path: "/C".into(),
            curve_type: CurveType::Linear,
            basis: Basis::Bezier,
            wrap: Wrap::Periodic,
            counts: vec![3, 3],
            points: pts.clone(),
            widths: Primvar::Varying(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            colors: Primvar::Vertex((0..6).map(|i| Vec3::splat(i as f32)).collect()),
            opacities: Primvar::Uniform(vec![0.25, 0.75]),
        };
        c.validate().unwrap();
        let l = c.polylines();
        assert_eq!(l[0].points, [pts[0], pts[1], pts[2], pts[0]]);
        assert_eq!(l[1].points, [pts[3], pts[4], pts[5], pts[3]]);
        assert_eq!(l[0].widths, [1.0, 2.0, 3.0, 1.0]);
        assert_eq!(l[1].widths, [4.0, 5.0, 6.0, 4.0]);
        assert_eq!(l[1].colors, [3.0, 4.0, 5.0, 3.0].map(Vec3::splat));
        assert_eq!((l[0].opacities[3], l[1].opacities[0]), (0.25, 0.75));
        // A periodic curve of two points is not closed; nonperiodic varying
        // values run one per point.
        let two = CurvesData {
            counts: vec![2],
            points: line_pts(2),
            widths: Primvar::Varying(vec![1.0, 2.0]),
            colors: Primvar::Constant(Vec3::ONE),
            opacities: Primvar::Constant(1.0),
            ..c.clone()
        };
        assert_eq!(two.polylines()[0].points, line_pts(2));
        let open = CurvesData {
            wrap: Wrap::Nonperiodic,
            counts: vec![4],
            points: line_pts(4),
            widths: Primvar::Varying(vec![1.0, 2.0, 3.0, 4.0]),
            ..two
        };
        open.validate().unwrap();
        assert_eq!(open.polylines()[0].widths, [1.0, 2.0, 3.0, 4.0]);
        // Too short for a cubic span: an empty polyline.
        let short = curves(CurveType::Cubic, Basis::Bspline, Wrap::Nonperiodic, line_pts(3));
        assert_eq!(short.polylines()[0], Polyline::default());
    }

    #[test]
    fn linear_curves_take_vertex_opacities_from_their_own_points() {
        // Two open curves of three points, one opacity per point: each point
        // keeps its own value, the second curve reading from offset 3.
        let c = CurvesData {
            counts: vec![3, 3],
            points: [line_pts(3), line_pts(3)].concat(),
            widths: Primvar::Constant(1.0),
            opacities: Primvar::Vertex(vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6]),
            ..curves(CurveType::Linear, Basis::Bezier, Wrap::Nonperiodic, vec![])
        };
        c.validate().unwrap();
        let l = c.polylines();
        assert_eq!(l[0].opacities, [0.1, 0.2, 0.3]);
        assert_eq!(l[1].opacities, [0.4, 0.5, 0.6]);
    }
}
