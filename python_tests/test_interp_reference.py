"""`painterly interpolate` (JSON on stdin) against the independent numpy
reference in reference_interp.py: smooth Voronoi (Bassett et al. 2013
eqs. 7-12 with the SPEC's erratum), normalized Gaussian RBF and Shepard.

Set PAINTERLY_BIN to test another build of the CLI.
"""

from __future__ import annotations

import inspect
import re
import json
import subprocess

import numpy as np
import pytest

import reference_interp as R
from conftest import painterly_binary, run_painterly

REL_TOL = 1e-9


def interpolate(payload, check=True):
    """Run `painterly interpolate` with `payload` as JSON on stdin."""
    text = json.dumps(payload)
    if "input" in inspect.signature(run_painterly).parameters:
        return run_painterly("interpolate", input=text, check=check)
    exe = painterly_binary()
    if not exe.exists():
        pytest.fail(f"painterly binary not built: {exe} (run `cargo build --release --ignore-rust-version`)")
    proc = subprocess.run(
        [str(exe), "interpolate"], input=text, capture_output=True, text=True, timeout=600
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"painterly interpolate exited {proc.returncode}\nstderr:\n{proc.stderr}")
    return proc


def cli_weights(method, keys, points, radius=None):
    payload = {"method": method, "keys": np.asarray(keys).tolist(), "points": np.asarray(points).tolist()}
    if radius is not None:
        payload["radius"] = radius
    out = json.loads(interpolate(payload).stdout)
    return np.array(out["weights"], dtype=float).reshape(len(points), len(keys))


def assert_close(got, expected):
    err = np.abs(got - expected) / np.maximum(1.0, np.abs(expected))
    assert err.max() <= REL_TOL, f"max relative error {err.max():.3e}\ngot\n{got}\nexpected\n{expected}"


def separated_keys(rng, n, d):
    """n keys in [0, 1]^d, pairwise at least 0.3 n^(-1/d) apart."""
    min_dist = 0.3 * n ** (-1.0 / d)
    keys = []
    while len(keys) < n:
        p = rng.random(d)
        if all(np.linalg.norm(p - k) >= min_dist for k in keys):
            keys.append(p)
    return np.array(keys)


