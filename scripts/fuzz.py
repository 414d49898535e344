"""Mutation fuzzer for painterly's reader, inspect and bake (issue 11).

Each case takes a seed file (the fixtures, the reliability cases and
usd-core-written .usdc copies), applies 1-4 random mutations (byte flips,
line deletions/duplications/swaps, truncation, numbers replaced by extreme
values, composition arcs inserted) and runs `painterly inspect` and, when
inspect passes or on every 4th case, `painterly bake` on it, each as its own
process under a 60 s timeout and an address-space limit. A case fails when:

- a run ends by a signal (abort, stack overflow) or with exit 3 (a panic);
- a run takes over 60 s (a hang);
- stderr shows a panic or "internal error";
- a run exits outside {0, 1} (usage errors cannot come from a file);
- a run leaves a temporary (`.painterly-`) file, or changes its input;
- with --values or --keys, a bake on one thread writes other bytes than on all.

- inspect exits 0 but the default bake (no --frames) fails: inspect
  evaluates every frame of that bake, so it must find what bake finds (a
  "trust" failure). A stage without a frame range is inspected and baked
  with --frames 1:3, as both then need frames, and judged so; a stage with
  half a range and other problems is baked with --frames 1:3 unjudged
  (inspect stopped at the other problems), and so is a stage with nothing
  painterly in it (inspect finds nothing wrong, bake says "nothing to
  bake").

With --edits each case also runs one command that writes (picked by the
case's random stream): `bind --in-place`, `bind --edit-layer`, `expand` or
`smudge --in-place` on the seed's first stroke layer, a pose or time key
(`key --in-place --points`), or a two-frame `render` through the seed's
camera. Besides the checks above, a case also fails when:

- a command that failed, or one that writes elsewhere (`--edit-layer`,
  `render`), changed its input, or one left a temporary file;
- an in-place edit of a file `inspect` passed leaves a file `inspect`
  rejects (an "edit" trust failure);
- usd-core opens the input but not what painterly wrote, or cannot then
  edit it and save it in place (checked in batches, one usd-core process
  per 200 written files).

With --values the mutations keep the file's structure, so that more
inputs read and more edits get as far as writing: the case takes a text
fixture (those above and blowfish.usda, which has time keys and
sentinels) and changes only its values, on lines picked at random (a
number scaled, nudged by a rounding step, set to 0 or an extreme, an
index moved by one; an array element dropped or repeated); a bake that
succeeds runs again on one thread and must write the same bytes; and two
cases in five go to usd-core, which writes the mutated text as a crate
file (the crate reader and writer then run). A case usd-core cannot
convert stays text.

With --keys the mutations change the structure of painterly's own prims
(keys, axes, view keys) in the fixtures that have them (blowfish, head,
walk, building, apple): a prim deleted, copied under a new name (beside
itself or after another prim, which may be in another stroke layer, with
one of its scalars nudged or not), retyped, a property dropped or copied
in from another prim, a sentinel set or cleared. Cases otherwise run as
with --values (crate conversion, the one-thread bake check), and with
--edits half of the edits are `key` commands of every kind (pose, time
key, sentinel; at several times; with points or an opacity; named after
an existing key or not; replacing or not).

Usage: python3 scripts/fuzz.py --cases N --seed S [--first K] [--jobs J] [--keep DIR] [--edits] [--values | --keys]
Failing inputs are copied to --keep (default target/fuzz-failures) with
their stderr; the exit status is the number of failures (capped at 100).
Cases are reproducible from (seed, case index).
"""

import argparse
import concurrent.futures as cf
import functools
import json
import os
import pathlib
import random
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parent.parent
TIMEOUT_S = 60
# Address-space limit per painterly run (documented in README "Limits").
MEMORY_LIMIT = 4 << 30

EXTREMES = [b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"1e19", b"4294967296", b"0", b"-1", b"1e-19",
            b"2147483647", b"-2147483648", b"1e9"]
ARCS = [b'(inherits = </Nowhere>)', b'(references = @missing.usda@)', b'(payload = @gone.usdc@)',
        b'(specializes = </Blowfish>)', b'(inherits = </World>)', b'(references = </World>)']


