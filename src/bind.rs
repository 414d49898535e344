//! Binding stroke points to the proxy: closest point on the rest triangles.
//!
//! Bassett §3.2: "simply associating each stroke with the closest geometric
//! primitive of the mesh has proven to be sufficient"; the barycentric
//! coordinates of the closest point are the skinning weights. SPEC §3 pins
//! the result so that independent implementations agree: distances in f64
//! by the region-based closest point below, and among triangles whose
//! closest points lie within 1e-6 × the bounding-box diagonal of the
//! smallest distance, the lowest triangle index (fan order) wins. Both sides
//! of a split texture seam are such a tie.
//!
//! The search is a bounding-volume hierarchy over the triangles (median
//! splits, f32 boxes rounded outwards so they always contain their f64
//! triangles), built binary and queried four-wide (four child boxes tested
//! in one pass of f32 lanes), per point in parallel. A query keeps every
//! triangle within the tie tolerance of the best distance found so far and
//! prunes only boxes farther than that (plus a margin for f32 and f64
//! rounding), so its answer is exactly the brute-force answer of
//! [`bind_brute_force`].

use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Per stroke point: its triangle's three proxy vertices and weights.
///
/// This is the flat "stencil table" of the bake: computed once, applied to the
/// per-vertex motions of every frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Binding {
    /// The three proxy vertex indices of each point's bound triangle.
    pub vertices: Vec<[u32; 3]>,
    /// Barycentric weights (non-negative, summing to 1) of each point.
    pub weights: Vec<[f32; 3]>,
}

impl Binding {
    /// Number of bound points.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True when no points are bound.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }
}

/// Triangles per BVH leaf.
const LEAF_SIZE: usize = 4;

/// A BVH node: an f32 box; a leaf holds `count` triangles from `first` in
/// [`ClosestPoint::leaf_tris`], an inner node (`count == 0`) has children
/// `first` and `first + 1`.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: [f32; 3],
    hi: [f32; 3],
    first: u32,
    count: u32,
}

/// A BVH over the rest-pose triangles, built once per proxy.
pub struct ClosestPoint {
    points: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    nodes: Vec<Node>,
    /// The triangles in leaf order, with what prunes them cheaply.
    leaf_tris: Vec<LeafTri>,
    /// Their corners, in the same order: a leaf's exact tests read
    /// neighbouring memory instead of three scattered vertices each.
    leaf_corners: Vec<[DVec3; 3]>,
    /// The same hierarchy with four children per node (the binary tree's
    /// grandchildren), queried: one pass over f32 lanes tests four boxes.
    wide: Vec<Wide>,
    /// The leaves of `wide`: their triangles' boxes, four at a time.
    groups: Vec<LeafGroup>,
    /// SPEC §3 tie tolerance (1e-6 × bounding-box diagonal).
    tol: f64,
    /// Absolute slack added to pruning distances: covers the rounding of
    /// distances computed at coordinates of this size.
    slack: f64,
    /// How far a plane distance from f32 `n`, `d` may undershoot the true
    /// one at the mesh; a query adds its own term for its distance from
    /// the origin.
    plane_slack: f64,
}

/// A triangle as a leaf stores it: its index, its f32 box (rounded
/// outwards) and its plane `n·x = d` in f32 (`n` unit, zero for a
/// degenerate triangle). Box and plane distances are lower bounds of the
/// distance to the triangle, checked before the exact f64 test; the plane
/// prunes triangle soups whose boxes all overlap.
#[derive(Clone, Copy, Debug)]
struct LeafTri {
    lo: [f32; 3],
    hi: [f32; 3],
    plane: [f32; 4],
    index: u32,
}

/// Subtrees at least this large are split in parallel.
const PAR_BUILD: usize = 1 << 14;

/// The f32 value at or below `x` (at or above when `up`).
fn round_f32(x: f64, up: bool) -> f32 {
    let f = x as f32;
    if up && (f as f64) < x {
        f.next_up()
    } else if !up && (f as f64) > x {
        f.next_down()
    } else {
        f
    }
}

impl ClosestPoint {
    /// Builds the BVH. `triangles` must index into `points` (callers
    /// validate); an empty triangle list gives a BVH that cannot bind.
    pub fn new(points: &[DVec3], triangles: &[[u32; 3]]) -> Self {
        let tol = tie_tolerance(points);
        let extent = points.iter().fold(0.0f64, |m, p| m.max(p.length()));
        let mut cp = ClosestPoint {
            points: points.to_vec(),
            triangles: triangles.to_vec(),
            nodes: Vec::new(),
            leaf_tris: Vec::new(),
            leaf_corners: Vec::new(),
            wide: Vec::new(),
            groups: Vec::new(),
            tol,
            slack: 1e-12 * (extent + tol * 1e6),
            // Rounding n and d to f32 (relative 2⁻²⁴ each), and the f64
            // error in n's direction (kept below about 5e-8 by the sliver
            // test in `leaf_tri`), move n·x − d by at most about
            // 1.2e-7·(|x| + |d|) at a point x; |d| ≤ extent. The query adds
            // 1e-6·|p| for its own point.
            plane_slack: 1e-6 * extent,
        };
        cp.build();
        cp
    }

    fn leaf_tri(&self, t: u32) -> LeafTri {
        let [a, b, c] = self.triangles[t as usize].map(|v| self.points[v as usize]);
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let n = (b - a).cross(c - a);
        let len = n.length();
        // A sliver (height below 1e-8 of its longest edge) gets no plane:
        // its f64 normal's direction may be off by more than the slack
        // allows (error up to about 4.4e-16 × |ab| |ac| / |n|).
        let longest2 = (b - a)
            .length_squared()
            .max((c - a).length_squared())
            .max((c - b).length_squared());
        let plane = if len > 1e-8 * longest2 && len.is_finite() {
            let n = n / len;
            [n.x as f32, n.y as f32, n.z as f32, n.dot(a) as f32]
        } else {
            [0.0; 4]
        };
        LeafTri {
            lo: [0, 1, 2].map(|k| round_f32(lo[k], false)),
            hi: [0, 1, 2].map(|k| round_f32(hi[k], true)),
            plane,
            index: t,
        }
    }

    /// Median splits along the longest axis of the centroids' box (large
    /// subtrees in parallel); then boxes bottom-up (children always follow
    /// their parent).
    fn build(&mut self) {
        let n = self.triangles.len();
        if n == 0 {
            return;
        }
        let mut items: Vec<([f32; 3], u32)> = (0..n as u32)
            .into_par_iter()
            .map(|t| {
                let [a, b, c] = self.triangles[t as usize].map(|v| self.points[v as usize]);
                (((a + b + c) / 3.0).as_vec3().to_array(), t)
            })
            .collect();
        let mut nodes = split(&mut items, 0);
        self.leaf_tris = items.par_iter().map(|&(_, t)| self.leaf_tri(t)).collect();
        self.leaf_corners = items
            .iter()
            .map(|&(_, t)| self.triangles[t as usize].map(|v| self.points[v as usize]))
            .collect();
        for i in (0..nodes.len()).rev() {
            let Node { first, count, .. } = nodes[i];
            let (lo, hi) = if count > 0 {
                self.leaf_tris[first as usize..(first + count) as usize]
                    .iter()
                    .map(|t| (t.lo, t.hi))
                    .reduce(|(l0, h0), (l1, h1)| union(l0, h0, l1, h1))
                    .expect("leaves are not empty")
            } else {
                let (a, b) = (nodes[first as usize], nodes[first as usize + 1]);
                union(a.lo, a.hi, b.lo, b.hi)
            };
            nodes[i].lo = lo;
            nodes[i].hi = hi;
        }
        self.nodes = nodes;
        (self.wide, self.groups) = widen(&self.nodes, &self.leaf_tris);
    }

