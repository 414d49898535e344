"""Shared pytest setup for painterly's contract tests.

The painterly schema plugin is registered *before* the first `from pxr import Usd`
(usd-core ignores PXR_PLUGINPATH_NAME set later), so every test validates
against the codeless schema in `schemas/painterly/`.
"""

import importlib.util
import os
import pathlib
import pty
import select
import subprocess

REPO = pathlib.Path(__file__).resolve().parent.parent
SCHEMA_DIR = REPO / "schemas" / "painterly"
SHARED = REPO.parent / "shared"
# A worktree outside the usual layout can point at the assets directly.
REAL_ASSETS = pathlib.Path(os.environ.get("PAINTERLY_REAL_ASSETS", SHARED / "real_assets"))

# With the `painterly` package installed, its usd-core validator plugin too
# (found without importing the package, which would not matter, and pxr,
# which would: the plugin path must be set before pxr starts).
_package = importlib.util.find_spec("painterly")
PAINTERLY_PLUGIN = (
    os.path.join(list(_package.submodule_search_locations)[0], "validators")
    if _package and _package.submodule_search_locations
    else None
)
os.environ["PXR_PLUGINPATH_NAME"] = os.pathsep.join(p for p in (str(SCHEMA_DIR), PAINTERLY_PLUGIN) if p)

import pytest  # noqa: E402


def painterly_binary() -> pathlib.Path:
    """The CLI under test: $PAINTERLY_BIN, else the release build."""
    env = os.environ.get("PAINTERLY_BIN")
    if env:
        return pathlib.Path(env)
    return REPO / "target" / "release" / "painterly"


def run_on_pty(args):
    """Run with stderr (and stdout) on a pseudo-terminal; return (exit code, what the terminal got)."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([str(painterly_binary()), *map(str, args)], stdout=slave, stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    out = b""
    while True:
        ready, _, _ = select.select([master], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not chunk:
                break
            out += chunk
        elif proc.poll() is not None:
            break
    code = proc.wait(timeout=300)
    os.close(master)
    return code, out.decode("utf-8", "replace")


def run_painterly(*args, check=True, cwd=None, env=None, input=None):
    """Run the painterly CLI; returns CompletedProcess with text stdout/stderr."""
    exe = painterly_binary()
    if not exe.exists():
        pytest.fail(f"painterly binary not built: {exe} (run `cargo build --release --ignore-rust-version`)")
    proc = subprocess.run(
        [str(exe), *[str(a) for a in args]],
        capture_output=True,
        input=input,
        text=True,
        cwd=cwd,
        env=env,
        timeout=600,
    )
    if check and proc.returncode != 0:
        raise AssertionError(
            f"painterly {' '.join(map(str, args))} exited {proc.returncode}\n"
            f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
        )
    return proc


@pytest.fixture
def painterly():
    return run_painterly


@pytest.fixture
def repo_root():
    return REPO


@pytest.fixture
def real_assets():
    if not REAL_ASSETS.exists():
        pytest.skip(f"real assets not found at {REAL_ASSETS}")
    return REAL_ASSETS