FIXTURES = ["static.usda", "building.usda", "tube.usda", "head.usda", "walk.usda", "fig4.usda"]
# --values also takes blowfish.usda, the fixture with time keys and
# sentinels (kept out of FIXTURES so that the cases of a seed without
# --values stay the ones the failure notes cite).
VALUE_FIXTURES = FIXTURES + ["blowfish.usda"]
# --keys: the fixtures with painterly prims (keys, axes, view keys).
KEY_FIXTURES = ["blowfish.usda", "head.usda", "walk.usda", "building.usda", "apple.usda"]


def main_checkout():
    """The checkout a worktree was added from (REPO itself in a clone): its
    .venv serves a scratch worktree that has none."""
    common = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--path-format=absolute", "--git-common-dir"],
                            capture_output=True, text=True).stdout.strip()
    return pathlib.Path(common).parent if common else REPO


@functools.cache
def venv_python():
    """Found once: the harness asks for it per case, and the main checkout
    costs a `git` call."""
    venv = [REPO / ".venv/bin/python", main_checkout() / ".venv/bin/python"]
    return next((str(v) for v in venv if v.exists()), None)


# The stroke layers, cameras and start time of each seed (before mutation),
# read by usd-core: the arguments of the edit commands.
META_CODE = """
import json, sys
from pxr import Usd
out = {}
for path in sys.argv[1:]:
    st = Usd.Stage.Open(path)
    layers = [str(p.GetPath()) for p in st.Traverse()
              if p.HasAuthoredMetadata('apiSchemas')
              and 'PainterlyStrokeLayerAPI' in p.GetMetadata('apiSchemas').GetAddedOrExplicitItems()]
    cams = [str(p.GetPath()) for p in st.Traverse() if p.GetTypeName() == 'Camera']
    out[path] = {'layers': layers, 'cameras': cams, 'start': st.GetStartTimeCode()}
print(json.dumps(out))
"""


def seed_meta(paths):
    r = subprocess.run([venv_python(), "-c", META_CODE, *map(str, paths)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"fuzz: reading the seeds' layers and cameras with usd-core failed:\n{r.stderr}")
    return {pathlib.Path(k).name: v for k, v in json.loads(r.stdout).items()}


def seeds(work):
    """Seed files: small fixtures as text, and each also as usd-core crate bytes."""
    out = []
    for n in FIXTURES:
        p = REPO / "fixtures" / n
        if p.exists():
            out.append((n, p.read_bytes()))
    crate_dir = work / "seeds"
    crate_dir.mkdir(exist_ok=True)
    py = venv_python()
    if py:
        for n, _ in list(out)[:4]:
            dst = crate_dir / n.replace(".usda", ".usdc")
            code = ("from pxr import Sdf; import sys; l = Sdf.Layer.FindOrOpen(sys.argv[1]); "
                    "l.Export(sys.argv[2])")
            r = subprocess.run([py, "-c", code, str(REPO / "fixtures" / n), str(dst)], capture_output=True)
            if r.returncode == 0 and dst.exists():
                out.append((dst.name, dst.read_bytes()))
    return out


def seeds_meta():
    """seed_meta of every seed file, the crate copies sharing their fixture's."""
    names = dict.fromkeys(VALUE_FIXTURES + KEY_FIXTURES)
    meta = seed_meta([REPO / "fixtures" / n for n in names if (REPO / "fixtures" / n).exists()])
    return {**meta, **{n.replace(".usda", ".usdc"): m for n, m in meta.items()}}


def mutate(rng, data, is_text):
    for _ in range(rng.randint(1, 4)):
        if not data:
            break
        kind = rng.random()
        if is_text and kind < 0.30:
            # Replace a number by an extreme value.
            nums = list(re.finditer(rb"-?\d+(\.\d+)?(e-?\d+)?", data))
            if nums:
                m = rng.choice(nums)
                data = data[:m.start()] + rng.choice(EXTREMES) + data[m.end():]
                continue
        if is_text and kind < 0.50:
            lines = data.split(b"\n")
            i = rng.randrange(len(lines))
            op = rng.random()
            if op < 0.35:
                del lines[i]
            elif op < 0.6:
                lines.insert(i, lines[rng.randrange(len(lines))])
            elif op < 0.8:
                j = rng.randrange(len(lines))
                lines[i], lines[j] = lines[j], lines[i]
            else:
                # A composition arc on a prim definition line.
                defs = [k for k, l in enumerate(lines) if re.match(rb'\s*(def|over|class)\b.*"\s*$', l)]
                if defs:
                    k = rng.choice(defs)
                    lines[k] = lines[k] + b" " + rng.choice(ARCS)
            data = b"\n".join(lines)
            continue
        if kind < 0.85:
            b = bytearray(data)
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(b))
                b[i] = rng.randrange(256) if rng.random() < 0.5 else b[i] ^ (1 << rng.randrange(8))
            data = bytes(b)
        else:
            data = data[: rng.randrange(len(data))]
    return data


