"""painterly's rules as usd-core UsdValidation validators.

One stage validator per rule ``painterly inspect`` checks (``painterly.RULES``),
named ``painterly.validators:<Rule>``, with the keyword ``painterly``. The
findings come from the Rust inspection (``painterly.inspect``), run once
per stage state and shared by every validator: the rules have one
implementation, and the CLI and the validators cannot disagree.

usd-core imports this module itself when ``plugInfo.json`` beside it is on
``PXR_PLUGINPATH_NAME`` as the validation registry starts (the plugin
path), and a validation context asks for the keyword. Importing it by hand
registers the same validators explicitly when the registry did not see
the plugin (``PXR_PLUGINPATH_NAME`` set too late).
"""

from __future__ import annotations

import os
import threading

from pxr import Sdf, Usd, UsdUtils, UsdValidation

import painterly

PLUGIN = "painterly.validators"
KEYWORD = "painterly"
UNREADABLE = "unreadable"

_lock = threading.Lock()
_cache: dict = {}


def _fingerprint(stage):
    """What the inspection of `stage` depends on: its layers' content (text
    for unsaved or anonymous layers, size and mtime for files), what the
    stage leaves out of them (muted layers, population mask, load rules) and
    the chunk files of a clip-set bake."""
    parts = [
        ("\0muted", tuple(sorted(stage.GetMutedLayers()))),
        ("\0mask", tuple(str(p) for p in stage.GetPopulationMask().GetPaths())),
        ("\0load", tuple((str(p), str(r)) for p, r in stage.GetLoadRules().GetRules())),
    ]
    for layer in stage.GetUsedLayers():
        real = layer.realPath
        if layer.anonymous or layer.dirty or not real or not os.path.isfile(real):
            parts.append((layer.identifier, layer.ExportToString()))
        else:
            st = os.stat(real)
            parts.append((layer.identifier, st.st_size, st.st_mtime_ns))
    real = stage.GetRootLayer().realPath
    if real:
        clips = os.path.splitext(real)[0] + ".clips"
        if os.path.isdir(clips):
            for name in sorted(os.listdir(clips)):
                st = os.stat(os.path.join(clips, name))
                parts.append((name, st.st_size, st.st_mtime_ns))
    parts.extend(_clip_set_input(stage.GetRootLayer()))
    return tuple(sorted(parts, key=lambda p: p[0]))


def _clip_set_input(root):
    """A clip set's chunks are judged against its input as it is now: the
    files that input reads (its layers, and the clips and other assets they
    name) are part of what the inspection depends on, though the stage does
    not open them."""
    data = root.customLayerData.get("painterly", {})
    src = data.get("input") if "chunks" in data else None
    if not isinstance(src, str) or not os.path.isfile(src):
        return [("\0input", src)]
    layers, assets, _ = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(src))
    files = {src, *(layer.realPath for layer in layers), *assets}
    out = []
    for f in sorted(p for p in files if p and os.path.isfile(p)):
        st = os.stat(f)
        out.append(("\0input " + f, st.st_size, st.st_mtime_ns))
    return out


def _source(stage):
    """The file itself when the stage is exactly what is on disk (relative
    paths, clips and chunk checks work as in the CLI), else the flattened
    stage, which holds every unsaved edit and leaves out what the stage
    does (muted layers, prims outside its population mask, unloaded payloads)."""
    root = stage.GetRootLayer()
    session = stage.GetSessionLayer()
    clean = (
        root.realPath
        and not root.anonymous
        and not any(layer.dirty for layer in stage.GetUsedLayers() if layer != session)
        and (session is None or session.empty)
        and not stage.GetMutedLayers()
        and stage.GetPopulationMask() == Usd.StagePopulationMask.All()
        and stage.GetLoadRules() == Usd.StageLoadRules.LoadAll()
    )
    return root.realPath if clean else stage.Flatten()


def _frames(time_range):
    """The validation's time range as inspect's frames: (min, max) when it
    is a finite interval (as ``--frames A:B``), else None (the stage's own)."""
    interval = time_range.GetInterval() if time_range is not None else None
    if interval is None or interval.IsEmpty() or not interval.IsFinite():
        return None
    return (interval.GetMin(), interval.GetMax())


def problems(stage, frames=None):
    """The inspection of `stage` (over `frames`, (start, end), when given):
    (problems as in ``inspect --json``, None) or ([], the
    ``painterly.Error`` that stopped it)."""
    key = (stage.GetRootLayer().identifier, frames, _fingerprint(stage))
    with _lock:
        if key not in _cache:
            try:
                _cache.clear()  # one stage state at a time: validators of one run share it
                _cache[key] = (painterly.inspect(_source(stage), frames=frames)["problems"], None)
            except painterly.Error as e:
                _cache[key] = ([], e)
        return _cache[key]


def _site(stage, prim, attribute):
    """The property when the stage has it, else its prim (a site must
    exist on the stage to be valid); the message names both anyway."""
    p = stage.GetPrimAtPath(prim) if prim and Sdf.Path.IsValidPathString(prim) else None
    if not p:
        return UsdValidation.ValidationErrorSite(stage, Sdf.Path.absoluteRootPath)
    path = p.GetPath()
    if attribute and p.GetProperty(attribute):
        path = path.AppendProperty(attribute)
    return UsdValidation.ValidationErrorSite(stage, path)


def _error(stage, name, p):
    # `name` is the error's own name: usd-core prints it after the
    # validator's ("painterly.validators:PointCounts.point-counts"), so the
    # rule id, not the validator's name again.
    where = p["prim"] or ""
    if p["attribute"]:
        where += "." + p["attribute"]
    text = f"{where}: {p['message']}" if where else p["message"]
    return UsdValidation.ValidationError(
        name, UsdValidation.ValidationErrorType.Error, [_site(stage, p["prim"], p["attribute"])], text
    )


def _rule_task(rule):
    def task(stage, time_range=None):
        found, failure = problems(stage, _frames(time_range))
        errors = [_error(stage, rule["id"], p) for p in found if p["rule"] == rule["id"]]
        if failure is not None and rule["id"] == UNREADABLE:
            # The inspection could not even open the stage.
            p = {"prim": failure.prim, "attribute": failure.attribute, "message": str(failure)}
            errors.append(_error(stage, rule["id"], p))
        return errors

    return task


def validators():
    """(name, doc, task) of every painterly validator, one per rule."""
    return [(r["validator"], r["doc"], _rule_task(r)) for r in painterly.RULES]


def plugin_info():
    """The contents ``plugInfo.json`` must have (a test compares them)."""
    entries = {name: {"doc": doc} for name, doc, _ in validators()}
    entries["keywords"] = [KEYWORD]
    return {"Plugins": [{"Type": "python", "Name": PLUGIN, "Info": {"Validators": entries}}]}


def register():
    """Registers every validator, once: under the plugin's metadata when the
    registry read ``plugInfo.json``, else explicitly with the same metadata."""
    registry = UsdValidation.ValidationRegistry()
    for name, doc, task in validators():
        full = f"{PLUGIN}:{name}"
        if registry.HasValidator(full):
            continue
        if registry.GetValidatorMetadata(full) is not None:
            registry.RegisterPluginStageValidator(full, task)
        else:
            meta = UsdValidation.ValidatorMetadata(name=full, doc=doc, keywords=[KEYWORD])
            registry.RegisterStageValidator(meta, task)


register()
