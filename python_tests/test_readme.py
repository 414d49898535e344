"""The README is executable (issue 13): every command in its ```sh blocks runs
as written, in a scratch copy of the repository, and what it says it writes
exists and opens in usd-core.

Conventions the README follows so that this test can run it:
- each ```sh block is one bash script (`set -euo pipefail`), run from the
  repository root of the scratch copy with `painterly` and the venv's
  `python` first on PATH;
- `cargo run --release --ignore-rust-version -- ARGS` runs the same binary as
  `painterly ARGS`; `cargo install --path . --ignore-rust-version` is the
  step that puts it on PATH, so it is not re-run here; `scripts/test` is what
  is running this test;
- outputs go to `/tmp/` (mapped to a scratch folder here);
- a block preceded by `<!-- readme-test: skip REASON -->` is not run (only
  for what cannot run here, e.g. usdview); the reason is listed in the test
  output and every skip must name one.
"""

import os
import pathlib
import re
import shlex
import shutil
import subprocess

import pytest
from pxr import Sdf

from conftest import REPO, painterly_binary

README = REPO / "README.md"
SKIP = re.compile(r"<!--\s*readme-test:\s*skip\s+(.+?)\s*-->\s*$")
# Commands that are the test harness itself or the install step.
NOT_RERUN = [
    (re.compile(r"^scripts/test(\s|$)"), "scripts/test is what runs this test"),
    (re.compile(r"^cargo install --path \. --ignore-rust-version$"), "the binary under test is already on PATH"),
]
CARGO_RUN = "cargo run --release --ignore-rust-version -- "


def sh_blocks(text):
    """(line number, skip reason or None, code) of every ```sh block."""
    blocks = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if lines[i].strip() == "```sh":
            prev = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            m = SKIP.search(prev)
            start = i + 1
            i += 1
            body = []
            while i < len(lines) and lines[i].strip() != "```":
                body.append(lines[i])
                i += 1
            blocks.append((start, m.group(1) if m else None, "\n".join(body)))
        i += 1
    return blocks


def commands(code):
    """Logical commands of a block (continuations joined, comments dropped)."""
    out, cur = [], ""
    for line in code.splitlines():
        if cur == "" and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.rstrip().endswith("\\"):
            cur += line.rstrip()[:-1] + " "
            continue
        cur += line
        out.append(cur.strip())
        cur = ""
    return out


def rewrite(code, tmp):
    """The block as the scratch copy runs it."""
    lines = []
    for cmd in commands(code):
        reason = next((why for pat, why in NOT_RERUN if pat.search(cmd)), None)
        if reason:
            lines.append(": " + shlex.quote(f"not re-run: {cmd} ({reason})"))
            continue
        if cmd.startswith(CARGO_RUN):
            cmd = "painterly " + cmd[len(CARGO_RUN):]
        lines.append(cmd)
    script = "\n".join(lines)
    return re.sub(r"(?<![\w.])/tmp/", str(tmp) + "/", script)


def scratch_copy(dest):
    """The tracked files of the repository (no target/, no venv)."""
    files = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout.split()
    for f in files:
        src = REPO / f
        if not src.is_file():
            continue
        d = dest / f
        d.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, d)
    return dest


BLOCKS = sh_blocks(README.read_text())


def test_readme_opens_with_the_two_commands():
    first = commands(BLOCKS[0][2])
    assert first == [
        "cargo run --release --ignore-rust-version -- bake fixtures/blowfish.usda -o /tmp/blowfish_bake.usdc",
        "scripts/test",
    ], first
    text = README.read_text()
    assert "cargo install --path . --ignore-rust-version" in text
    assert "painterly --version" in text


def test_every_skip_names_a_reason():
    for line, reason, _ in BLOCKS:
        if reason is not None:
            assert len(reason.split()) >= 3, f"README.md:{line}: a skip needs a reason"


@pytest.mark.parametrize("line,reason,code", BLOCKS, ids=[f"README.md:{b[0]}" for b in BLOCKS])
def test_readme_block_runs(tmp_path, line, reason, code):
    if reason is not None:
        pytest.skip(reason)
    repo = scratch_copy(tmp_path / "repo")
    out = tmp_path / "out"
    out.mkdir()
    script = rewrite(code, out)
    env = dict(os.environ)
    venv_bin = pathlib.Path(os.environ.get("VIRTUAL_ENV", REPO / ".venv")) / "bin"
    env["PATH"] = f"{painterly_binary().parent}:{venv_bin}:{env['PATH']}"
    env.pop("PXR_PLUGINPATH_NAME", None)
    proc = subprocess.run(
        ["bash", "-c", "set -euo pipefail\n" + script],
        cwd=repo,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"README.md:{line} failed (exit {proc.returncode})\n{script}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    assert "error" not in proc.stderr.lower(), f"README.md:{line} printed an error:\n{proc.stderr}"
    # What the commands say they write exists and opens in usd-core.
    for cmd in commands(script):
        for flag in ("-o", "--output", "--edit-layer"):
            for m in re.finditer(rf"(?:^|\s){re.escape(flag)}\s+(\S+)", cmd):
                target = m.group(1).strip("'\"")
                p = (repo / target) if not os.path.isabs(target) else pathlib.Path(target)
                if "#" in p.name:
                    matches = list(p.parent.glob(p.name.replace("#", "?")))
                    assert matches, f"README.md:{line}: `{cmd}` wrote no {p}"
                    continue
                assert p.exists(), f"README.md:{line}: `{cmd}` did not write {p}"
                if p.suffix in (".usda", ".usdc", ".usd"):
                    assert Sdf.Layer.FindOrOpen(str(p)), f"README.md:{line}: usd-core cannot open {p}"
    # Inputs are never modified (outside --in-place).
    for f in (repo / "fixtures").glob("*.usda"):
        if "--in-place" not in script:
            assert f.read_bytes() == (REPO / "fixtures" / f.name).read_bytes(), f"README.md:{line} changed {f.name}"