# A number standing alone: not part of a name such as `float3`, `Layer_12`
# or `v1.2.usda`, whose change would break the syntax rather than a value.
NUMBER = re.compile(rb"(?<![\w.:@/-])-?\d+(\.\d+)?([eE][-+]?\d+)?(?![\w.@/])")
# One element of a flat number array or a tuple array: `[1, 2, 3]`, `[(0, 1, 2), (3, 4, 5)]`.
ELEMENT = re.compile(rb"(?<=[\[,])\s*(\([^()\[\]]*\)|-?[\d.eE+-]+)\s*(?=[,\]])")


def pick(rng, lines, pattern, max_len=None):
    """A random line holding `pattern` (no longer than `max_len`, if given),
    and one match on it; None if no line has one. The line is picked first,
    so that a scalar on a short line is as likely as a large array's
    element, which all share one line."""
    found = [(i, ms) for i, line in enumerate(lines)
             if (max_len is None or len(line) < max_len) and (ms := list(pattern.finditer(line)))]
    if not found:
        return None
    i, ms = rng.choice(found)
    return i, rng.choice(ms)


def mutate_values(rng, data):
    """1-4 value changes that keep a text layer parseable (--values). Each
    picks a line first, then a value on it, so that the few scalar values
    (times, scales, sentinels, transform ops) are as likely to change as
    the points of a large array, which all share one line."""
    for _ in range(rng.randint(1, 4)):
        lines = data.split(b"\n")
        if rng.random() < 0.2:
            # Drop or repeat one array element: counts that no longer agree.
            hit = pick(rng, lines, ELEMENT)
            if hit is None:
                continue
            i, m = hit
            line = lines[i]
            if rng.random() < 0.5:
                end = m.end() + 1 if line[m.end():m.end() + 1] == b"," else m.end()
                start = m.start() - 1 if end == m.end() and line[m.start() - 1:m.start()] == b"," else m.start()
                lines[i] = line[:start] + line[end:]
            else:
                lines[i] = line[:m.end()] + b"," + m.group(0) + line[m.end():]
        else:
            hit = pick(rng, lines, NUMBER)
            if hit is None:
                break
            i, m = hit
            is_int = m.group(1) is None and m.group(2) is None
            x = float(m.group(0))
            op = rng.random()
            if op < 0.1:
                new = rng.choice(EXTREMES)
            elif is_int and op < 0.6:
                # 4095, not 65535: a range of 65,535 frames is legal, and inspect
                # of blowfish.usda then evaluates them for about 25 s (40 s
                # under load: seed 20261210, case 1261), too near the hang limit.
                new = str(int(rng.choice([0, -1, x + 1, x - 1, 2 * x + 1, 4095]))).encode()
            elif op < 0.7:
                new = repr(x * (1 + rng.choice([1e-15, -1e-15, 1e-7, -1e-7]))).encode()
            else:
                new = repr(x * rng.choice([0.0, -1.0, 2.0, 0.5, 1e-6, 1e6, 1e-30, 1e30]) if x else
                           rng.choice([1e-30, 1e-7, 1.0, -1.0])).encode()
            lines[i] = lines[i][:m.start()] + new + lines[i][m.end():]
        data = b"\n".join(lines)
    return data


PRIM = re.compile(rb'^(\s*)def (Painterly\w+) "([^"]+)"')
PRIM_TYPES = [b"PainterlyPoseKey", b"PainterlyTimeKey", b"PainterlyViewKey", b"PainterlyAxis"]
PROPERTY = re.compile(rb"^\s*(uniform |custom )*[\w:\[\]]+ [\w:.]+( = .*)?$")


