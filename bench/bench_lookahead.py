"""One match with look-ahead off and on, side by side in one run: wall time, where the rallies
were played, and whether the two points tables and tracks are identical.

    python bench/bench_lookahead.py [--best-of 1 --games 6] [--seeds 1] [--workers 1]
        [--depth 2]

The bundled model plays Roger Federer v Rafael Nadal on hard (`Simulator.simulate_match`,
`lookahead=0` then `lookahead=workers`). The look-ahead's own counts (rallies played by the
calling process, taken from a worker, played ahead unused, seconds waiting) are logged by
`sportsngen.sim.lookahead`.
"""

from __future__ import annotations

import argparse
import logging
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--best-of", type=int, default=1)
    ap.add_argument("--games", type=int, default=6, help="games a set")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--depth", type=int, default=2)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from sportsngen.sim.simulator import Simulator
    from sportsngen.tennis.scoring import MatchFormat

    sim = Simulator.from_pretrained()
    fmt = MatchFormat(best_of=args.best_of, games_per_set=args.games, tiebreak_at=args.games)
    print("| seed | look-ahead | wall s | points | frames | score | identical |")
    print("|---:|---:|---:|---:|---:|---|---|")
    for seed in args.seeds:
        runs = {}
        for workers in (0, args.workers):
            t = time.perf_counter()
            runs[workers] = res = sim.simulate_match(
                "Roger Federer", "Rafael Nadal", "hard", fmt=fmt, seed=seed, progress=False,
                lookahead=workers, lookahead_depth=args.depth)
            s = time.perf_counter() - t
            same = "" if not workers else str(
                res.points.equals(runs[0].points)
                and res.rallies.frames.equals(runs[0].rallies.frames))
            print(f"| {seed} | {workers} | {s:.1f} | {len(res.points)} | "
                  f"{len(res.rallies.frames) // 3} | {res.score_line} | {same} |", flush=True)


if __name__ == "__main__":
    main()