    /// Exact f64 distance from `p` to triangle `t` and the barycentrics of
    /// its closest point.
    fn distance(&self, p: DVec3, t: u32) -> (f64, [f64; 3]) {
        let [a, b, c] = self.triangles[t as usize].map(|v| self.points[v as usize]);
        triangle_distance(p, a, b, c)
    }

    /// Closest point on the triangle set under the SPEC §3 tie rule:
    /// (triangle index, barycentrics).
    ///
    /// # Panics
    /// On an empty triangle set.
    pub fn query(&self, p: DVec3) -> (usize, [f64; 3]) {
        let mut scratch = Scratch::default();
        self.query_with(p, None, &mut scratch)
    }

    /// [`Self::query`] starting from `hint`, a triangle likely to be close
    /// (the previous point's), which only speeds the search up.
    ///
    /// Boxes are tested in f32, four at a time, against a bound rounded so
    /// that a box is skipped only when its exact distance exceeds best + tie
    /// tolerance (+ rounding slack): every triangle the f64 test would keep
    /// is still tested exactly, so the answer is the brute-force one.
    fn query_with(&self, p: DVec3, hint: Option<u32>, s: &mut Scratch) -> (usize, [f64; 3]) {
        assert!(!self.wide.is_empty(), "closest point on an empty triangle set");
        s.found.clear();
        s.stack.clear();
        let mut best = f64::INFINITY;
        if let Some(t) = hint {
            let (d, w) = self.distance(p, t);
            best = d;
            s.found.push((t, d, w));
        }
        // Box distances are taken from p rounded to f32; that moves them
        // by at most |p - p32|, added to the bound.
        let p32 = p.as_vec3();
        let shift = (p - p32.as_dvec3()).length();
        let q = p32.to_array();
        let limit = |best: f64| f32_bound2(best + self.tol + self.slack + shift);
        let mut limit2 = limit(best);
        // The plane's f32 rounding moves n·p − d in proportion to |p| too:
        // a point far from a tilted mesh sees it far more than the mesh.
        let plane_slack = self.plane_slack + 1e-6 * p.length();
        s.stack.push((0u32, 0.0));
        while let Some((ni, d2)) = s.stack.pop() {
            if d2 > limit2 {
                continue;
            }
            s.work.nodes += 1;
            let node = &self.wide[ni as usize];
            let dist = node.boxes.distance2(q);
            let mut inner = [(0u32, 0f32); 4];
            let mut n_inner = 0;
            for (&d2, &child) in dist.iter().zip(&node.child).take(node.len as usize) {
                if d2 > limit2 {
                    continue;
                }
                if child & LEAF_FLAG == 0 {
                    inner[n_inner] = (child, d2);
                    n_inner += 1;
                    continue;
                }
                let group = &self.groups[(child & !LEAF_FLAG) as usize];
                let tri_dist = group.boxes.distance2(q);
                let first = group.first as usize;
                for (i, lt) in self.leaf_tris[first..][..group.len as usize].iter().enumerate() {
                    if tri_dist[i] > limit2 || Some(lt.index) == hint {
                        continue;
                    }
                    let bound = best + self.tol + self.slack;
                    let [nx, ny, nz, nd] = lt.plane.map(f64::from);
                    if (nx * p.x + ny * p.y + nz * p.z - nd).abs() - plane_slack > bound {
                        continue;
                    }
                    let [a, b, c] = self.leaf_corners[first + i];
                    s.work.exact += 1;
                    let (d, w) = triangle_distance(p, a, b, c);
                    if d <= best + self.tol {
                        s.found.push((lt.index, d, w));
                        if d < best {
                            best = d;
                            limit2 = limit(best);
                        }
                    }
                }
            }
            // Farther children first, so the nearest is searched next.
            let inner = &mut inner[..n_inner];
            inner.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
            s.stack.extend_from_slice(inner);
        }
        let (t, _, w) = s
            .found
            .iter()
            .filter(|f| f.1 <= best + self.tol)
            .min_by_key(|f| f.0)
            .copied()
            .expect("the nearest triangle is always found");
        (t as usize, w)
    }

    /// Binds every point (must be finite) to its closest triangle (SPEC §3),
    /// in parallel over points.
    ///
    /// # Panics
    /// On an empty triangle set with points to bind.
    pub fn bind(&self, points: &[Vec3]) -> Binding {
        // Queries in Morton order: neighbours in space are neighbours in
        // the queue, so each starts from its predecessor's triangle and
        // finds the BVH nodes it needs still in cache. Each result depends
        // on its point only, so the order changes nothing but speed.
        const CHUNK: usize = 256;
        let order = self.morton_order(points);
        let mut found = vec![(0u32, [0f32; 3]); points.len()];
        let per_chunk: Vec<Vec<(u32, [f32; 3])>> = order
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut s = Scratch::default();
                let mut hint = None;
                chunk
                    .iter()
                    .map(|&i| {
                        let (t, w) = self.query_with(points[i as usize].as_dvec3(), hint, &mut s);
                        hint = Some(t as u32);
                        (t as u32, [w[0] as f32, w[1] as f32, w[2] as f32])
                    })
                    .collect()
            })
            .collect();
        for (&i, r) in order.iter().zip(per_chunk.into_iter().flatten()) {
            found[i as usize] = r;
        }
        Binding {
            vertices: found.iter().map(|&(t, _)| self.triangles[t as usize]).collect(),
            weights: found.into_iter().map(|(_, w)| w).collect(),
        }
    }

    /// Indices of `points` sorted by the Morton code of their position in
    /// the BVH's box (10 bits per axis; points outside are clamped to it).
    fn morton_order(&self, points: &[Vec3]) -> Vec<u32> {
        let Some(root) = self.nodes.first() else {
            return (0..points.len() as u32).collect();
        };
        let (lo, hi) = (Vec3::from_array(root.lo), Vec3::from_array(root.hi));
        let scale = Vec3::splat(1023.0) / (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
        let spread = |x: u32| {
            // 10 bits to every third of 30.
            let mut x = x & 0x3ff;
            x = (x | (x << 16)) & 0x030000ff;
            x = (x | (x << 8)) & 0x0300f00f;
            x = (x | (x << 4)) & 0x030c30c3;
            (x | (x << 2)) & 0x09249249
        };
        let mut keyed: Vec<(u32, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let q = ((*p - lo) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
                let code = spread(q.x as u32) | (spread(q.y as u32) << 1) | (spread(q.z as u32) << 2);
                (code, i as u32)
            })
            .collect();
        keyed.par_sort_unstable();
        keyed.into_iter().map(|(_, i)| i).collect()
    }
}

/// Per-thread query buffers.
#[derive(Default)]
struct Scratch {
    stack: Vec<(u32, f32)>,
    /// (triangle, distance, barycentrics) within the tie tolerance of the
    /// best distance at the time it was found.
    found: Vec<(u32, f64, [f64; 3])>,
    /// What the queries cost, for tests that pin the pruning.
    work: Work,
}