def painterly_prims(lines):
    """(first line, closing line, match) of each painterly prim: the fixtures
    close a prim with a `}` at the indent of its `def`."""
    out = []
    for i, line in enumerate(lines):
        m = PRIM.match(line)
        if m:
            close = m.group(1) + b"}"
            j = next((j for j in range(i + 1, len(lines)) if lines[j].rstrip() == close), None)
            if j is not None:
                out.append((i, j, m))
    return out


def property_lines(lines, first, close):
    """Indices of the one-line properties of the prim from line `first` (its
    `def`) to `close` (its `}`)."""
    return [k for k in range(first + 2, close)
            if PROPERTY.match(lines[k]) and not lines[k].rstrip().endswith(b"(")]


def nudge_scalar(rng, lines):
    """Changes one number on a short line (a time, a coordinate, a
    direction, a sentinel): the values that decide which keys meet."""
    hit = pick(rng, lines, NUMBER, max_len=200)
    if hit is None:
        return
    i, m = hit
    x = float(m.group(0))
    new = rng.choice([x * (1 + 1e-15), x * (1 - 1e-7), x + 1e-12, x + 0.5, -x, x * 1e6, 0.0])
    lines[i] = lines[i][:m.start()] + repr(new).encode() + lines[i][m.end():]


def mutate_keys(rng, data):
    """1-3 changes to the structure of a layer's painterly prims (--keys)."""
    for _ in range(rng.randint(1, 3)):
        lines = data.split(b"\n")
        prims = painterly_prims(lines)
        if not prims:
            break
        i, j, m = rng.choice(prims)
        indent, kind, name = m.groups()
        body = property_lines(lines, i, j)
        op = rng.random()
        if op < 0.15:
            del lines[i:j + 1]
        elif op < 0.45:
            # A copy under a new name: beside itself (a second key at nearly
            # the same place) or after another prim (perhaps in another layer).
            copy = lines[i:j + 1]
            copy[0] = copy[0].replace(b'"' + name + b'"', b'"%sCopy%d"' % (name, rng.randrange(100)), 1)
            if rng.random() < 0.7:
                nudge_scalar(rng, copy)
            at, _, m2 = (i, j, m) if rng.random() < 0.6 else rng.choice(prims)
            to = m2.group(1)
            copy = [to + line[len(indent):] if line.startswith(indent) else line for line in copy]
            end = next(e for s0, e, _ in prims if s0 == at)
            lines[end + 1:end + 1] = [b""] + copy
        elif op < 0.6:
            lines[i] = lines[i].replace(kind, rng.choice([t for t in PRIM_TYPES if t != kind]), 1)
        elif op < 0.75 and body:
            del lines[rng.choice(body)]
        elif op < 0.9:
            # A property of another prim (a sentinel, a time, coordinates of
            # another dimension, a direction, points of another layer).
            i2, j2, _ = rng.choice(prims)
            donors = property_lines(lines, i2, j2)
            if donors:
                line = lines[rng.choice(donors)].lstrip()
                lines[i + 2:i + 2] = [indent + b"    " + line]
        else:
            flag = [k for k in body if b"sentinel" in lines[k]]
            if flag:
                k = flag[0]
                lines[k] = lines[k].replace(b"= 1", b"= 0") if b"= 1" in lines[k] else lines[k].replace(b"= 0", b"= 1")
            else:
                lines[i + 2:i + 2] = [indent + b"    uniform bool sentinel = 1"]
        data = b"\n".join(lines)
    return data


# Writes a mutated text layer as crate (--values): usd-core's own writer.
CRATE_CODE = ("import sys; from pxr import Sdf; l = Sdf.Layer.FindOrOpen(sys.argv[1]); "
              "sys.exit(0 if l is not None and l.Export(sys.argv[2]) else 1)")


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(exe, args, cwd, env=None):
    t0 = time.monotonic()
    try:
        p = subprocess.run([exe, *args], capture_output=True, text=True, errors="replace", cwd=cwd,
                           timeout=TIMEOUT_S, preexec_fn=limit_memory, env=env)
        err = p.stderr
        if args[0] == "inspect" and "problem(s):" in p.stdout:
            # inspect lists its problems on stdout, after this line: a
            # failure note names them.
            err += p.stdout.split("problem(s):\n", 1)[-1]
        return p.returncode, err, time.monotonic() - t0
    except subprocess.TimeoutExpired:
        return "timeout", "", time.monotonic() - t0


