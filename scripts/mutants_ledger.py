#!/usr/bin/env python3
"""The ledger of the full mutation run (scripts/mutants_full).

docs/mutants_ledger.jsonl holds one JSON line per finished unit (a source
file, or shard K of N of one): the commit it ran at, the pytest files it
ran, how many mutants were caught and unviable, and the names of those
missed and timed out. It is committed, so a run resumes on any clone; the
last line of a unit wins. A recheck line records a later run of a file's
missed mutants alone (the tests written for them): the names it caught are
no longer missed.

A line stands while its file's mutable code is unchanged since its commit:
the file's text without its trailing `#[cfg(test)] mod` (cargo-mutants
never mutates test code, and tests added there only grow), so a test
written for a miss leaves the file's units standing.

docs/mutants_reasons.txt gives each miss no test kills its written reason:
a line with the mutant's name as cargo-mutants prints it, then the reason
on indented lines.

    mutants_ledger.py record UNIT_DIR   # append the unit that ran in UNIT_DIR
    mutants_ledger.py recheck UNIT_DIR  # append a recheck of missed mutants that ran in UNIT_DIR
    mutants_ledger.py standing          # "FILE K N COMMIT" of every unit whose result stands
    mutants_ledger.py missed FILE       # the file's standing misses no recheck has caught, one per line
    mutants_ledger.py report PLAN       # PLAN: "FILE K N COUNT" lines; a Markdown table and the misses
"""

import fcntl
import json
import os
import re
import subprocess
import sys
from collections import defaultdict
from datetime import datetime, timezone

# Run from the repository's top (scripts/mutants_full cds there).
LEDGER = os.environ.get("PAINTERLY_MUTANTS_LEDGER", os.path.join("docs", "mutants_ledger.jsonl"))