/// Wide nodes opened and exact triangle distances computed (the hint's
/// aside), summed over queries.
#[derive(Default, Debug, Clone, Copy)]
struct Work {
    nodes: u64,
    exact: u64,
}

fn union(l0: [f32; 3], h0: [f32; 3], l1: [f32; 3], h1: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    ([0, 1, 2].map(|k| l0[k].min(l1[k])), [0, 1, 2].map(|k| h0[k].max(h1[k])))
}

/// Marks a [`Wide`] child that is a leaf (its index in
/// `ClosestPoint::groups`) rather than another wide node.
const LEAF_FLAG: u32 = 1 << 31;

/// A node of the four-wide hierarchy: up to four children's boxes.
#[derive(Clone, Copy, Debug)]
struct Wide {
    boxes: Boxes4,
    /// A wide node's index, or `LEAF_FLAG |` a leaf group's index.
    child: [u32; 4],
    len: u32,
}

/// Four f32 boxes, axis-major so that the four are tested in one pass.
#[derive(Clone, Copy, Debug)]
struct Boxes4 {
    lo: [[f32; 4]; 3],
    hi: [[f32; 4]; 3],
}

impl Boxes4 {
    /// Up to four (lo, hi) boxes side by side; unused lanes are empty.
    fn from_boxes<'a>(boxes: impl Iterator<Item = (&'a [f32; 3], &'a [f32; 3])>) -> Self {
        let mut b = Boxes4 {
            lo: [[f32::INFINITY; 4]; 3],
            hi: [[f32::NEG_INFINITY; 4]; 3],
        };
        for (lane, (lo, hi)) in boxes.take(4).enumerate() {
            for k in 0..3 {
                b.lo[k][lane] = lo[k];
                b.hi[k][lane] = hi[k];
            }
        }
        b
    }

    /// Squared f32 distances from `p` to the four boxes (lanes past a
    /// node's `len` are meaningless). Each is within a relative 3e-7 of the
    /// exact value (five roundings), or smaller where a square underflows;
    /// [`f32_bound2`]'s margin covers that.
    #[inline]
    fn distance2(&self, p: [f32; 3]) -> [f32; 4] {
        let mut d2 = [0f32; 4];
        for ((lo, hi), &x) in self.lo.iter().zip(&self.hi).zip(&p) {
            for ((d2, &lo), &hi) in d2.iter_mut().zip(lo).zip(hi) {
                let (below, above) = (lo - x, x - hi);
                let d = if below > above { below } else { above };
                let d = if d > 0.0 { d } else { 0.0 };
                *d2 += d * d;
            }
        }
        d2
    }
}

/// An f32 bound for squared f32 box distances: a box whose f32 distance²
/// exceeds it is farther than `bound` (f64) exactly. Rounded up, with a
/// relative margin (1e-6) above the f32 arithmetic's error.
fn f32_bound2(bound: f64) -> f32 {
    round_f32(bound * bound * (1.0 + 1e-6), true)
}

/// The four-wide hierarchy of a binary one (root first): each wide node
/// takes its binary node's children, splitting the largest inner child
/// (by box surface) until it has four.
fn widen(nodes: &[Node], tris: &[LeafTri]) -> (Vec<Wide>, Vec<LeafGroup>) {
    if nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let mut groups = Vec::new();
    let area = |n: &Node| {
        let e = [0, 1, 2].map(|k| n.hi[k] - n.lo[k]);
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    };
    let mut wide = Vec::new();
    // (binary node, wide slot to fill)
    let mut todo = vec![(0usize, 0usize)];
    wide.push(None);
    while let Some((b, slot)) = todo.pop() {
        let mut kids: Vec<usize> = if nodes[b].count > 0 {
            vec![b]
        } else {
            vec![nodes[b].first as usize, nodes[b].first as usize + 1]
        };
        while kids.len() < 4 {
            let Some(i) = (0..kids.len())
                .filter(|&i| nodes[kids[i]].count == 0)
                .max_by(|&i, &j| area(&nodes[kids[i]]).total_cmp(&area(&nodes[kids[j]])))
            else {
                break;
            };
            let n = nodes[kids[i]];
            kids[i] = n.first as usize;
            kids.push(n.first as usize + 1);
        }
        let mut w = Wide {
            boxes: Boxes4::from_boxes(kids.iter().map(|&c| (&nodes[c].lo, &nodes[c].hi))),
            child: [0; 4],
            len: kids.len() as u32,
        };
        for (j, &c) in kids.iter().enumerate() {
            w.child[j] = if nodes[c].count > 0 {
                let (first, len) = (nodes[c].first, nodes[c].count);
                let leaf = &tris[first as usize..(first + len) as usize];
                let boxes = Boxes4::from_boxes(leaf.iter().map(|t| (&t.lo, &t.hi)));
                groups.push(LeafGroup { boxes, first, len });
                LEAF_FLAG | (groups.len() - 1) as u32
            } else {
                let s = wide.len();
                wide.push(None);
                todo.push((c, s));
                s as u32
            };
        }
        wide[slot] = Some(w);
    }
    let wide = wide
        .into_iter()
        .map(|w| w.expect("every wide node is filled"))
        .collect();
    (wide, groups)
}

/// A leaf of the wide hierarchy: up to four triangles (`LEAF_SIZE`) from
/// `first` in `ClosestPoint::leaf_tris`, with their boxes side by side.
#[derive(Clone, Copy, Debug)]
struct LeafGroup {
    boxes: Boxes4,
    first: u32,
    len: u32,
}

/// Splits `items` (centroid, triangle) into a BVH whose leaves index
/// `items` from `start`; returns its nodes, root first.
fn split(items: &mut [([f32; 3], u32)], start: usize) -> Vec<Node> {
    let leaf = |first: usize, count: usize| Node {
        lo: [0.0; 3],
        hi: [0.0; 3],
        first: first as u32,
        count: count as u32,
    };
    if items.len() <= LEAF_SIZE {
        return vec![leaf(start, items.len())];
    }
    if items.len() < PAR_BUILD {
        // Sequential, in place: children pairs are appended.
        let mut nodes = vec![leaf(0, 0)];
        let mut stack = vec![(0usize, 0usize, items.len())];
        while let Some((node, s, e)) = stack.pop() {
            if e - s <= LEAF_SIZE {
                nodes[node] = leaf(start + s, e - s);
                continue;
            }
            let mid = s + median_split(&mut items[s..e]);
            let left = nodes.len();
            nodes.extend([leaf(0, 0), leaf(0, 0)]);
            nodes[node].first = left as u32;
            stack.push((left + 1, mid, e));
            stack.push((left, s, mid));
        }
        return nodes;
    }
    let mid = median_split(items);
    let (l, r) = items.split_at_mut(mid);
    let (left, right) = rayon::join(|| split(l, start), || split(r, start + mid));
    // Root, the two subtree roots, then the rest of each subtree: a node at
    // index i ≥ 1 of the left subtree moves to i + 2, of the right subtree
    // to i + 1 + left.len(); roots to 1 and 2.
    let (nl, nr) = (left.len(), right.len());
    let mut nodes = Vec::with_capacity(1 + nl + nr);
    let remap = |n: &Node, first_base: usize| Node {
        first: if n.count == 0 {
            (n.first as usize + first_base) as u32
        } else {
            n.first
        },
        ..*n
    };
    let mut root = leaf(0, 0);
    root.first = 1;
    nodes.push(root);
    nodes.push(remap(&left[0], 2));
    nodes.push(remap(&right[0], 1 + nl));
    nodes.extend(left[1..].iter().map(|n| remap(n, 2)));
    nodes.extend(right[1..].iter().map(|n| remap(n, 1 + nl)));
    nodes
}

