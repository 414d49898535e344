#!/usr/bin/env python3
"""Which region of src/bind.rs's closest_point_barycentric near-degenerate
triangles reach, in the same f64 operations (Python floats are IEEE f64 and
glam's DVec3::dot sums x, y, z left to right without FMA).

Written for the mutation triage of 2026-12-03 (docs/mutants_reasons.txt):
it looks for inputs where an edge branch's quotient is not finite (sending
the code to degenerate_barycentric) and for exactly collinear triangles
that reach the face branch with a zero denominator.

    python3 scripts/degenerate_regions.py [--seed 1] [--tiny 2000000] [--collinear 200000]
"""

import argparse
import math
import random


def dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def sub(u, v):
    return (u[0] - v[0], u[1] - v[1], u[2] - v[2])


def edge(name, num, den):
    """An edge branch: its name, with '-nan' when num / den is not finite."""
    return (name if den != 0 and math.isfinite(num / den) else name + "-nan"), None


def region(p, a, b, c):
    """The branch closest_point_barycentric takes; '-nan' when its quotient
    is not finite; for the face branch also its denominator."""
    ab, ac, ap = sub(b, a), sub(c, a), sub(p, a)
    d1, d2 = dot(ab, ap), dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return "vertex a", None
    bp = sub(p, b)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return "vertex b", None
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return edge("edge ab", d1, d1 - d3)
    cp = sub(p, c)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return "vertex c", None
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return edge("edge ac", d2, d2 - d6)
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        return edge("edge bc", d4 - d3, (d4 - d3) + (d5 - d6))
    return "face", va + vb + vc


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tiny", type=int, default=2_000_000, help="triangles with a tiny edge ac")
    ap.add_argument("--collinear", type=int, default=200_000, help="exactly collinear triangles")
    args = ap.parse_args()
    rng = random.Random(args.seed)

    counts = {}
    for _ in range(args.tiny):
        # a, b a unit edge; c within 1e-30 .. 1e-14 of a.
        e = 10 ** rng.uniform(-30, -14)
        c = (rng.choice((-1, 1)) * e * rng.random(), e * rng.random(), 0.0)
        p = (rng.uniform(-0.5, 1.5), rng.uniform(-1, 1) * 10 ** rng.uniform(-20, 0), rng.uniform(-1, 1))
        r, _ = region(p, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), c)
        counts[r] = counts.get(r, 0) + 1
    print(f"tiny edge ac, {args.tiny} triangles:", dict(sorted(counts.items())))

    counts, smallest = {}, math.inf
    for _ in range(args.collinear):
        d = tuple(rng.uniform(-1, 1) for _ in range(3))
        a, b, c = [(t * d[0], t * d[1], t * d[2]) for t in (rng.uniform(-2, 2) for _ in range(3))]
        p = tuple(rng.uniform(-2, 2) for _ in range(3))
        r, den = region(p, a, b, c)
        counts[r] = counts.get(r, 0) + 1
        if den is not None:
            smallest = min(smallest, abs(den))
    print(f"collinear, {args.collinear} triangles:", dict(sorted(counts.items())))
    print(f"  smallest |denominator| in the face branch: {smallest:.3g}")


if __name__ == "__main__":
    main()
