"""An independent numpy implementation of configuration-space interpolation
(Bassett et al. 2013 section 4; SPEC sections 3-4), used as the expected
value in painterly's contract tests.

Written straight from the paper's equations, with no shortcuts:
- smooth step S (eq. 7) with the SPEC's erratum: the quadratic pieces divide
  by 2*gamma*(1 - gamma), not 2*gamma - gamma**2;
- kernels phi'_i (eq. 8): product over j != i of S of the projection
  parameter of x onto the line from x_j to x_i, normalised to sum to 1;
- a_ij = phi_i(alpha x_i + (1 - alpha) x_j) (eq. 11),
  b_ij = S(-beta min_{k != i} cos(x_k - x_i, x_j - x_i)) (eq. 12);
- gradients g_i minimising eq. 10 plus eps*|g|^2, solved as one stacked
  least-squares system per key with numpy.linalg.lstsq;
- weights w(x) = sum_i phi_i(x) (e_i + G_i^T (x - x_i)) (eq. 9 folded).
alpha = 0.5, beta = 5, gamma = 0.2, eps = 0.2.

Also the comparison methods: normalized Gaussian RBF (eq. 3, kernel
exp(-|x - x_i|^2 / radius^2), coefficients solving the interpolation
system) and Shepard with 1/d^2 weights (eq. 5).

Everything is float64. Keys are an (n, d) array, points an (m, d) array;
every function returns an (m, n) array of basis weights.
"""

from __future__ import annotations

import numpy as np

ALPHA = 0.5
BETA = 5.0
GAMMA = 0.2
EPSILON = 0.2


def smooth_step(t, gamma=GAMMA):
    """Corrected eq. 7 (SPEC erratum), elementwise."""
    t = np.asarray(t, dtype=float)
    denom = 2.0 * gamma * (1.0 - gamma)
    out = 0.5 + (t - 0.5) / (1.0 - gamma)
    if gamma > 0:
        out = np.where(t <= gamma, t * t / denom, out)
        out = np.where((t > 1.0 - gamma) & (t < 1.0), 1.0 - (1.0 - t) ** 2 / denom, out)
    out = np.where(t <= 0.0, 0.0, out)
    out = np.where(t >= 1.0, 1.0, out)
    return out


def smooth_step_as_printed(t, gamma=GAMMA):
    """Eq. 7 exactly as printed (dividing by 2*gamma - gamma**2); only for
    demonstrating the erratum."""
    t = np.asarray(t, dtype=float)
    denom = 2.0 * gamma - gamma * gamma
    out = 0.5 + (t - 0.5) / (1.0 - gamma)
    out = np.where((t > 0) & (t <= gamma), t * t / denom, out)
    out = np.where((t > 1.0 - gamma) & (t < 1.0), 1.0 - (1.0 - t) ** 2 / denom, out)
    out = np.where(t <= 0.0, 0.0, out)
    out = np.where(t >= 1.0, 1.0, out)
    return out


def kernels(keys, x):
    """Normalised kernels phi_i(x) (eq. 8 and its normalisation)."""
    keys = np.asarray(keys, dtype=float)
    x = np.asarray(x, dtype=float)
    n = len(keys)
    phi = np.ones(n)
    for i in range(n):
        for j in range(n):
            if j == i:
                continue
            direction = keys[i] - keys[j]
            t = np.dot(x - keys[j], direction) / np.dot(direction, direction)
            phi[i] *= smooth_step(t)
    return phi / phi.sum()


def _b(keys, i, j):
    """eq. 12."""
    dj = keys[j] - keys[i]
    cosines = []
    for k in range(len(keys)):
        if k == i:
            continue
        dk = keys[k] - keys[i]
        cosines.append(np.dot(dk, dj) / (np.linalg.norm(dk) * np.linalg.norm(dj)))
    return float(smooth_step(-BETA * min(cosines)))


def gradient_operators(keys):
    """Per key i, the (d, n) matrix G_i with g_i = G_i @ y (eqs. 10-12)."""
    keys = np.asarray(keys, dtype=float)
    n, d = keys.shape
    grads = []
    for i in range(n):
        others = [j for j in range(n) if j != i]
        lhs = np.zeros((len(others) + d, d))
        rhs = np.zeros((len(others) + d, n))
        for row, j in enumerate(others):
            diff = keys[j] - keys[i]
            length = np.linalg.norm(diff)
            a = kernels(keys, ALPHA * keys[i] + (1.0 - ALPHA) * keys[j])[i]
            b = _b(keys, i, j)
            # a_ij (g . u_j - b_ij (y_j - y_i) / |x_j - x_i|), one row per j
            lhs[row] = a * diff / length
            rhs[row, j] += a * b / length
            rhs[row, i] -= a * b / length
        # Tikhonov term eps |g|^2 as sqrt(eps) I rows with zero targets
        lhs[len(others) :] = np.sqrt(EPSILON) * np.eye(d)
        g, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
        grads.append(g)
    return grads


def smooth_voronoi_weights(keys, points):
    """Basis weights of smooth Voronoi interpolation, shape (m, n)."""
    keys = np.asarray(keys, dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    n = len(keys)
    if n == 1:
        return np.ones((len(points), 1))
    grads = gradient_operators(keys)
    out = np.zeros((len(points), n))
    for p, x in enumerate(points):
        phi = kernels(keys, x)
        for i in range(n):
            w = np.zeros(n)
            w[i] = 1.0
            w += (x - keys[i]) @ grads[i]
            out[p] += phi[i] * w
    return out


def _sq_dists(points, keys):
    return ((points[:, None, :] - keys[None, :, :]) ** 2).sum(axis=2)


def _normalized_gaussians(sq, radius):
    """Rows of normalised Gaussians, shifted by the row minimum for range."""
    e = np.exp(-(sq - sq.min(axis=1, keepdims=True)) / radius**2)
    return e / e.sum(axis=1, keepdims=True)


def rbf_weights(keys, points, radius=1.0):
    """Normalized Gaussian RBF weights (eq. 3), shape (m, n).

    y(x) = sum_i c_i psi_i(x) with N c = y, N[j, i] = psi_i(x_j), so the
    weights are w(x) = psi(x) @ inv(N).
    """
    keys = np.asarray(keys, dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    if len(keys) == 1:
        return np.ones((len(points), 1))
    big_n = _normalized_gaussians(_sq_dists(keys, keys), radius)
    psi = _normalized_gaussians(_sq_dists(points, keys), radius)
    return np.linalg.solve(big_n.T, psi.T).T


def shepard_weights(keys, points):
    """Shepard weights with 1/d^2 kernels (eq. 5), exact at keys."""
    keys = np.asarray(keys, dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    sq = _sq_dists(points, keys)
    out = np.zeros_like(sq)
    for p, row in enumerate(sq):
        hit = np.flatnonzero(row == 0.0)
        if len(hit):
            out[p, hit[0]] = 1.0
        else:
            inv = 1.0 / row
            out[p] = inv / inv.sum()
    return out


def weights(method, keys, points, radius=1.0):
    """Dispatch on the USD token of painterly:interpolation."""
    if method == "smoothVoronoi":
        return smooth_voronoi_weights(keys, points)
    if method == "rbf":
        return rbf_weights(keys, points, radius)
    if method == "shepard":
        return shepard_weights(keys, points)
    raise ValueError(f"unknown method {method!r}")
