"""Match speed of two revisions side by side, in one run (this machine's speed drifts 2-5x
between runs, so only timings taken together compare).

    python bench/compare_sim.py --base ec091c8 [--head WORKTREE] [--best-of 1 --games 2]
        [--seeds 0 1] [--repeats 1]

Each revision is exported (`git archive`, `compare_generator.export`); in a fresh child process
with that folder first on the path, the bundled model plays Roger Federer v Rafael Nadal on
hard (`Simulator.simulate_matches`, one match, one rally at a time as a match plays) for each
seed, the two revisions alternating. Reported per revision and seed: the best wall time, the
points, the frames simulated (every rally's, set-aside ones included) and frames a second,
and the score line, so a reader sees whether the two revisions played the same match.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compare_generator import export  # noqa: E402

_CHILD = """
import json, sys, time
import torch
from sportsngen.sim.simulator import Simulator
from sportsngen.tennis.scoring import MatchFormat
best_of, games, seed = (int(a) for a in sys.argv[1:4])
sim = Simulator.from_pretrained()
fmt = MatchFormat(best_of=best_of, games_per_set=games, tiebreak_at=games)
t = time.perf_counter()
res = sim.simulate_matches([("Roger Federer", "Rafael Nadal")], "hard", fmt=fmt, seed=seed,
                           progress=False)[0]
s = time.perf_counter() - t
frames = len(res.rallies.frames) // 3
if res.discarded is not None:
    frames += len(res.discarded.frames) // 3
print(json.dumps({"s": s, "points": len(res.points), "frames": frames,
                  "score": res.score_line}))
"""


def time_once(tree: Path, best_of: int, games: int, seed: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    res = subprocess.run([sys.executable, "-c", _CHILD, str(best_of), str(games), str(seed)],
                         env=env, check=True, capture_output=True, text=True, cwd=tree)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the older revision (a commit)")
    ap.add_argument("--head", default=None, help="the newer revision's tree (default: this one)")
    ap.add_argument("--best-of", type=int, default=1)
    ap.add_argument("--games", type=int, default=2, help="games a set")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"base " + args.base: export(args.base, Path(tmp) / "base"),
                 "head": Path(args.head) if args.head else Path(__file__).resolve().parents[1]}
        best: dict = {}
        for seed in args.seeds:
            for _ in range(args.repeats):
                for name, tree in trees.items():
                    r = time_once(tree, args.best_of, args.games, seed)
                    key = (name, seed)
                    if key not in best or r["s"] < best[key]["s"]:
                        best[key] = r
        print(f"best of {args.best_of}, {args.games} games a set, Federer v Nadal on hard, "
              f"best of {args.repeats} run(s)")
        print("| revision | seed | wall s | points | frames | frames/s | score |")
        print("|---|---:|---:|---:|---:|---:|---|")
        for (name, seed), r in best.items():
            print(f"| {name} | {seed} | {r['s']:.1f} | {r['points']} | {r['frames']} | "
                  f"{r['frames'] / r['s']:.0f} | {r['score']} |")


if __name__ == "__main__":
    main()