def edit_command(rng, name, meta):
    """One command that writes, for a case's file `name`: (args, in_place)."""
    layers, cams = meta.get("layers") or ["/Nowhere"], meta.get("cameras") or ["/Nowhere"]
    layer, start = rng.choice(layers), str(meta.get("start", 1.0))
    tool = ["--layer", layer, "--path", "-100,-100,-100 100,100,100", "--radius", "1000"]
    commands = [
        (["bind", name, "--in-place"], True),
        (["bind", name, "--edit-layer", "edits.usda"], False),
        (["expand", name, "--in-place", *tool, "--strength", "0.01"], True),
        (["smudge", name, "--in-place", *tool, "--strength", "0.02"], True),
        (["key", name, "--in-place", "--layer", layer, "--time", start, "--points"], True),
        (["key", name, "--in-place", "--layer", layer, "--time", start, "--time-key", "--points"], True),
        (["render", name, "--camera", rng.choice(cams), "--frames", "1:2", "-o", "r.####.exr", "--size", "32x18"],
         False),
    ]
    args, in_place = rng.choice(commands)
    return [*args, "-q"], in_place


# Key names of the --keys fixtures, and keyN/timeN/sentinelN: `key --name`
# that may meet an existing key.
KEY_NAMES = ["front", "left", "shock", "settle", "shockEnd", "light000", "FrontF10", "key1", "time1", "sentinel1"]


def key_command(rng, name, meta):
    """A `key --in-place` of --keys: any kind (pose, time, sentinel), at
    the start, a fraction of a frame on, a frame blowfish keys or a random
    time, with points or an opacity, sometimes named or replacing."""
    layers = meta.get("layers") or ["/Nowhere"]
    start = float(meta.get("start", 1.0))
    time = rng.choice([start, start + 0.5, start + 1e-9, 36.0, 40.0, 44.0, 47.0, rng.uniform(start, start + 48)])
    args = ["key", name, "--in-place", "--layer", rng.choice(layers), "--time", repr(time)]
    kind = rng.random()
    if kind < 0.2:
        args.append("--sentinel")
    else:
        if kind < 0.6:
            args.append("--time-key")
        args += rng.choice([["--points"], ["--opacity", "0.5"], ["--points", "--opacity", "1"]])
    if rng.random() < 0.3:
        args += ["--name", rng.choice(KEY_NAMES)]
    if rng.random() < 0.3:
        args.append("--replace")
    return [*args, "-q"], True