/// Partitions `items` at their median along the longest axis of their
/// centroids' box; returns the split index.
fn median_split(items: &mut [([f32; 3], u32)]) -> usize {
    let (lo, hi) = items
        .iter()
        .fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), (c, _)| {
            ([0, 1, 2].map(|k| lo[k].min(c[k])), [0, 1, 2].map(|k| hi[k].max(c[k])))
        });
    let size = [0, 1, 2].map(|k| hi[k] - lo[k]);
    let axis = if size[0] >= size[1] && size[0] >= size[2] {
        0
    } else if size[1] >= size[2] {
        1
    } else {
        2
    };
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1)));
    mid
}

/// Distance from `p` to triangle (a, b, c) and the barycentrics of the
/// closest point: the one f64 formula both the BVH and brute force use.
pub fn triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (f64, [f64; 3]) {
    let w = closest_point_barycentric(p, a, b, c);
    ((a * w[0] + b * w[1] + c * w[2] - p).length(), w)
}

/// The SPEC §3 binding of every point by brute force over all triangles:
/// the closest point, ties (closest points within 1e-6 × the bounding-box
/// diagonal of `points` of the smallest distance) to the lowest triangle
/// index. O(points × triangles): the reference the BVH is tested against.
///
/// # Panics
/// On an empty triangle set with points to bind.
pub fn bind_brute_force(points: &[DVec3], triangles: &[[u32; 3]], queries: &[Vec3]) -> Binding {
    let tol = tie_tolerance(points);
    let (vertices, weights) = queries
        .par_iter()
        .map(|q| {
            let p = q.as_dvec3();
            let dist = |&[a, b, c]: &[u32; 3]| {
                triangle_distance(p, points[a as usize], points[b as usize], points[c as usize])
            };
            let best = triangles.iter().map(|t| dist(t).0).fold(f64::INFINITY, f64::min);
            let (t, w) = triangles
                .iter()
                .map(dist)
                .enumerate()
                .find(|(_, (d, _))| *d <= best + tol)
                .map_or((0, [1.0, 0.0, 0.0]), |(t, (_, w))| (t, w));
            (triangles[t], [w[0] as f32, w[1] as f32, w[2] as f32])
        })
        .unzip();
    Binding { vertices, weights }
}

/// SPEC §3 tie tolerance: 1e-6 × the bounding-box diagonal of `points`.
pub fn tie_tolerance(points: &[DVec3]) -> f64 {
    crate::mesh::bounds_f64(points).map_or(0.0, |[lo, hi]| 1e-6 * (hi - lo).length())
}

/// Barycentric coordinates of the point of triangle (a, b, c) closest to `p`.
///
/// Region-based closest point (vertex, edge or face region), so the result is
/// clamped to the triangle. A degenerate triangle falls back to its closest
/// edge or vertex.
pub fn closest_point_barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        if !v.is_finite() {
            // a == b: a zero-length edge.
            return degenerate_barycentric(p, a, b, c);
        }
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        if !w.is_finite() {
            return degenerate_barycentric(p, a, b, c);
        }
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        if !w.is_finite() {
            return degenerate_barycentric(p, a, b, c);
        }
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE || !denom.is_finite() {
        // Degenerate (collinear) triangle: best of its three edges.
        return degenerate_barycentric(p, a, b, c);
    }
    // denom = |ab × ac|² = |ab|²|ac|² sin²θ, each term a difference of
    // products: on a sliver (small sin θ) they cancel, and vb/denom loses
    // about 1e-16/sin²θ (1e-3 at a 1e-7 high sliver). There the weights come
    // from cross products with the normal n, which lose about 1e-16/sin θ:
    // p − a = v ab + w ac + (normal part), so ap × ac = v n, ab × ap = w n.
    if denom < THIN_TRIANGLE * ab.length_squared() * ac.length_squared() {
        let n = ab.cross(ac);
        let nn = n.length_squared();
        if nn > f64::MIN_POSITIVE && nn.is_finite() {
            let v = ap.cross(ac).dot(n) / nn;
            let w = ab.cross(ap).dot(n) / nn;
            return [1.0 - v - w, v, w];
        }
    }
    let v = vb / denom;
    let w = vc / denom;
    [1.0 - v - w, v, w]
}

/// sin²θ of a triangle's angle at `a` below which its face weights come
/// from cross products ([`closest_point_barycentric`]): there Ericson's
/// products would have lost more than about 1e-12.
const THIN_TRIANGLE: f64 = 1e-4;

