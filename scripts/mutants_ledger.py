#!/usr/bin/env python3
"""The ledger of the full mutation run (scripts/mutants_full).

docs/mutants_ledger.jsonl holds one JSON line per finished unit (a source
file, or shard K of N of one): the commit it ran at, the pytest files it
ran, how many mutants were caught and unviable, and the names of those
missed and timed out. It is committed, so a run resumes on any clone; the
last line of a unit wins. A unit's result stands while its source file is
unchanged since that commit.

    mutants_ledger.py record UNIT_DIR   # append the unit that ran in UNIT_DIR
    mutants_ledger.py standing          # "FILE K N COMMIT" of every unit whose result stands
    mutants_ledger.py report PLAN       # PLAN: "FILE K N COUNT" lines; a Markdown table and the misses
"""

import fcntl
import json
import os
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


def record(unit_dir):
    f, k, n = open(os.path.join(unit_dir, "unit")).read().split()
    out = os.path.join(unit_dir, "mutants.out")
    outcomes = json.load(open(os.path.join(out, "outcomes.json")))
    entry = {
        "file": f,
        "k": int(k),
        "n": int(n),
        "commit": open(os.path.join(unit_dir, "commit")).read().strip(),
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "pytest": open(os.path.join(unit_dir, "pytest")).read().split(),
        "caught": outcomes["caught"],
        "unviable": outcomes["unviable"],
        "missed": lines(os.path.join(out, "missed.txt")),
        "timeout": lines(os.path.join(out, "timeout.txt")),
    }
    # Lanes finish units at the same time: one appender at a time.
    with open(LEDGER, "a") as ledger:
        fcntl.flock(ledger, fcntl.LOCK_EX)
        ledger.write(json.dumps(entry, sort_keys=True) + "\n")


def entries():
    last = {}
    for l in lines(LEDGER):
        e = json.loads(l)
        last[(e["file"], e["k"], e["n"])] = e
    return last


def stands(e):
    """Whether the entry's source file is unchanged from its commit to the work tree."""
    known = subprocess.run(["git", "cat-file", "-e", e["commit"]], capture_output=True)
    if known.returncode != 0:
        return False
    same = subprocess.run(["git", "diff", "--quiet", e["commit"], "--", e["file"]])
    return same.returncode == 0


def standing():
    for (f, k, n), e in sorted(entries().items()):
        if stands(e):
            print(f, k, n, e["commit"][:12])


def report(plan_path):
    last = entries()
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
        commits.add(e["commit"][:12])
        r["done"] += 1
        r["caught"] += e["caught"]
        r["unviable"] += e["unviable"]
        r["missed"] += len(e["missed"])
        r["timeout"] += len(e["timeout"])
        missed += e["missed"]
        timeouts += e["timeout"]
    print("| file | mutants | units done | caught | missed | timeouts | unviable |")
    print("|---|---|---|---|---|---|---|")
    tot = defaultdict(int)
    for f in sorted(rows):
        r = rows[f]
        print(f"| `{f}` | {r['total']} | {r['done']}/{r['units']} | {r['caught']} | {r['missed']} | {r['timeout']} | {r['unviable']} |")
        for key, v in r.items():
            tot[key] += v
    print(f"| **all** | {tot['total']} | {tot['done']}/{tot['units']} | {tot['caught']} | {tot['missed']} | {tot['timeout']} | {tot['unviable']} |")
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
    for title, names in (("Missed", missed), ("Timed out", timeouts)):
        if names:
            print(f"\n{title}:")
            for m in names:
                print("  " + m)


if __name__ == "__main__":
    cmd = sys.argv[1:2]
    if cmd == ["record"] and len(sys.argv) == 3:
        record(sys.argv[2])
    elif cmd == ["standing"] and len(sys.argv) == 2:
        standing()
    elif cmd == ["report"] and len(sys.argv) == 3:
        report(sys.argv[2])
    else:
        sys.exit(__doc__)