def check(exe, seed, k, seed_files, work, meta=None, value_files=None, keys=False):
    rng = random.Random(f"{seed}:{k}")
    d = work / f"c{k}"
    d.mkdir()
    values = value_files is not None
    if values:
        if keys:
            name = rng.choice(KEY_FIXTURES)
            data = mutate_keys(rng, value_files[name])
        else:
            name = rng.choice(VALUE_FIXTURES)
            data = mutate_values(rng, value_files[name])
        if rng.random() < 0.4:
            (d / "text.usda").write_bytes(data)
            crate = d / name.replace(".usda", ".usdc")
            r = subprocess.run([venv_python(), "-c", CRATE_CODE, str(d / "text.usda"), str(crate)],
                               capture_output=True)
            (d / "text.usda").unlink()
            if r.returncode == 0 and crate.exists():
                name, data = crate.name, crate.read_bytes()
            crate.unlink(missing_ok=True)
    else:
        name, data = rng.choice(seed_files)
        data = mutate(rng, data, name.endswith(".usda"))
    src = d / name
    src.write_bytes(data)
    problems, trust = [], []

    def judge(what, rc, err):
        if rc == "timeout":
            problems.append(f"{what}: no exit within {TIMEOUT_S} s")
        elif rc < 0:
            problems.append(f"{what}: killed by signal {-rc}")
        elif rc not in (0, 1):
            problems.append(f"{what}: exit {rc}")
        if "panicked" in err or "internal error" in err or "overflowed its stack" in err:
            problems.append(f"{what}: panic/internal error")

    rc_i, err_i, t_i = run(exe, ["inspect", name], d)
    judge("inspect", rc_i, err_i)
    frames = []
    if rc_i == 1 and "pass --frames" in err_i:
        # No frame range: inspect, like bake, needs --frames.
        frames = ["--frames", "1:3"]
        rc_i, err_i, t_i = run(exe, ["inspect", name, *frames], d)
        judge("inspect --frames 1:3", rc_i, err_i)
    rc_b, err_b, t_b = None, "", 0.0
    if rc_i == 0 or k % 4 == 0:
        # The default bake (the stage's range) is what inspect vouches for.
        rc_b, err_b, t_b = run(exe, ["bake", name, "-o", "out.usdc", "-q", *frames], d)
        vouched = True
        if rc_b == 1 and "pass --frames" in err_b and not frames:
            # No complete range, and inspect stopped before the frames.
            frames = ["--frames", "1:3"]
            rc_b, err_b, t_b = run(exe, ["bake", name, "-o", "out.usdc", "-q", *frames], d)
            vouched = False
        judge("bake", rc_b, err_b)
        if values and rc_b == 0:
            # The bake's output may not depend on the thread count (issue 12).
            args = ["bake", name, "-o", "one.usdc", "-q", *frames]
            rc_1, err_1, _ = run(exe, args, d, env={**os.environ, "RAYON_NUM_THREADS": "1"})
            judge("bake on one thread", rc_1, err_1)
            if rc_1 == 0 and (d / "one.usdc").read_bytes() != (d / "out.usdc").read_bytes():
                problems.append("bake on one thread wrote other bytes than on all threads")
        # A stage with nothing painterly in it is not wrong (inspect passes),
        # but bake refuses it: "nothing to bake".
        if vouched and rc_i == 0 and rc_b not in (0, None) and rc_b != "timeout" and "nothing to bake" not in err_b:
            first = err_b.strip().splitlines()[:1]
            trust.append(f"inspect passed but bake exited {rc_b}: {first}")
    t_e, written, edit, data_changed_ok = 0.0, None, None, False
    if meta is not None:
        # A case's own stream picks the edit, after the mutation, so that
        # the default run's cases are the same with and without --edits.
        edit_rng = random.Random(f"{seed}:{k}:edit")
        if keys and edit_rng.random() < 0.5:
            args, in_place = key_command(edit_rng, name, meta.get(name, {}))
        else:
            args, in_place = edit_command(edit_rng, name, meta.get(name, {}))
        rc_e, err_e, t_e = run(exe, args, d)
        what = " ".join(a for a in args if a not in (name, "-q"))
        edit = (" ".join(args[:1] + [a for a in args if a in ("--in-place", "--edit-layer", "--time-key", "--sentinel")]),
                rc_e)
        judge(what, rc_e, err_e)
        err_b += err_e
        after = src.read_bytes()
        if (rc_e != 0 or not in_place) and after != data:
            problems.append(f"{what} exited {rc_e} and changed its input")
        if in_place and rc_e == 0:
            rc_a, err_a, _ = run(exe, ["inspect", name, *frames], d)
            judge(f"inspect after {what}", rc_a, err_a)
            if rc_i == 0 and rc_a != 0:
                first = err_a.strip().splitlines()[:1]
                trust.append(f"inspect passed, {what} succeeded, then inspect exited {rc_a}: {first}")
            written = (args, after)
        elif rc_e == 0 and (d / "edits.usda").exists():
            written = (args, (d / "edits.usda").read_bytes())
        data_changed_ok = in_place and rc_e == 0
    left = [n for n in os.listdir(d) if ".painterly-" in n]
    if left:
        problems.append(f"left temporaries {left}")
    if src.read_bytes() != data and not data_changed_ok:
        problems.append("input changed")
    # Only a failing case keeps its bytes and stderr: every finished future
    # stays referenced until the run ends, and 100,000 cases' worth made the
    # driver slow (garbage collection over gigabytes) and big.
    failed = bool(problems or trust)
    result = (k, name, rc_i, rc_b, max(t_i, t_b, t_e), problems, trust,
              err_i + err_b if failed else "", data if failed else b"", (data, written) if written else None, edit)
    shutil.rmtree(d, ignore_errors=True)
    return result


