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
- a run leaves a temporary (`.painterly-`) file, or changes its input.

- inspect exits 0 but the default bake (no --frames) fails: inspect
  evaluates every frame of that bake, so it must find what bake finds (a
  "trust" failure). A stage without a complete frame range is baked with
  --frames 1:3 and not judged so: inspect has no frames to evaluate there;
  nor is a stage with nothing painterly in it (inspect finds nothing wrong,
  bake says "nothing to bake").

Usage: python3 scripts/fuzz.py --cases N --seed S [--first K] [--jobs J] [--keep DIR]
Failing inputs are copied to --keep (default target/fuzz-failures) with
their stderr; the exit status is the number of failures (capped at 100).
Cases are reproducible from (seed, case index).
"""

import argparse
import concurrent.futures as cf
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


def seeds(work):
    """Seed files: small fixtures as text, and each also as usd-core crate bytes."""
    names = ["static.usda", "building.usda", "tube.usda", "head.usda", "walk.usda", "fig4.usda"]
    out = []
    for n in names:
        p = REPO / "fixtures" / n
        if p.exists():
            out.append((n, p.read_bytes()))
    crate_dir = work / "seeds"
    crate_dir.mkdir(exist_ok=True)
    venv = [REPO / ".venv/bin/python", pathlib.Path("/work/main/.venv/bin/python")]
    py = next((str(v) for v in venv if v.exists()), None)
    if py:
        for n, _ in list(out)[:4]:
            dst = crate_dir / n.replace(".usda", ".usdc")
            code = ("from pxr import Sdf; import sys; l = Sdf.Layer.FindOrOpen(sys.argv[1]); "
                    "l.Export(sys.argv[2])")
            r = subprocess.run([py, "-c", code, str(REPO / "fixtures" / n), str(dst)], capture_output=True)
            if r.returncode == 0 and dst.exists():
                out.append((dst.name, dst.read_bytes()))
    return out


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


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(exe, args, cwd):
    t0 = time.monotonic()
    try:
        p = subprocess.run([exe, *args], capture_output=True, text=True, errors="replace", cwd=cwd,
                           timeout=TIMEOUT_S, preexec_fn=limit_memory)
        return p.returncode, p.stderr, time.monotonic() - t0
    except subprocess.TimeoutExpired:
        return "timeout", "", time.monotonic() - t0


def check(exe, seed, k, seed_files, work):
    rng = random.Random(f"{seed}:{k}")
    name, data = rng.choice(seed_files)
    data = mutate(rng, data, name.endswith(".usda"))
    d = work / f"c{k}"
    d.mkdir()
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
    rc_b, err_b, t_b = None, "", 0.0
    if rc_i == 0 or k % 4 == 0:
        # The default bake (the stage's range) is what inspect vouches for.
        rc_b, err_b, t_b = run(exe, ["bake", name, "-o", "out.usdc", "-q"], d)
        vouched = True
        if rc_b == 1 and "pass --frames" in err_b:
            # No complete range: bake needs --frames, and inspect evaluated no frame.
            rc_b, err_b, t_b = run(exe, ["bake", name, "-o", "out.usdc", "--frames", "1:3", "-q"], d)
            vouched = False
        judge("bake", rc_b, err_b)
        # A stage with nothing painterly in it is not wrong (inspect passes),
        # but bake refuses it: "nothing to bake".
        if vouched and rc_i == 0 and rc_b not in (0, None) and rc_b != "timeout" and "nothing to bake" not in err_b:
            first = err_b.strip().splitlines()[:1]
            trust.append(f"inspect passed but bake exited {rc_b}: {first}")
    left = [n for n in os.listdir(d) if ".painterly-" in n]
    if left:
        problems.append(f"left temporaries {left}")
    if src.read_bytes() != data:
        problems.append("input changed")
    # Only a failing case keeps its bytes and stderr: every finished future
    # stays referenced until the run ends, and 100,000 cases' worth made the
    # driver slow (garbage collection over gigabytes) and big.
    failed = bool(problems or trust)
    result = (k, name, rc_i, rc_b, max(t_i, t_b), problems, trust,
              err_i + err_b if failed else "", data if failed else b"")
    shutil.rmtree(d, ignore_errors=True)
    return result


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0,
                    help="index of the first case (a long run can be split: --first 40000 continues one)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--keep", default=str(REPO / "target" / "fuzz-failures"))
    ap.add_argument("--bin", default=os.environ.get("PAINTERLY_BIN", str(REPO / "target/release/painterly")))
    a = ap.parse_args()
    exe = str(pathlib.Path(a.bin).resolve())
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="painterly-fuzz-") as tmp:
        work = pathlib.Path(tmp)
        seed_files = seeds(work)
        failures, trusts, slowest, exits = [], [], 0.0, {}
        with cf.ThreadPoolExecutor(a.jobs) as pool:
            futs = [pool.submit(check, exe, a.seed, k, seed_files, work) for k in range(a.first, a.first + a.cases)]
            for n, f in enumerate(cf.as_completed(futs), 1):
                k, name, rc_i, rc_b, t, problems, trust, err, data = f.result()
                slowest = max(slowest, t)
                exits[(rc_i, rc_b)] = exits.get((rc_i, rc_b), 0) + 1
                if trust:
                    trusts.append(k)
                    problems = problems + trust
                if problems:
                    failures.append(k)
                    keep = pathlib.Path(a.keep) / f"seed{a.seed}-case{k}"
                    keep.mkdir(parents=True, exist_ok=True)
                    (keep / name).write_bytes(data)
                    (keep / "stderr.txt").write_text(err)
                    (keep / "problems.txt").write_text("\n".join(problems) + "\n")
                    print(f"FAIL case {k} ({name}): {'; '.join(problems)}", flush=True)
                if n % 1000 == 0:
                    print(f"{n}/{a.cases} cases, {len(failures)} failures, {len(trusts)} trust, "
                          f"{time.monotonic() - started:.0f} s", flush=True)
    took = time.monotonic() - started
    summary = ", ".join(f"inspect {i}/bake {b}: {c}" for (i, b), c in sorted(exits.items(), key=str))
    print(f"fuzz: {a.cases} cases ({a.first}..{a.first + a.cases - 1} of seed {a.seed}, {a.jobs} jobs) in {took:.1f} s; "
          f"{len(failures)} failures; {len(trusts)} inspect-0/bake-1 (trust); slowest run {slowest:.2f} s")
    print(f"exit codes: {summary}")
    sys.exit(min(len(failures), 100))


if __name__ == "__main__":
    main()
