"""The simulation issue's acceptance figures: simulated service points against the generator.

    .venv/bin/python scripts/check_simulation.py [--model PATH] [--points 500] [--seed 0]
        [--top-p-player P] [--top-p-ball P] [... the sampling flags] [--refresh-frames K]
        [--json out.json] [--players "Roger Federer,Rafael Nadal"] [--surface hard]

What it prints: `sportsngen.eval.check_simulation`; `scripts/pool_checks.py` pools `--json`s.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.check_simulation import PLAYERS, SURFACES, check_simulation
from sportsngen.eval.command_line import add_points_seed, add_simulator_options, simulator_from_args


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_points_seed(ap, points=500, seed=0)
    ap.add_argument("--truth-points", type=int, default=3000)
    ap.add_argument("--refresh-frames", type=int, default=None,
                    help="past the model's window, re-fill the rollout cache from the last "
                         "window every this many frames (1: training's view every frame)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--players", default=",".join(PLAYERS),
                    help="the two players, comma-separated")
    ap.add_argument("--surface", default="hard", choices=SURFACES)
    add_simulator_options(ap)
    ap.add_argument("--save-sim", type=Path, default=None,
                    help="write the simulated rallies (a RallyData folder) here")
    ap.add_argument("--no-physical-limits", action="store_true",
                    help="free rollouts, as the paper (no redraws, no net/ground correction)")
    args = ap.parse_args()
    players = tuple(p.strip() for p in args.players.split(","))
    if len(players) != 2 or not all(players):
        ap.error(f"--players needs two names separated by a comma, got {args.players!r}")
    sim = simulator_from_args(ap, args, physical_limits=not args.no_physical_limits)
    check_simulation(sim, players, args.surface, args.points, args.truth_points, args.seed,
                     save_sim=args.save_sim, physical_limits=not args.no_physical_limits,
                     json_path=args.json)


if __name__ == "__main__":
    main()
