#!/usr/bin/env python3
"""Regenerate painterly's codeless USD schema plugin from its source.

    schemas/painterly/schema.usda          (source, edited by hand)
      -> schemas/painterly/generatedSchema.usda   (committed)
      -> schemas/painterly/plugInfo.json          (committed)

usd-core's own generator (`python -m pxr.Usd.usdGenSchema`, which needs
jinja2) writes both files into a temporary folder; this script then fills in
the placeholders that usdGenSchema leaves for CMake in plugInfo.json
(`@PLUG_INFO_ROOT@` etc.), so the folder works as a resource plugin named by
PXR_PLUGINPATH_NAME: "Root" and "ResourcePath" are "." (the folder holding
plugInfo.json and generatedSchema.usda) and "LibraryPath" is removed (a
resource plugin has no shared library).

Usage (run with the Python that has usd-core and jinja2, e.g. .venv/bin/python):

    scripts/gen_schema.py            rewrite the generated files if they changed
    scripts/gen_schema.py --check    exit 1 (with a diff) if the committed files
                                     differ from what schema.usda generates

Exit codes: 0 up to date / written, 1 out of date (--check), 2 the generator
could not run.
"""

import argparse
import difflib
import importlib.util
import json
import os
import pathlib
import subprocess
import sys
import tempfile

REPO = pathlib.Path(__file__).resolve().parent.parent
SCHEMA_DIR = REPO / "schemas" / "painterly"
SOURCE = SCHEMA_DIR / "schema.usda"
GENERATED = ("generatedSchema.usda", "plugInfo.json")

PLUGIN_NAME = "painterly"
PLUGINFO_HEADER = (
    "# Generated from schema.usda by scripts/gen_schema.py (usd-core's\n"
    "# usdGenSchema, placeholders filled in). Do not edit: edit schema.usda\n"
    "# and rerun the script.\n"
)


class GenerationError(RuntimeError):
    pass


def _generator_available():
    """None when usdGenSchema can run here, else the reason it cannot."""
    for module in ("jinja2", "pxr"):
        if importlib.util.find_spec(module) is None:
            return f"Python module '{module}' is not importable by {sys.executable}"
    pxr_dir = pathlib.Path(importlib.util.find_spec("pxr").origin).parent
    if not (pxr_dir / "Usd" / "usdGenSchema.py").is_file():
        return f"usd-core at {pxr_dir} has no Usd/usdGenSchema.py"
    return None


def _run_usdgenschema(out_dir):
    # The generator must not see painterly's own (possibly stale) plugin: it
    # would add it to the resolver's search path and the schema registry.
    env = dict(os.environ)
    env.pop("PXR_PLUGINPATH_NAME", None)
    proc = subprocess.run(
        [sys.executable, "-m", "pxr.Usd.usdGenSchema", "-q", str(SOURCE), str(out_dir)],
        capture_output=True,
        text=True,
        env=env,
        cwd=str(out_dir),
    )
    missing = [name for name in GENERATED if not (out_dir / name).is_file()]
    if proc.returncode != 0 or missing:
        raise GenerationError(
            f"usdGenSchema failed (exit {proc.returncode}, missing {missing}):\n"
            f"{proc.stdout}{proc.stderr}"
        )


def _fix_pluginfo(text):
    """Fill usdGenSchema's CMake placeholders; returns the committed text."""
    # plugInfo.json may carry '#' comment lines (Plug's reader skips them).
    body = "".join(line for line in text.splitlines(keepends=True)
                   if not line.lstrip().startswith("#"))
    info = json.loads(body)
    plugins = [p for p in info.get("Plugins", []) if p.get("Name") == PLUGIN_NAME]
    if len(plugins) != 1:
        raise GenerationError(f"expected one plugin named {PLUGIN_NAME!r} in plugInfo.json")
    plugin = plugins[0]
    if plugin.get("Type") != "resource":
        raise GenerationError(
            "usdGenSchema did not declare a resource plugin: is "
            "skipCodeGeneration = true set on GLOBAL in schema.usda?")
    plugin["Root"] = "."
    plugin["ResourcePath"] = "."
    plugin.pop("LibraryPath", None)
    out = json.dumps(info, indent=4, sort_keys=True, separators=(",", ": "))
    if "@PLUG_INFO_" in out:
        raise GenerationError("unreplaced @PLUG_INFO_*@ placeholder left in plugInfo.json")
    return PLUGINFO_HEADER + out + "\n"


def generate():
    """Returns {file name: expected text} generated from schema.usda."""
    if not SOURCE.is_file():
        raise GenerationError(f"missing schema source {SOURCE}")
    with tempfile.TemporaryDirectory(prefix="painterly-schema-") as tmp:
        out_dir = pathlib.Path(tmp)
        _run_usdgenschema(out_dir)
        schema = (out_dir / "generatedSchema.usda").read_text()
        pluginfo = _fix_pluginfo((out_dir / "plugInfo.json").read_text())
    if not schema.endswith("\n"):
        schema += "\n"
    return {"generatedSchema.usda": schema, "plugInfo.json": pluginfo}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 if the committed files are out of date")
    args = parser.parse_args(argv)

    reason = _generator_available()
    if reason:
        print(f"gen_schema: usdGenSchema unavailable: {reason}", file=sys.stderr)
        return 2
    try:
        expected = generate()
    except GenerationError as err:
        print(f"gen_schema: {err}", file=sys.stderr)
        return 2

    stale = []
    for name, text in expected.items():
        path = SCHEMA_DIR / name
        current = path.read_text() if path.is_file() else None
        if current == text:
            continue
        stale.append(name)
        if args.check:
            diff = difflib.unified_diff(
                (current or "").splitlines(keepends=True), text.splitlines(keepends=True),
                fromfile=f"{path} (committed)", tofile=f"{path} (generated)")
            sys.stdout.writelines(diff)
        else:
            path.write_text(text)
            print(f"gen_schema: wrote {path.relative_to(REPO)}")

    if args.check and stale:
        print(f"gen_schema: out of date: {', '.join(stale)}; run scripts/gen_schema.py",
              file=sys.stderr)
        return 1
    if not stale:
        print("gen_schema: up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