# Opens each written case in usd-core: when it opens the input, it must
# open what painterly wrote, edit it and save it in place. Prints one JSON
# object: case directory name -> the problem.
USD_CHECK_CODE = """
import json, pathlib, sys
from pxr import Sdf, Usd
bad = {}
for case in map(pathlib.Path, sys.argv[1:]):
    spec = json.loads((case / "case.json").read_text())
    try:
        Usd.Stage.Open(str(case / "orig" / spec["name"]))
    except Exception:
        continue  # usd-core rejects the input too: nothing to compare
    root = case / "edit" / spec["root"]
    try:
        stage = Usd.Stage.Open(str(root))
        layer = stage.GetRootLayer()
        Sdf.CreatePrimInLayer(layer, "/FuzzCheckEdit")
        if not layer.Save():
            raise RuntimeError("Save() returned False")
        again = Sdf.Layer.OpenAsAnonymous(str(root))
        if again is None or not again.GetPrimAtPath("/FuzzCheckEdit"):
            raise RuntimeError("the edit saved in place is not in the file read back")
    except Exception as e:
        bad[case.name] = f"usd-core opens the input but not what painterly wrote: {str(e).strip()[:300]}"
print(json.dumps(bad))
"""


def usd_check(batch):
    """Runs USD_CHECK_CODE over the case folders in `batch` (a folder)."""
    cases = sorted(str(c) for c in batch.iterdir())
    if not cases:
        return {}
    r = subprocess.run([venv_python(), "-c", USD_CHECK_CODE, *cases], capture_output=True, text=True)
    if r.returncode == 0:
        return json.loads(r.stdout.strip().splitlines()[-1])
    # usd-core itself can crash on a mutated input (seed 20261208, case
    # 12,954: a segmentation fault opening it). Each case alone, then: a
    # crash on the input is usd-core's and skipped; one on what painterly
    # wrote, when usd-core opens the input, is a failure.
    bad = {}
    for c in cases:
        r = subprocess.run([venv_python(), "-c", USD_CHECK_CODE, c], capture_output=True, text=True)
        if r.returncode == 0:
            bad.update(json.loads(r.stdout.strip().splitlines()[-1]))
            continue
        spec = json.loads((pathlib.Path(c) / "case.json").read_text())
        orig = subprocess.run([venv_python(), "-c", "import sys; from pxr import Usd; Usd.Stage.Open(sys.argv[1])",
                               str(pathlib.Path(c) / "orig" / spec["name"])], capture_output=True, text=True)
        if orig.returncode in (0, 1):
            bad[pathlib.Path(c).name] = (f"usd-core opens the input but crashes (exit {r.returncode}) on what "
                                         f"painterly wrote: {r.stderr.strip()[-300:]}")
    return bad


