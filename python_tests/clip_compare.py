"""Comparing a clip-set bake with a single-file bake in usd-core.

Shared by test_clips.py (local chunked bakes) and test_farm.py (farm bakes):
each layer is sublayered over the input, as a TD opens a bake, and the
composed values of every attribute the single-file bake authors are
compared at the given times.
"""

import numpy as np
from pxr import Sdf, Usd


def over_input(bake_layer, src):
    """A stage showing `bake_layer` sublayered over `src`, as a TD opens it."""
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths.append(str(bake_layer))
    root.subLayerPaths.append(str(src))
    return Usd.Stage.Open(root)


def baked_attributes(layer_path):
    """Attribute paths a single-file bake authors samples on."""
    layer = Sdf.Layer.FindOrOpen(str(layer_path))
    out = []

    def visit(path):
        if path.IsPropertyPath() and layer.ListTimeSamplesForPath(path):
            out.append(path)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return sorted(out, key=str)


def compare(single, clips, src, times, exact):
    """Every baked attribute agrees at every time: bit for bit with `exact`,
    else within 1e-6 of the value's magnitude (interpolated times)."""
    a, b = over_input(single, src), over_input(clips, src)
    attrs = baked_attributes(single)
    assert attrs
    for path in attrs:
        pa = a.GetAttributeAtPath(path)
        pb = b.GetAttributeAtPath(path)
        for t in times:
            va, vb = np.array(pa.Get(t)), np.array(pb.Get(t))
            assert va.shape == vb.shape and va.size > 0, (path, t)
            if exact:
                assert np.array_equal(va, vb), f"{path} at {t}"
            else:
                assert np.allclose(va, vb, rtol=0, atol=1e-6 * max(1.0, float(np.abs(va).max()))), f"{path} at {t}"