def query_points(rng, keys, count=12):
    """Keys themselves, midpoints of key pairs, and random points around."""
    n, d = keys.shape
    pts = [k for k in keys]
    for _ in range(count // 2):
        i, j = rng.choice(n, size=2, replace=n < 2)
        pts.append(0.5 * (keys[i] + keys[j]))
    pts.extend(rng.uniform(-0.3, 1.3, size=(count, d)))
    return np.array(pts)


# ---------------------------------------------------------------------------
# erratum (SPEC section 4): S must be continuous and C1 at gamma


@pytest.mark.parametrize("gamma", [0.05, 0.2, 0.35, 0.5])
def test_smooth_step_erratum_is_continuous_and_c1(gamma):
    h = 1e-9
    for joint in (0.0, gamma, 1.0 - gamma, 1.0):
        assert abs(R.smooth_step(joint - h, gamma) - R.smooth_step(joint + h, gamma)) < 1e-8
        slopes = [
            (R.smooth_step(s + 1e-7, gamma) - R.smooth_step(s - 1e-7, gamma)) / 2e-7
            for s in (joint - 1e-5, joint + 1e-5)
        ]
        assert abs(slopes[0] - slopes[1]) < 1e-3
    assert abs(R.smooth_step(0.5, gamma) - 0.5) < 1e-15
    t = np.linspace(-0.5, 1.5, 101)
    assert np.allclose(R.smooth_step(t, gamma) + R.smooth_step(1.0 - t, gamma), 1.0, atol=1e-14)


def test_smooth_step_as_printed_is_discontinuous():
    # The printed 2*gamma - gamma**2 gives 0.111 at t = gamma where the linear
    # piece gives 0.125, and S(0.5) != 0.5 for gamma = 0.5.
    assert abs(R.smooth_step_as_printed(0.2, 0.2) - 0.04 / 0.36) < 1e-15
    assert abs(R.smooth_step_as_printed(0.2 + 1e-12, 0.2) - 0.125) < 1e-9
    assert abs(R.smooth_step_as_printed(0.5, 0.5) - 0.5) > 0.1
    assert abs(R.smooth_step(0.2, 0.2) - 0.125) < 1e-15


def test_cli_uses_the_corrected_step():
    # Two keys: the interpolant is S along the line, so the CLI's weights
    # expose S itself; compare with the corrected and the printed step.
    t = np.array([0.05, 0.15, 0.2, 0.2 + 1e-9, 0.5, 0.81, 0.95])
    w = cli_weights("smoothVoronoi", [[0.0], [1.0]], t[:, None])
    assert_close(w[:, 1], R.smooth_step(t))
    assert np.abs(w[:, 1] - R.smooth_step_as_printed(t)).max() > 1e-3
    # Continuity at t = gamma, seen through the CLI.
    assert abs(w[2, 1] - w[3, 1]) < 1e-8


# ---------------------------------------------------------------------------
# random layouts against the reference

SIZES = [(1, 1), (1, 2), (1, 5), (2, 2), (2, 4), (2, 7), (3, 6), (5, 3), (5, 8), (8, 10)]
LAYOUTS = [(d, n, seed) for d, n in SIZES for seed in (1, 2)]


@pytest.mark.parametrize("d,n,seed", LAYOUTS)
def test_smooth_voronoi_matches_reference(d, n, seed):
    rng = np.random.default_rng(1000 * d + 10 * n + seed)
    keys = separated_keys(rng, n, d)
    points = query_points(rng, keys)
    got = cli_weights("smoothVoronoi", keys, points)
    expected = R.smooth_voronoi_weights(keys, points)
    assert_close(got, expected)
    assert np.allclose(got.sum(axis=1), 1.0, atol=1e-12)
    assert np.allclose(got[:n], np.eye(n), atol=1e-12)  # R1: exact at keys


@pytest.mark.parametrize("d,n,seed", [(1, 4, 1), (2, 5, 2), (3, 6, 3), (5, 8, 4)])
@pytest.mark.parametrize("radius", [0.3, 1.0])
def test_rbf_matches_reference(d, n, seed, radius):
    rng = np.random.default_rng(7 * d + n + seed)
    keys = separated_keys(rng, n, d)
    points = query_points(rng, keys)
    got = cli_weights("rbf", keys, points, radius=radius)
    assert_close(got, R.rbf_weights(keys, points, radius))
    assert np.allclose(got.sum(axis=1), 1.0, atol=1e-9)


def test_rbf_radius_defaults_to_one():
    keys = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    points = np.array([[0.3, 0.4], [2.0, -1.0]])
    assert_close(cli_weights("rbf", keys, points), R.rbf_weights(keys, points, 1.0))


@pytest.mark.parametrize("d,n,seed", [(1, 1, 1), (1, 4, 1), (2, 5, 2), (3, 6, 3), (5, 8, 4)])
def test_shepard_matches_reference(d, n, seed):
    rng = np.random.default_rng(11 * d + n + seed)
    keys = separated_keys(rng, n, d)
    points = query_points(rng, keys)
    got = cli_weights("shepard", keys, points)
    assert_close(got, R.shepard_weights(keys, points))
    assert np.array_equal(got[:n], np.eye(n))


def test_fig9_layout():
    """Bassett Fig. 9: keys (0.2,0.2), (0.8,0.8), (0.2,0.8), (0.8,0.2), (0.3,0.4)."""
    keys = np.array([[0.2, 0.2], [0.8, 0.8], [0.2, 0.8], [0.8, 0.2], [0.3, 0.4]])
    g = np.linspace(0.0, 1.0, 11)
    grid = np.array([[x, y] for x in g for y in g])
    points = np.vstack([keys, grid])
    got = cli_weights("smoothVoronoi", keys, points)
    assert_close(got, R.smooth_voronoi_weights(keys, points))
    assert np.array_equal(got[:5], np.eye(5))
    assert np.allclose(got.sum(axis=1), 1.0, atol=1e-12)


def test_high_dimensional_layout():
    """d = 30 with 12 keys on a 3-D affine subspace: R3 in the CLI output."""
    rng = np.random.default_rng(30)
    basis, _ = np.linalg.qr(rng.normal(size=(30, 4)))
    origin = rng.normal(size=30)
    z = separated_keys(rng, 12, 3)
    keys = origin + z @ basis[:, :3].T
    x = origin + rng.uniform(-0.2, 1.2, size=(6, 3)) @ basis[:, :3].T
    moved = x + 0.8 * basis[:, 3]  # orthogonal to the keys' affine span
    got = cli_weights("smoothVoronoi", keys, np.vstack([x, moved]))
    assert_close(got[:6], R.smooth_voronoi_weights(keys, x))
    assert np.abs(got[:6] - got[6:]).max() < 1e-9


# ---------------------------------------------------------------------------
# errors


@pytest.mark.parametrize(
    "payload,needle",
    [
        (
            {"method": "smoothVoronoi", "keys": [[0.0, 1.0], [0.5, 0.5], [0.0, 1.0]], "points": []},
            "keys 0 and 2",
        ),
        ({"method": "linear", "keys": [[0.0]], "points": []}, "linear"),
        ({"method": "shepard", "keys": [[0.0], [1.0]], "points": [[0.0, 1.0]]}, "point 0"),
        ({"method": "rbf", "radius": 0.0, "keys": [[0.0], [1.0]], "points": []}, "radius"),
        ({"method": "shepard", "keys": [], "points": []}, "no keys"),
        # Found by an interpolation review (2026-12-06), each exit 0 before:
        # a radius 100 times the spacing gave weights summing to 0.48 at a key,
        ({"method": "rbf", "radius": 100.0, "keys": [[0.0], [0.25], [0.5], [0.75], [1.0]], "points": [[0.25]]},
         "RBF weights cannot be solved accurately: the kernel radius is too wide"),
        # a point 1e160 away printed null weights (the schema wants numbers),
        ({"method": "smoothVoronoi", "keys": [[0.0], [1.0], [3.0]], "points": [[1e160]]},
         "point 0 is too far from the keys to weigh"),
        # keys without coordinates were "no keys",
        ({"method": "shepard", "keys": [[], []], "points": []}, "the keys have no coordinates"),
        # and 1,000 keys would take minutes to set up, without a word.
        ({"method": "shepard", "keys": [[float(i)] for i in range(301)], "points": []},
         "301 keys; painterly interpolates at most 300"),
    ],
)
def test_errors_name_the_problem(payload, needle):
    proc = interpolate(payload, check=False)
    assert proc.returncode == 1
    assert needle in proc.stderr


def test_a_request_longer_than_the_limit_is_refused_without_reading_on():
    """`cat /dev/zero | painterly interpolate` took memory until the machine
    ran out: stdin is read up to 64 MiB (README, Limits) and the request
    refused past it, exit 1, before any parsing."""
    exe = painterly_binary()
    limit = 64 << 20
    with subprocess.Popen([str(exe), "interpolate"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE) as proc:
        chunk = b" " * (1 << 20)
        sent = 0
        try:
            # Far more than the limit: a reader without a bound would take it all.
            while sent < 4 * limit:
                proc.stdin.write(chunk)
                sent += len(chunk)
        except BrokenPipeError:
            pass
        try:
            proc.stdin.close()
        except BrokenPipeError:
            pass
        err = proc.stderr.read().decode()
        assert proc.stdout.read() == b""
        assert proc.wait(timeout=60) == 1
    assert err == ("error: the request on stdin is longer than 64 MiB; painterly interpolate reads at most "
                   "that (send the points in several requests)\n")
    # Exactly at the limit: whitespace around a request is still JSON.
    body = json.dumps({"method": "shepard", "keys": [[0], [1]], "points": [[0.25]]}).encode()
    proc = subprocess.run([str(exe), "interpolate"], input=body + b" " * (limit - len(body)),
                          capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    # Shepard with power 2 at 0.25: 1/0.0625 and 1/0.5625 normalised.
    assert np.allclose(json.loads(proc.stdout)["weights"], [[0.9, 0.1]], rtol=1e-15, atol=0)


def test_verbose_says_what_was_read():
    exe = painterly_binary()
    proc = subprocess.run([str(exe), "interpolate", "-v"], capture_output=True, text=True, timeout=60,
                          input='{"method": "rbf", "keys": [[0, 0], [1, 0], [0, 1]], "points": [[1, 1]]}')
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert lines[0] == "painterly: interpolate: 3 keys of 2 coordinates, 1 points, method rbf"
    assert re.fullmatch(r"painterly: interpolate: weights in \d+\.\d{3} s", lines[1]), lines
    assert len(lines) == 2
