"""``painterly-validate FILE...``: run painterly's usd-core validators.

Runs ``UsdValidation.ValidationContext(keywords=["painterly"])`` on each
file's stage, prints every error (validator, prim, attribute, message) and
exits 1 when there is one, 0 when there is none, 2 for bad usage.

The validators are a usd-core plugin (``painterly.plugin_path()``). usd-core
reads ``PXR_PLUGINPATH_NAME`` once, when its plugin registry starts, so this
script puts the plugin on it before importing ``pxr``.
"""

from __future__ import annotations

import argparse
import os
import sys


def _add_plugin_path():
    from painterly import plugin_path

    paths = [p for p in os.environ.get("PXR_PLUGINPATH_NAME", "").split(os.pathsep) if p]
    if plugin_path() not in paths:
        os.environ["PXR_PLUGINPATH_NAME"] = os.pathsep.join([plugin_path(), *paths])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="painterly-validate",
        description="Check USD files against the painterly schema's rules with usd-core's UsdValidation.",
        epilog="Example: painterly-validate fixtures/blowfish.usda",
    )
    ap.add_argument("files", nargs="+", metavar="FILE", help="USD files (.usda, .usdc, .usdz)")
    args = ap.parse_args(argv)

    if "pxr" not in sys.modules:
        _add_plugin_path()
    from pxr import Usd, UsdValidation

    if UsdValidation.ValidationRegistry().GetValidatorMetadata("painterly.validators:Unreadable") is None:
        import painterly.validators  # noqa: F401  (pxr was imported before the plugin path was set)

    failed = False
    for f in args.files:
        try:
            stage = Usd.Stage.Open(f)
        except Exception as e:  # usd-core raises Tf.ErrorException
            print(f"{f}: usd-core cannot open it: {e}", file=sys.stderr)
            failed = True
            continue
        context = UsdValidation.ValidationContext(keywords=["painterly"])
        errors = [e for e in context.Validate(stage) if not e.HasNoError()]
        for e in errors:
            print(f"{f}: {e.GetErrorAsString()}")
        if any(e.GetType() == UsdValidation.ValidationErrorType.Error for e in errors):
            failed = True
        if not errors:
            print(f"{f}: no problems found")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