def stash_written(batch, k, name, data, written):
    """Keeps a written case for usd_check: orig/NAME (the mutated input),
    edit/ (what the edit left: the file edited in place, or the input and
    its edit layer)."""
    args, out = written
    case = batch / f"c{k}"
    (case / "orig").mkdir(parents=True)
    (case / "edit").mkdir()
    (case / "orig" / name).write_bytes(data)
    if "--edit-layer" in args:
        (case / "edit" / name).write_bytes(data)
        (case / "edit" / "edits.usda").write_bytes(out)
        root = "edits.usda"
    else:
        (case / "edit" / name).write_bytes(out)
        root = name
    (case / "case.json").write_text(json.dumps({"name": name, "root": root, "args": args}))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0,
                    help="index of the first case (a long run can be split: --first 40000 continues one)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--keep", default=str(REPO / "target" / "fuzz-failures"))
    ap.add_argument("--bin", default=os.environ.get("PAINTERLY_BIN", str(REPO / "target/release/painterly")))
    ap.add_argument("--edits", action="store_true",
                    help="also run one writing command per case (bind, expand, smudge, key, render)")
    ap.add_argument("--values", action="store_true",
                    help="mutate only values of the text fixtures (the file stays parseable); some go to crate")
    ap.add_argument("--keys", action="store_true",
                    help="mutate the structure of painterly's prims (keys, axes, view keys); some go to crate")
    a = ap.parse_args()
    if a.values and a.keys:
        ap.error("--values and --keys are two modes: pass one")
    if (a.edits or a.values or a.keys) and not venv_python():
        sys.exit("fuzz: --edits, --values and --keys need .venv (usd-core): run scripts/test once")
    exe = str(pathlib.Path(a.bin).resolve())
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="painterly-fuzz-") as tmp:
        work = pathlib.Path(tmp)
        seed_files = seeds(work)
        meta = seeds_meta() if a.edits else None
        # --values, --keys: the text fixtures' bytes, read once (blowfish.usda is 1.6 MB).
        names = VALUE_FIXTURES if a.values else KEY_FIXTURES if a.keys else []
        value_files = {n: (REPO / "fixtures" / n).read_bytes() for n in names} if names else None
        batch = work / "written"
        batch.mkdir()
        failures, trusts, slowest, exits, checked, edits = [], [], (0.0, None), {}, 0, {}
        stashed = 0  # written cases in `batch`, not yet checked

        def keep_failure(k, name, data, err, problems):
            failures.append(k)
            keep = pathlib.Path(a.keep) / f"seed{a.seed}-case{k}"
            keep.mkdir(parents=True, exist_ok=True)
            (keep / name).write_bytes(data)
            (keep / "stderr.txt").write_text(err)
            (keep / "problems.txt").write_text("\n".join(problems) + "\n")
            print(f"FAIL case {k} ({name}): {'; '.join(problems)}", flush=True)

        def check_batch():
            nonlocal checked, stashed
            for case, problem in usd_check(batch).items():
                spec = json.loads((batch / case / "case.json").read_text())
                k = int(case[1:])
                keep_failure(k, spec["name"], (batch / case / "orig" / spec["name"]).read_bytes(), "",
                             [f"{' '.join(spec['args'])}: {problem}"])
                shutil.copytree(batch / case / "edit", pathlib.Path(a.keep) / f"seed{a.seed}-case{k}" / "written")
            checked += stashed
            stashed = 0
            shutil.rmtree(batch)
            batch.mkdir()

        with cf.ThreadPoolExecutor(a.jobs) as pool:
            # No list of the futures is kept here: as_completed lets go of
            # each one it yields, and with it the bytes of a written case
            # (a kept list held every written blowfish case, 1.8 GB by
            # case 7,000 of a --values run, and slowed the driver).
            done = cf.as_completed([pool.submit(check, exe, a.seed, k, seed_files, work, meta, value_files, a.keys)
                                    for k in range(a.first, a.first + a.cases)])
            for n, f in enumerate(done, 1):
                k, name, rc_i, rc_b, t, problems, trust, err, data, written, edit = f.result()
                if edit:
                    edits[edit] = edits.get(edit, 0) + 1
                if written:
                    stash_written(batch, k, name, *written)
                    stashed += 1
                    if stashed >= 200:
                        check_batch()
                slowest = max(slowest, (t, k), key=lambda s: s[0])
                exits[(rc_i, rc_b)] = exits.get((rc_i, rc_b), 0) + 1
                if trust:
                    trusts.append(k)
                    problems = problems + trust
                if problems:
                    keep_failure(k, name, data, err, problems)
                if n % 1000 == 0:
                    print(f"{n}/{a.cases} cases, {len(failures)} failures, {len(trusts)} trust, "
                          f"{time.monotonic() - started:.0f} s", flush=True)
            check_batch()
    took = time.monotonic() - started
    summary = ", ".join(f"inspect {i}/bake {b}: {c}" for (i, b), c in sorted(exits.items(), key=str))
    print(f"fuzz: {a.cases} {'value-mutated ' if a.values else 'key-mutated ' if a.keys else ''}cases ({a.first}..{a.first + a.cases - 1} of seed {a.seed}, {a.jobs} jobs) in {took:.1f} s; "
          f"{len(failures)} failures; {len(trusts)} inspect-0/bake-1 (trust); slowest run {slowest[0]:.2f} s (case {slowest[1]})")
    print(f"exit codes: {summary}")
    if a.edits:
        print("edits (command: exits 0 / 1 / other): " + ", ".join(
            f"{c}: {edits.get((c, 0), 0)} / {edits.get((c, 1), 0)} / "
            f"{sum(n for (c2, rc), n in edits.items() if c2 == c and rc not in (0, 1))}"
            for c in sorted({c for c, _ in edits})))
        print(f"edits: {checked} written files checked with usd-core")
    sys.exit(min(len(failures), 100))


if __name__ == "__main__":
    main()