fn degenerate_barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let seg = |x: DVec3, y: DVec3| {
        let d = y - x;
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - x).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (t, (x + d * t - p).length_squared())
    };
    // Edges in the order ab, ac, bc; ties keep the earlier edge (the
    // numpy reference does the same, so weights on coincident vertices agree).
    let (t0, e0) = seg(a, b);
    let (t1, e1) = seg(a, c);
    let (t2, e2) = seg(b, c);
    if e0 <= e1 && e0 <= e2 {
        [1.0 - t0, t0, 0.0]
    } else if e1 <= e2 {
        [1.0 - t1, 0.0, t1]
    } else {
        [0.0, 1.0 - t2, t2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> (DVec3, DVec3, DVec3) {
        (DVec3::ZERO, DVec3::X, DVec3::Y)
    }

    #[test]
    fn interior_point_projects_to_its_barycentrics() {
        let (a, b, c) = tri();
        let w = closest_point_barycentric(DVec3::new(0.25, 0.5, 3.0), a, b, c);
        assert!((w[0] - 0.25).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn outside_points_clamp_to_edges_and_vertices() {
        let (a, b, c) = tri();
        assert_eq!(
            closest_point_barycentric(DVec3::new(-1.0, -1.0, 0.0), a, b, c),
            [1.0, 0.0, 0.0]
        );
        assert_eq!(
            closest_point_barycentric(DVec3::new(2.0, -0.5, 0.0), a, b, c),
            [0.0, 1.0, 0.0]
        );
        let w = closest_point_barycentric(DVec3::new(0.5, -1.0, 1.0), a, b, c);
        assert_eq!(w, [0.5, 0.5, 0.0]);
        // Beyond the hypotenuse: its midpoint.
        let w = closest_point_barycentric(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((w[1] - 0.5).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12 && w[0].abs() < 1e-12);
    }

    fn assert_weights(got: [f64; 3], want: [f64; 3], what: &str) {
        assert!(
            (0..3).all(|k| (got[k] - want[k]).abs() < 1e-12),
            "{what}: {got:?} vs {want:?}"
        );
    }

    #[test]
    fn every_region_gives_its_barycentrics() {
        // A right triangle with unequal legs, points 1 above its plane; the
        // weights of each region's closest point by hand.
        let (a, b, c) = (DVec3::ZERO, DVec3::new(4.0, 0.0, 0.0), DVec3::new(0.0, 2.0, 0.0));
        for (p, want, what) in [
            ((1.0, 0.5), [0.5, 0.25, 0.25], "face"),
            ((1.0, -1.0), [0.75, 0.25, 0.0], "edge ab at (1, 0)"),
            ((-1.0, 1.5), [0.25, 0.0, 0.75], "edge ac at (0, 1.5)"),
            // (3, 2) - (2.4, 0.8) = (0.6, 1.2) is normal to bc = (-4, 2).
            ((3.0, 2.0), [0.0, 0.6, 0.4], "edge bc at (2.4, 0.8)"),
            ((-1.0, -1.0), [1.0, 0.0, 0.0], "vertex a"),
            ((5.0, -1.0), [0.0, 1.0, 0.0], "vertex b"),
            ((-1.0, 3.0), [0.0, 0.0, 1.0], "vertex c"),
        ] {
            let p = DVec3::new(p.0, p.1, 1.0);
            assert_weights(closest_point_barycentric(p, a, b, c), want, what);
        }
    }

    #[test]
    fn a_sliver_gets_its_face_weights_to_rounding() {
        // a = 0, b = (1, 0, 0), c = (1/2, h, 0) and p = (0.3, h/4, 1/2): in
        // the plane, p = a + v ab + w ac with w h = h/4 and v + w/2 = 0.3, so
        // (u, v, w) = (0.575, 0.175, 0.25) exactly, for every h (the inputs
        // are exact in binary up to h/4). Ericson's products lost about
        // 1e-16/h²: 1.2e-3 at h = 1e-7, against 1e-16/h now. (Near 1e-9 the
        // region tests' own products round: p is put on the edge ab, h/4
        // from where it belongs.)
        for h in [1e-2, 1e-5, 1e-7] {
            let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::new(0.5, h, 0.0));
            let w = closest_point_barycentric(DVec3::new(0.3, h / 4.0, 0.5), a, b, c);
            let want = [0.575, 0.175, 0.25];
            let err = (0..3).map(|k| (w[k] - want[k]).abs()).fold(0.0, f64::max);
            assert!(err <= 1e-15 / h, "h {h}: {w:?}, off by {err:e}");
        }
        // A sliver tilted out of every axis plane, checked against the
        // projection p − (n̂·ap) n̂ rebuilt from the weights.
        let (a, b) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(2.0, 2.5, 3.25));
        let c = (a + b) * 0.5 + DVec3::new(-0.3, 0.6, 0.0).normalize() * 1e-6;
        let p = a * 0.4 + b * 0.35 + c * 0.25 + (b - a).cross(c - a).normalize() * 0.7;
        let w = closest_point_barycentric(p, a, b, c);
        assert!(
            (w[0] - 0.4).abs() < 1e-9 && (w[1] - 0.35).abs() < 1e-9 && (w[2] - 0.25).abs() < 1e-9,
            "{w:?}"
        );
    }

    #[test]
    fn the_degenerate_fallback_takes_the_closest_edge_the_earlier_on_ties() {
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let p = |x: f64, y: f64| DVec3::new(x, y, 1.0);
        for (q, [a, b, c], want, what) in [
            // ab and bc both reach (1.5, 0); ab is earlier.
            (
                (1.5, 1.0),
                [(0.0, 0.0), (2.0, 0.0), (1.0, 0.0)],
                [0.25, 0.75, 0.0],
                "collinear, ab and bc tie",
            ),
            // ab ends at a = (1, 0); ac and bc both reach (1.8, 0).
            (
                (1.8, 1.0),
                [(1.0, 0.0), (0.0, 0.0), (2.0, 0.0)],
                [0.2, 0.0, 0.8],
                "collinear, ac and bc tie",
            ),
            // Any triangle: its closest edge alone (bc at (2.4, 0.8)).
            (
                (3.0, 2.0),
                [(0.0, 0.0), (4.0, 0.0), (0.0, 2.0)],
                [0.0, 0.6, 0.4],
                "bc closest",
            ),
            // One point: its first weight.
            (
                (3.0, 2.0),
                [(1.0, 1.0), (1.0, 1.0), (1.0, 1.0)],
                [1.0, 0.0, 0.0],
                "a = b = c",
            ),
        ] {
            let w = degenerate_barycentric(p(q.0, q.1), v(a.0, a.1), v(b.0, b.1), v(c.0, c.1));
            assert_weights(w, want, what);
        }
        // A zero-length edge a = b, reached from the region test's 0 / 0:
        // ac (= bc) at (0, 1).
        let w = closest_point_barycentric(DVec3::new(1.0, 1.0, 0.0), v(0.0, 0.0), v(0.0, 0.0), v(0.0, 2.0));
        assert_weights(w, [0.5, 0.0, 0.5], "a = b");
    }

    #[test]
    fn degenerate_triangle_gives_finite_weights() {
        let w = closest_point_barycentric(DVec3::new(0.5, 1.0, 0.0), DVec3::ZERO, DVec3::X, DVec3::X * 2.0);
        assert!(w.iter().all(|x| x.is_finite()));
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    /// A quad split along a texture seam, as glTF/FBX converters write it:
    /// two copies of the seam vertices, so triangles on both sides touch
    /// the seam at the same positions.
    fn seam_mesh() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let pts = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            // right half: seam vertices 1 and 2 again (5, 6)
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
        ];
        // Right half first in fan order, so the lowest index is not the
        // first triangle a left-to-right search would meet.
        let tris = vec![[5, 4, 7], [5, 7, 6], [0, 1, 2], [0, 2, 3]];
        (pts, tris)
    }

    #[test]
    fn seam_ties_go_to_the_lowest_triangle_index() {
        let (pts, tris) = seam_mesh();
        let cp = ClosestPoint::new(&pts, &tris);
        // On the seam (x = 1), above it, and within the 1e-6 × diagonal
        // tolerance on the left side: triangle 1 ([5, 7, 6]) holds the seam
        // edge 5–6 and has the lowest index among the tied triangles.
        let diag = (pts[7] - pts[0]).length();
        for q in [
            DVec3::new(1.0, 0.5, 0.0),
            DVec3::new(1.0, 0.5, 0.3),
            DVec3::new(1.0 - 0.4e-6 * diag, 0.5, 0.2),
        ] {
            let (t, w) = cp.query(q);
            assert_eq!(t, 1, "{q}");
            let [a, b, c] = tris[t];
            let at = pts[a as usize] * w[0] + pts[b as usize] * w[1] + pts[c as usize] * w[2];
            assert!((at - DVec3::new(1.0, 0.5, 0.0)).length() < 1.0 * diag * 1e-6, "{at}");
        }
        // Beyond the tolerance the left triangle wins on distance alone.
        let (t, _) = cp.query(DVec3::new(1.0 - 3e-6 * diag, 0.5, 0.0));
        assert_eq!(t, 2);
        // The shared corner (1, 0): every triangle touching it ties.
        assert_eq!(cp.query(DVec3::new(1.0, -0.5, 0.1)).0, 0);
        let b = cp.bind(&[Vec3::new(1.0, 0.5, 0.0), Vec3::new(0.2, 0.7, -1.0)]);
        assert_eq!(b.vertices, vec![[5, 7, 6], [0, 2, 3]]);
        assert_eq!(
            b,
            bind_brute_force(&pts, &tris, &[Vec3::new(1.0, 0.5, 0.0), Vec3::new(0.2, 0.7, -1.0)])
        );
        // A binding has one entry per bound point.
        assert_eq!((b.len(), b.is_empty()), (2, false));
        let none = cp.bind(&[]);
        assert_eq!((none.len(), none.is_empty()), (0, true));
    }

    /// round_f32 gives the nearest f32 on the asked side: the smallest f32
    /// at or above x (up), the largest at or below (down). Derived from the
    /// definition: the answer brackets x and its neighbour on that side
    /// does not.
    #[test]
    fn round_f32_gives_the_nearest_f32_on_each_side() {
        let one_ulp = 2f64.powi(-23);
        for x in [
            1.0,                            // an f32: itself both ways
            1.0 + 2f64.powi(-30),           // just above 1: nearest f32 is 1 (below x)
            1.0 + one_ulp - 2f64.powi(-30), // just below 1 + ulp: nearest f32 is above x
            -1.0 - 2f64.powi(-30),
            0.1,
            -0.1,
            3.0e7 + 0.3,
            1e-40, // subnormal in f32
            0.0,
        ] {
            let (up, down) = (round_f32(x, true), round_f32(x, false));
            assert!(up as f64 >= x && (up.next_down() as f64) < x, "up {x}: {up}");
            assert!(down as f64 <= x && (down.next_up() as f64) > x, "down {x}: {down}");
            if x as f32 as f64 == x {
                assert_eq!((up, down), (x as f32, x as f32), "{x} is an f32");
            } else {
                assert_eq!(up, down.next_up(), "{x}: one f32 apart");
            }
        }
        assert_eq!(round_f32(1.0 + 2f64.powi(-30), true), (1.0 + one_ulp) as f32);
        assert_eq!(round_f32(1.0 + 2f64.powi(-30), false), 1.0);
    }

    /// Far from the origin, p rounded to f32 moves by up to half an f32
    /// spacing (2⁻¹¹ at 10⁴), more than the gap between two candidates; the
    /// pruning bound widens by that shift, so the nearer triangle is still
    /// found after a hint that is farther. Numbers by hand: p.x = 10⁴ +
    /// 0.00045 rounds to 10⁴ (shift 0.00045); B lies in x = 10⁴ + 2⁻⁹ (an
    /// f32, so its box is exact), 0.001503 from p and 2⁻⁹ = 0.001953 from
    /// p32; the hint A lies 0.002 from p on the other side. The bound
    /// without the shift, 0.002 + tol + slack − 0.00045 ≈ 0.00155, would
    /// skip B's box; with it, 0.00245, B is tested and wins.
    #[test]
    fn the_bound_covers_the_query_rounded_to_f32() {
        let x = 10_000.0 + 0.00045;
        assert_eq!(x as f32, 10_000.0f32);
        let xb = 10_000.0 + 2f64.powi(-9);
        let xa = x - 0.002;
        let pts = vec![
            DVec3::new(xa, -1.0, -1.0),
            DVec3::new(xa, 1.0, -1.0),
            DVec3::new(xa, 0.0, 1.0),
            DVec3::new(xb, -1.0, -1.0),
            DVec3::new(xb, 1.0, -1.0),
            DVec3::new(xb, 0.0, 1.0),
        ];
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let cp = ClosestPoint::new(&pts, &tris);
        let p = DVec3::new(x, 0.0, 0.0);
        let (t, _) = cp.query_with(p, Some(0), &mut Scratch::default());
        assert_eq!(t, 1, "the nearer triangle, 0.0015 away against 0.002");
        assert_eq!(cp.query(p).0, 1);
    }

    /// A soup of slanted triangles whose boxes all contain the query: only
    /// their planes (x + y + z = c) tell them apart before the exact test.
    /// Without the plane every one of the 32 would be tested exactly; with
    /// it, a triangle is tested only while its plane is within the best
    /// distance so far.
    #[test]
    fn planes_prune_a_soup_whose_boxes_overlap() {
        let mut pts = Vec::new();
        let mut tris = Vec::new();
        for k in 0..32u32 {
            let c = -0.5 + k as f64 / 31.0;
            pts.extend([
                DVec3::new(c + 2.0, -1.0, -1.0),
                DVec3::new(-1.0, c + 2.0, -1.0),
                DVec3::new(-1.0, -1.0, c + 2.0),
            ]);
            tris.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        // p lies in the plane c = 0.01·√3 = 0.0173, between c₁₆ = 0.0161
        // and c₁₇ = 0.0484. The same soup and point 120 from the origin:
        // the plane test's slack grows with |p| (1e-6 of it), no more.
        for off in [DVec3::ZERO, DVec3::new(100.0, -50.0, 40.0)] {
            let pts: Vec<DVec3> = pts.iter().map(|&x| x + off).collect();
            let cp = ClosestPoint::new(&pts, &tris);
            let n = DVec3::ONE / 3f64.sqrt();
            let p = n * 0.01 + off;
            let mut s = Scratch::default();
            let (t, _) = cp.query_with(p, None, &mut s);
            let want = (0..32)
                .min_by(|&a, &b| cp.distance(p, a).0.total_cmp(&cp.distance(p, b).0))
                .unwrap();
            assert_eq!(t, want as usize);
            // Measured when written: 2 (32 with the plane test removed).
            assert!(s.work.exact <= 8, "{} exact distances of 32 at {off}", s.work.exact);
        }
    }

    /// A tie found second: the plane prefilter keeps every triangle within
    /// best + tolerance, so a lower-index triangle 0.9 tolerances farther
    /// than the hint still wins (SPEC §3). The mesh is centred on the
    /// origin, so the plane's own slack (10⁻⁶ × the largest |x|, √2 here)
    /// is below the tolerance (10⁻⁶ × the diagonal, √8 here) and cannot
    /// hide a bound that forgot the tolerance.
    #[test]
    fn the_tie_tolerance_is_a_millionth_of_the_diagonal() {
        // A 6 × 8 × 0 box: diagonal 10 (SPEC §3).
        let pts = [
            DVec3::new(-1.0, 2.0, 5.0),
            DVec3::new(5.0, 10.0, 5.0),
            DVec3::new(2.0, 3.0, 5.0),
        ];
        assert!((tie_tolerance(&pts) - 1e-5).abs() < 1e-18, "{}", tie_tolerance(&pts));
        assert_eq!(tie_tolerance(&[]), 0.0);
    }

    #[test]
    fn a_tie_at_the_edge_of_the_tolerance_is_kept() {
        // B (index 0) lies at x = T, just inside the tie tolerance of A
        // (index 1, x = 0); the query is on A, so SPEC §3 answers B. T is
        // small enough for f32 boxes to place B's box within an ulp of T:
        // the box test then has no margin but the rounding slack.
        let tri = |x: f64| {
            [
                DVec3::new(x, -1.0, -1.0),
                DVec3::new(x, 2.0, -1.0),
                DVec3::new(x, -1.0, 2.0),
            ]
        };
        let tris = [[0, 1, 2], [3, 4, 5]];
        let mut t = 4.2e-6;
        for _ in 0..3 {
            t = tie_tolerance(&[tri(t), tri(0.0)].concat()) * (1.0 - 1e-9);
        }
        let pts = [tri(t), tri(0.0)].concat();
        assert!(t < tie_tolerance(&pts));
        assert_eq!(bind_brute_force(&pts, &tris, &[Vec3::ZERO]).vertices, [[0, 1, 2]]);
        // From A as the hint (as bind() starts from a neighbour's triangle),
        // B's box is tested against the tightest bound.
        let cp = ClosestPoint::new(&pts, &tris);
        assert_eq!(cp.query_with(DVec3::ZERO, Some(1), &mut Scratch::default()).0, 0);
        assert_eq!(cp.query(DVec3::ZERO).0, 0);
    }

    #[test]
    fn a_tie_found_after_the_hint_still_goes_to_the_lower_index() {
        let quad = |z: f64| {
            [
                DVec3::new(-1.0, -1.0, z),
                DVec3::new(1.0, -1.0, z),
                DVec3::new(-1.0, 1.0, z),
            ]
        };
        let tol = tie_tolerance(&[quad(0.0).as_slice(), quad(-1e-5).as_slice()].concat());
        let eps = 0.9 * tol;
        let pts = [quad(-eps), quad(0.0)].concat();
        assert!((tie_tolerance(&pts) - tol).abs() < 1e-15);
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let cp = ClosestPoint::new(&pts, &tris);
        let p = DVec3::new(-0.5, -0.4, 0.5);
        assert_eq!(cp.query_with(p, Some(1), &mut Scratch::default()).0, 0);
        assert_eq!(cp.query(p).0, 0);
        assert_eq!(bind_brute_force(&pts, &tris, &[p.as_vec3()]).vertices, vec![[0, 1, 2]]);
    }

    use crate::interp::testutil::Lcg;

    /// A point uniform in the unit cube.
    fn unit_vec(rng: &mut Lcg) -> DVec3 {
        DVec3::new(rng.unit(), rng.unit(), rng.unit())
    }

    /// An n × n grid of 0.1-wide quads on a wave, every vertex duplicated per
    /// quad (seams everywhere), f32-rounded like stage data.
    fn seam_grid(n: usize) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut pts = Vec::new();
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = pts.len() as u32;
                for (di, dj) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                    let (x, y) = ((i + di) as f64 * 0.1, (j + dj) as f64 * 0.1);
                    pts.push(DVec3::new(x, y, 0.05 * (7.0 * x).sin()).as_vec3().as_dvec3());
                }
                tris.push([v, v + 1, v + 2]);
                tris.push([v, v + 2, v + 3]);
            }
        }
        (pts, tris)
    }

    #[test]
    fn bvh_equals_brute_force_on_hard_meshes() {
        let mut rng = Lcg::new(7);
        // A grid with every vertex duplicated per quad (seams everywhere),
        // f32-rounded like stage data; a soup of overlapping triangles with
        // degenerate ones; both queried on and off the surface.
        let n = 12;
        let (pts, tris) = seam_grid(n);
        let mut queries: Vec<Vec3> = (0..400)
            .map(|k| {
                if k % 4 == 0 {
                    // exactly on a grid line
                    let i = (rng.unit() * n as f64).floor() * 0.1;
                    DVec3::new(i, rng.unit() * 1.2, rng.unit() * 0.2 - 0.1).as_vec3()
                } else {
                    (unit_vec(&mut rng) * 1.4 - 0.2).as_vec3()
                }
            })
            .collect();
        let cp = ClosestPoint::new(&pts, &tris);
        assert_eq!(cp.bind(&queries), bind_brute_force(&pts, &tris, &queries));

        let mut pts: Vec<DVec3> = (0..300).map(|_| unit_vec(&mut rng)).collect();
        pts.push(pts[3]);
        let mut tris: Vec<[u32; 3]> = (0..500)
            .map(|_| [0, 1, 2].map(|_| (rng.unit() * 300.0) as u32))
            .collect();
        tris.push([5, 5, 5]);
        tris.push([3, 300, 7]);
        queries.extend(pts.iter().map(|p| p.as_vec3()));
        let cp = ClosestPoint::new(&pts, &tris);
        assert_eq!(cp.bind(&queries), bind_brute_force(&pts, &tris, &queries));
    }

    #[test]
    fn parallel_build_equals_brute_force() {
        // Enough triangles for the parallel split (PAR_BUILD), on a wavy
        // sheet with every vertex shared.
        let n = 150;
        let pts: Vec<DVec3> = (0..n * n)
            .map(|k| {
                let (x, y) = ((k % n) as f64 / n as f64, (k / n) as f64 / n as f64);
                DVec3::new(x, y, 0.1 * (9.0 * x).sin() * (4.0 * y).cos())
            })
            .collect();
        let counts = vec![4u32; (n - 1) * (n - 1)];
        let idx: Vec<u32> = (0..(n - 1) * (n - 1))
            .flat_map(|q| {
                let v = (q / (n - 1) * n + q % (n - 1)) as u32;
                [v, v + 1, v + 1 + n as u32, v + n as u32]
            })
            .collect();
        let tris = crate::mesh::fan_triangulate(&counts, &idx);
        assert!(tris.len() > 2 * PAR_BUILD);
        let mut rng = Lcg::new(3);
        let queries: Vec<Vec3> = (0..300).map(|_| (unit_vec(&mut rng) * 1.2 - 0.1).as_vec3()).collect();
        let cp = ClosestPoint::new(&pts, &tris);
        assert_eq!(cp.bind(&queries), bind_brute_force(&pts, &tris, &queries));
        // Every triangle is in exactly one leaf.
        let mut seen: Vec<u32> = cp.leaf_tris.iter().map(|t| t.index).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..tris.len() as u32).collect::<Vec<_>>());
    }

    #[test]
    fn tiny_and_huge_scales_equal_brute_force() {
        // f32 box distances underflow (squares of 1e-22) or grow large; the
        // pruning must stay conservative at both ends.
        let (pts, tris) = seam_grid(12);
        let mut rng = Lcg::new(11);
        for scale in [1e-22, 1e-9, 1e15] {
            let pts: Vec<DVec3> = pts.iter().map(|&p| (p * scale).as_vec3().as_dvec3()).collect();
            let queries: Vec<Vec3> = (0..300)
                .map(|_| ((unit_vec(&mut rng) * 1.6 - 0.3) * scale).as_vec3())
                .chain(pts.iter().map(|p| p.as_vec3()))
                .collect();
            let cp = ClosestPoint::new(&pts, &tris);
            assert_eq!(
                cp.bind(&queries),
                bind_brute_force(&pts, &tris, &queries),
                "scale {scale}"
            );
        }
    }

    #[test]
    fn f64_queries_far_from_the_origin_equal_brute_force() {
        // Queries not representable in f32, on a mesh 1e4 from the origin:
        // the f32 box test sees each query moved by up to about 5e-4, far
        // more than the tie tolerance, and must allow for it. Half lie on
        // seams (ties between two triangles).
        let (pts, tris) = seam_grid(12);
        let off = DVec3::new(1e4, -2e4, 5e3);
        let pts: Vec<DVec3> = pts.iter().map(|&p| p + off).collect();
        let cp = ClosestPoint::new(&pts, &tris);
        let tol = tie_tolerance(&pts);
        let mut rng = Lcg::new(17);
        for k in 0..600 {
            let q = off
                + if k % 2 == 0 {
                    let x = (rng.unit() * 12.0).floor() * 0.1;
                    DVec3::new(x, rng.unit() * 1.2, 0.05 * (7.0 * x).sin() + rng.unit() * 0.02 - 0.01)
                } else {
                    unit_vec(&mut rng) * 1.4 - 0.2
                };
            let d: Vec<(f64, [f64; 3])> = tris
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| pts[v as usize]);
                    triangle_distance(q, a, b, c)
                })
                .collect();
            let best = d.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
            let want = d.iter().position(|x| x.0 <= best + tol).expect("a nearest triangle");
            assert_eq!(cp.query(q), (want, d[want].1), "query {q}");
        }
    }

    #[test]
    fn pruning_keeps_queries_local() {
        // Results stay exact however weak the pruning (the brute-force tests
        // cannot see it); this pins its strength. Points 0.02 off a wavy
        // sheet of 0.1-wide quads (the Dog's stroke points sit about a
        // triangle's size off its proxy), each query starting from its
        // neighbour's triangle as `bind` does. Measured when written: 6.9
        // wide nodes and 2.6 exact distances per query (the bounds allow
        // twice that); without pruning it would be every one of about a
        // thousand nodes and 12,800 triangles.
        let (pts, tris) = seam_grid(80);
        let cp = ClosestPoint::new(&pts, &tris);
        let mut rng = Lcg::new(23);
        let mut s = Scratch::default();
        let mut hint = None;
        let n = 2000;
        for k in 0..n {
            // Along rows, as Morton-ordered neighbours would come.
            let (x, y) = ((k % 200) as f64 * 0.04, (k / 200) as f64 * 0.8 + rng.unit() * 0.02);
            let p = DVec3::new(x, y, 0.05 * (7.0 * x).sin() + 0.02 * (2.0 * rng.unit() - 1.0));
            hint = Some(cp.query_with(p, hint, &mut s).0 as u32);
        }
        let (nodes, exact) = (s.work.nodes as f64 / n as f64, s.work.exact as f64 / n as f64);
        assert!(
            nodes <= 14.0 && exact <= 5.5,
            "{nodes} wide nodes, {exact} exact distances per query"
        );
        // Every query opens the root and, starting from a hint on a sheet
        // of seams, meets another triangle now and then: the counts count.
        assert!(
            nodes >= 1.0 && exact > 0.0,
            "{nodes} wide nodes, {exact} exact distances"
        );
    }

    #[test]
    fn f32_bound_is_never_below_the_f64_bound() {
        let mut rng = Lcg::new(5);
        for _ in 0..10_000 {
            let b = (rng.unit() * 80.0 - 40.0).exp2() * rng.unit();
            assert!(f32_bound2(b) as f64 >= b * b, "{b}");
        }
        assert_eq!(f32_bound2(f64::INFINITY), f32::INFINITY);
        assert_eq!(f32_bound2(1e30), f32::INFINITY);
    }

    #[test]
    fn single_triangle_and_far_points() {
        let pts = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let cp = ClosestPoint::new(&pts, &[[0, 1, 2]]);
        let q = [Vec3::new(1e30, -1e30, 3.0), Vec3::new(0.2, 0.2, 0.0)];
        let b = cp.bind(&q);
        assert_eq!(b, bind_brute_force(&pts, &[[0, 1, 2]], &q));
        assert_eq!(b.weights[1], [0.6, 0.2, 0.2]);
    }

    #[test]
    fn far_points_off_tilted_sheets_equal_brute_force() {
        // A flat sheet of 800 triangles, 2 units wide, turned 40 ways, and
        // points 1e2 to 1e7 units off it along its normal. Far off, many
        // triangles tie within the tolerance (their distances differ by
        // x²/2r for an offset x along the sheet); every plane's f32
        // rounding then moves n·p − d by up to 1e-7·|p|, which the pruning
        // must allow for, or it drops the lower-indexed ties.
        let n = 20u32;
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = j * (n + 1) + i;
                tris.push([v, v + 1, v + n + 2]);
                tris.push([v, v + n + 2, v + n + 1]);
            }
        }
        let mut wrong = Vec::new();
        for turn in 0..40 {
            let axis = DVec3::new(0.3 + turn as f64 * 0.11, 0.8 - turn as f64 * 0.07, 0.52).normalize();
            let rot = glam::DQuat::from_axis_angle(axis, 0.7 + turn as f64 * 0.13);
            let pts: Vec<DVec3> = (0..=n)
                .flat_map(|j| (0..=n).map(move |i| DVec3::new(i as f64 * 0.1, j as f64 * 0.1, 0.0)))
                .map(|p| rot * p)
                .collect();
            let cp = ClosestPoint::new(&pts, &tris);
            let tol = tie_tolerance(&pts);
            for r in [1e2, 1e3, 1e5, 1e7] {
                for k in 0..12 {
                    let foot = rot * DVec3::new(0.05 + 0.15 * k as f64, 0.05 + 0.12 * k as f64, 0.0);
                    let side = if k % 2 == 0 { 1.0 } else { -1.0 };
                    let q = foot + rot * DVec3::Z * r * side;
                    let d: Vec<f64> = tris
                        .iter()
                        .map(|t| {
                            let [a, b, c] = t.map(|v| pts[v as usize]);
                            triangle_distance(q, a, b, c).0
                        })
                        .collect();
                    let best = d.iter().copied().fold(f64::INFINITY, f64::min);
                    let want = d.iter().position(|&x| x <= best + tol).expect("a nearest triangle");
                    let got = cp.query(q).0;
                    if got != want {
                        wrong.push((turn, r, k, got, want));
                    }
                }
            }
        }
        assert!(
            wrong.is_empty(),
            "{} of 1920 differ, e.g. {:?}",
            wrong.len(),
            &wrong[..wrong.len().min(5)]
        );
    }

    #[test]
    fn slivers_get_no_plane() {
        // A triangle with a longest edge of 2 away from the origin, at
        // heights 1.5e-9 and 1.5e-8 (below 1e-8 of the longest edge: no
        // plane), 3e-8 and 1e-7 (a plane), its corners in each of three
        // orders so that the longest edge is each of ab, ac and bc in turn.
        let p = DVec3::new(-3.0, 2.0, 7.0);
        for (h, has_plane) in [(1.5e-9, false), (1.5e-8, false), (3e-8, true), (1e-7, true)] {
            let pts = [p, p + DVec3::new(2.0, 0.0, 0.0), p + DVec3::new(1.0, h, 0.0)];
            let cp = ClosestPoint::new(&pts, &[[0, 1, 2], [1, 2, 0], [2, 0, 1]]);
            for t in 0..3 {
                let plane = cp.leaf_tri(t).plane;
                assert_eq!(plane != [0.0; 4], has_plane, "height {h}, order {t}: {plane:?}");
            }
        }
    }

    #[test]
    fn bvh_query_matches_brute_force() {
        // Two triangles of a folded quad; compare with brute force over both.
        let pts = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.5),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let tris = [[0, 1, 2], [0, 2, 3]];
        let cp = ClosestPoint::new(&pts, &tris);
        for q in [
            DVec3::new(0.9, 0.2, 1.0),
            DVec3::new(0.1, 0.8, -1.0),
            DVec3::new(0.5, 0.5, 2.0),
        ] {
            let (t, w) = cp.query(q);
            let at = |t: usize, w: [f64; 3]| {
                let [a, b, c] = tris[t];
                pts[a as usize] * w[0] + pts[b as usize] * w[1] + pts[c as usize] * w[2]
            };
            let got = (at(t, w) - q).length();
            let best = (0..2)
                .map(|i| {
                    let [a, b, c] = tris[i];
                    let w = closest_point_barycentric(q, pts[a as usize], pts[b as usize], pts[c as usize]);
                    (at(i, w) - q).length()
                })
                .fold(f64::INFINITY, f64::min);
            assert!((got - best).abs() < 1e-9, "{got} vs {best}");
        }
    }
}