def lines(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [l.rstrip("\n") for l in f if l.strip()]


REASONS = os.environ.get("PAINTERLY_MUTANTS_REASONS", os.path.join("docs", "mutants_reasons.txt"))


def reasons():
    """Mutant name -> its written reason (docs/mutants_reasons.txt)."""
    out, name = {}, None
    for l in lines(REASONS):
        if l.startswith("#"):
            continue
        if l[:1].isspace():
            if name is None:
                sys.exit(f"{REASONS}: a reason before any mutant name: {l.strip()}")
            out[name] = (out[name] + " " + l.strip()).strip()
        else:
            name = l.strip()
            out[name] = ""
    for name, why in out.items():
        if not why:
            sys.exit(f"{REASONS}: no reason under {name}")
    return out


def append(entry):
    # Lanes finish units at the same time: one appender at a time.
    with open(LEDGER, "a") as ledger:
        fcntl.flock(ledger, fcntl.LOCK_EX)
        ledger.write(json.dumps(entry, sort_keys=True) + "\n")


def ran(unit_dir):
    """What a unit or recheck folder says of its run: file, commit, pytest files, misses."""
    out = os.path.join(unit_dir, "mutants.out")
    return {
        "file": open(os.path.join(unit_dir, "unit")).read().split()[0],
        "commit": open(os.path.join(unit_dir, "commit")).read().strip(),
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "pytest": open(os.path.join(unit_dir, "pytest")).read().split(),
        "missed": lines(os.path.join(out, "missed.txt")),
        "timeout": lines(os.path.join(out, "timeout.txt")),
    }


def recheck(unit_dir):
    caught = lines(os.path.join(unit_dir, "mutants.out", "caught.txt"))
    append({**ran(unit_dir), "recheck": True, "caught": caught})


def record(unit_dir):
    _, k, n = open(os.path.join(unit_dir, "unit")).read().split()
    outcomes = json.load(open(os.path.join(unit_dir, "mutants.out", "outcomes.json")))
    append({**ran(unit_dir), "k": int(k), "n": int(n), "caught": outcomes["caught"], "unviable": outcomes["unviable"]})


def entries():
    last = {}
    for l in lines(LEDGER):
        e = json.loads(l)
        if not e.get("recheck"):
            last[(e["file"], e["k"], e["n"])] = e
    return last


def killed():
    """File -> names of its mutants that a standing recheck caught."""
    out = defaultdict(set)
    for l in lines(LEDGER):
        e = json.loads(l)
        if e.get("recheck") and stands(e):
            out[e["file"]].update(e["caught"])
    return out


def block_end(text, i):
    """Index just past the `}` closing the `{` at text[i], skipping braces
    in comments, strings, raw strings and char literals; None if unclosed."""
    depth, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            i = text.find("\n", i)
            if i < 0:
                return None
        elif text.startswith("/*", i):
            nest, i = 1, i + 2
            while nest and i < n:
                if text.startswith("/*", i):
                    nest, i = nest + 1, i + 2
                elif text.startswith("*/", i):
                    nest, i = nest - 1, i + 2
                else:
                    i += 1
            continue
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (text[i - 1].isalnum() or text[i - 1] == "_"):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            close = text.find('"' + hashes, i + len(hashes) + 2)
            if close < 0:
                return None
            i = close + len(hashes) + 1
            continue
        elif c == '"':
            i += 1
            while i < n and text[i] != '"':
                i += 2 if text[i] == "\\" else 1
        elif c == "'":
            # A char literal ('x', '\n', '\u{..}'); otherwise a lifetime.
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", text[i:])
            if m:
                i += len(m.group(0))
                continue
        elif c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
            if depth == 0:
                return i + 1
        i += 1
    return None


def mutable_code(text):
    """The text cargo-mutants mutates: without a trailing `#[cfg(test)] mod`.

    The module is stripped only when it is the file's last item: its
    closing brace (found past comments and string literals) is followed by
    nothing but blank space. Anything else is kept whole.
    """
    for m in re.finditer(r"^#\[cfg\(test\)\]\n(pub(\([a-z]+\))? )?mod \w+ \{$", text, re.M):
        end = block_end(text, m.end() - 1)
        if end is not None and not text[end:].strip():
            return text[: m.start()].rstrip() + "\n"
    return text


_code_cache = {}


def stands(e):
    """Whether the entry's file has the same mutable code at its commit and in the work tree."""
    key = (e["commit"], e["file"])
    if key not in _code_cache:
        then = subprocess.run(["git", "show", f"{e['commit']}:{e['file']}"], capture_output=True, text=True)
        _code_cache[key] = mutable_code(then.stdout) if then.returncode == 0 else None
    if _code_cache[key] is None or not os.path.exists(e["file"]):
        return False
    with open(e["file"]) as now:
        return mutable_code(now.read()) == _code_cache[key]


def missed(f):
    """The file's standing misses that no standing recheck caught and no
    written reason explains: what a recheck runs again."""
    gone, why = killed()[f], reasons()
    for (g, _, _), e in sorted(entries().items()):
        if g == f and stands(e):
            for m in e["missed"] + e["timeout"]:
                if m not in gone and m not in why:
                    print(m)


def standing():
    for (f, k, n), e in sorted(entries().items()):
        if stands(e):
            print(f, k, n, e["commit"][:12])


def report(plan_path):
    last = entries()
    caught_since = killed()
    rows = defaultdict(lambda: defaultdict(int))
    missed, timeouts, commits, stale = [], [], set(), []
    for l in lines(plan_path):
        f, k, n, count = l.split()
        r = rows[f]
        r["total"], r["units"] = int(count), int(n)
        e = last.get((f, int(k), int(n)))
        if e is None:
            continue
        if not stands(e):
            stale.append(e)
            continue
        gone = caught_since[f]
        commits.add(e["commit"][:12])
        r["done"] += 1
        r["caught"] += e["caught"]
        r["unviable"] += e["unviable"]
        r["missed"] += len(e["missed"])
        r["timeout"] += len(e["timeout"])
        r["killed"] += sum(m in gone for m in e["missed"] + e["timeout"])
        missed += [m for m in e["missed"] if m not in gone]
        timeouts += [m for m in e["timeout"] if m not in gone]
    why = reasons()
    for m in missed + timeouts:
        if m in why:
            rows[m.split(":")[0]]["reasoned"] += 1
    print("| file | mutants | units done | caught | missed | timeouts | unviable | misses killed since | misses with a reason |")
    print("|---|---|---|---|---|---|---|---|---|")
    tot = defaultdict(int)
    for f in sorted(rows):
        r = rows[f]
        print(
            f"| `{f}` | {r['total']} | {r['done']}/{r['units']} | {r['caught']} | {r['missed']} | {r['timeout']} "
            f"| {r['unviable']} | {r['killed']} | {r['reasoned']} |"
        )
        for key, v in r.items():
            tot[key] += v
    print(
        f"| **all** | {tot['total']} | {tot['done']}/{tot['units']} | {tot['caught']} | {tot['missed']} | {tot['timeout']} "
        f"| {tot['unviable']} | {tot['killed']} | {tot['reasoned']} |"
    )
    tested = tot["caught"] + tot["missed"] + tot["timeout"] + tot["unviable"]
    print(f"\n{tested} of {tot['total']} mutants tested; commits: {', '.join(sorted(commits)) or 'none'}.")
    if stale:
        print("\nRecorded at a commit whose source file has changed since (to run again):")
        for e in stale:
            tested = e["caught"] + len(e["missed"]) + len(e["timeout"]) + e["unviable"]
            print(
                f"  {e['file']} {e['k'] + 1}/{e['n']} at {e['commit'][:12]}: {tested} tested, {e['caught']} caught, "
                f"{len(e['missed'])} missed, {len(e['timeout'])} timeouts, {e['unviable']} unviable"
            )
    open_ = [m for m in missed + timeouts if m not in why]
    listed = set(missed + timeouts)
    # Only for the files reported: another file's reasons wait for its units.
    unused = [m for m in why if m.split(":")[0] in rows and m not in listed]
    for title, names in (
        ("Missed or timed out, with neither a test that kills it nor a reason", open_),
        ("Reasons in " + REASONS + " for no standing miss (stale)", unused),
    ):
        if names:
            print(f"\n{title}:")
            for m in names:
                print("  " + m)


if __name__ == "__main__":
    cmd = sys.argv[1:2]
    if cmd == ["record"] and len(sys.argv) == 3:
        record(sys.argv[2])
    elif cmd == ["recheck"] and len(sys.argv) == 3:
        recheck(sys.argv[2])
    elif cmd == ["missed"] and len(sys.argv) == 3:
        missed(sys.argv[2])
    elif cmd == ["standing"] and len(sys.argv) == 2:
        standing()
    elif cmd == ["report"] and len(sys.argv) == 3:
        report(sys.argv[2])
    else:
        sys.exit(__doc__)
