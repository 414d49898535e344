"""painterly from Python: bake, evaluate, inspect and validate painted characters.

Thin over the Rust library; long work releases the GIL, so Python threads
run bakes at once. Inputs are a file path or a usd-core ``Sdf.Layer``: a
saved layer is read from its file (what a farm would read); an unsaved or
anonymous one through ``ExportToString()``, as if it were its own file, so
relative asset paths still resolve. A bake without ``output`` returns its
layer's usda text under ``"layer"``; :func:`to_layer` opens such text in
usd-core.

The usd-core validators (one per rule ``painterly inspect`` checks) live in
:mod:`painterly.validators`; ``painterly-validate FILE`` runs them.
"""

from __future__ import annotations

import os

import numpy as np

from ._painterly import Character, Error, __version__, _interpolate, _rules, bake, inspect

__all__ = [
    "Character",
    "Error",
    "RULES",
    "__version__",
    "bake",
    "inspect",
    "interpolate",
    "plugin_path",
    "to_layer",
]

#: The rules ``painterly inspect`` checks: ``{"id", "validator", "doc"}`` each.
#: A problem in ``inspect(path)["problems"]`` names its rule by ``id``; the
#: UsdValidation validator ``painterly.validators:<validator>`` reports it.
RULES = [{"id": i, "validator": v, "doc": d} for i, v, d in _rules()]


def _error(message: str) -> Error:
    """An :class:`Error` raised here, with the attributes the native ones
    carry (nothing is known of where: None)."""
    e = Error(message)
    e.message = message
    e.file = e.prim = e.attribute = e.rule = None
    return e


def _array(name: str, value) -> np.ndarray:
    # Converting these to float64 would drop something silently: an
    # imaginary part (numpy only warns) or a mask (its hidden values used).
    if isinstance(value, np.ma.MaskedArray):
        raise _error(f"{name} is a masked array: pass the values to use (e.g. {name}.filled(...) or "
                     f"{name}.compressed())")
    try:
        kind = np.asarray(value).dtype.kind
    except (TypeError, ValueError):
        kind = None  # ragged: the conversion below names it
    if kind == "c":
        raise _error(f"{name} must be real numbers, not complex")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as why:
        raise _error(f"{name} must be numbers in a rectangular array: {why}") from None


def interpolate(keys, values, queries, method: str = "smooth_voronoi", radius: float = 1.0) -> np.ndarray:
    """Configuration-space interpolation (Bassett et al. 2013, §4.2).

    ``keys``: (n, d) key coordinates, or (n,) in one dimension. ``values``:
    (n, ...) one value (scalar or array) per key. ``queries``: (m, d), or
    (m,) in one dimension. Returns float64 (m, ...): at each query the
    values blended with the basis weights of ``method`` ("smooth_voronoi",
    "rbf" with ``radius``, or "shepard"), the weights the ``painterly
    interpolate`` command prints.
    """
    keys = _array("keys", keys)
    queries = _array("queries", queries)
    values = _array("values", values)
    if keys.ndim == 1:
        keys = keys[:, None]
    if queries.ndim == 1:
        queries = queries[:, None] if keys.shape[1] == 1 else queries[None, :]
    if keys.ndim != 2 or queries.ndim != 2:
        raise _error("keys and queries must be (n, d) and (m, d) arrays")
    if keys.shape[0] == 0:
        raise _error("no keys: interpolation needs at least one key")
    if values.ndim == 0 or values.shape[0] != keys.shape[0]:
        raise _error(f"{keys.shape[0]} keys but values of shape {values.shape}: one value per key")
    try:
        radius = float(radius)
    except (TypeError, ValueError):
        raise _error(f"radius must be a number, not {radius!r}") from None
    rest = values.shape[1:]
    flat = np.ascontiguousarray(values.reshape(values.shape[0], -1))
    out = _interpolate(np.ascontiguousarray(keys), flat, np.ascontiguousarray(queries), method, radius)
    return out.reshape((queries.shape[0],) + rest)


def to_layer(text: str):
    """An anonymous usd-core ``Sdf.Layer`` holding ``text`` (usda), e.g. the
    ``"layer"`` of an in-memory :func:`bake`."""
    from pxr import Sdf, Tf

    if not isinstance(text, str):
        raise _error(f"to_layer takes usda text (a str), not {type(text).__name__}")
    layer = Sdf.Layer.CreateAnonymous(".usda")
    try:
        ok = layer.ImportFromString(text)
    except Tf.ErrorException as why:
        raise _error(f"usd-core could not read the layer text: {str(why).strip()}") from None
    if not ok:
        raise _error("usd-core could not read the layer text")
    return layer


def plugin_path() -> str:
    """The directory holding the validators' ``plugInfo.json``: put it on
    ``PXR_PLUGINPATH_NAME`` before usd-core starts (see the README)."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "validators")
