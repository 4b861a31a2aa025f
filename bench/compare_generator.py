"""Generation speed of two revisions side by side, in one run (this machine's speed drifts 2-5x
between runs, so only timings taken together compare).

    python bench/compare_generator.py --base 3bc30ae [--head WORKTREE] [--points 1000] [--repeats 3]

Each revision is exported (`git archive`) to a temporary folder; `generate_matches` of the
README's five matchups (Federer v Nadal and Djokovic v Murray on hard and clay, Serena Williams v
Sharapova on hard), `--points` each, seed 0, one process, runs in a fresh child process with
that folder first on the path, the two revisions alternating, `--repeats` times; the best time
of each counts. `--head` defaults to the working tree (uncommitted changes included).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from sportsngen.eval.hawkeye_report import README_MATCHUPS as MATCHUPS

ROOT = Path(__file__).resolve().parents[1]
_CHILD = """
import json, sys, time
from sportsngen.synth import generate_matches
n = int(sys.argv[1]); out = {"points": 0, "rallies": 0, "s": 0.0}
for pair, surface in json.loads(sys.argv[2]):
    t = time.perf_counter()
    d = generate_matches([tuple(pair)], surface, n, seed=0)
    out["s"] += time.perf_counter() - t
    out["points"] += n; out["rallies"] += len(d.rallies)
print(json.dumps(out))
"""


def export(rev: str, into: Path) -> Path:
    """The tree of `rev` (a commit) unpacked into `into`."""
    into.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "sportsngen"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def time_once(tree: Path, n_points: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    res = subprocess.run([sys.executable, "-c", _CHILD, str(n_points), json.dumps(MATCHUPS)],
                         env=env, check=True, capture_output=True, text=True, cwd=tree)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the older revision (a commit)")
    ap.add_argument("--head", default=None, help="the newer revision (default: working tree)")
    ap.add_argument("--points", type=int, default=1000, help="points per matchup")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"base": export(args.base, Path(tmp) / "base"),
                 "head": export(args.head, Path(tmp) / "head") if args.head else ROOT}
        best: dict[str, dict] = {}
        for r in range(args.repeats):
            for name, tree in trees.items():
                out = time_once(tree, args.points)
                print(f"repeat {r}: {name}: {out['s']:.1f} s for {out['points']} points "
                      f"({out['rallies']} rallies)", flush=True)
                if name not in best or out["s"] < best[name]["s"]:
                    best[name] = out
    b, h = best["base"], best["head"]
    print(f"best of {args.repeats}: base {args.base} {b['points'] / b['s']:.0f} points/s, "
          f"head {args.head or 'working tree'} {h['points'] / h['s']:.0f} points/s; "
          f"head takes {h['s'] / b['s']:.2f}x the base's time")


if __name__ == "__main__":
    main()
