"""Why serves go unreturned: the receiver's movement and reach on first serves, simulated
against the ground truth.

    .venv/bin/python scripts/diagnose_returns.py [--model PATH] [--points 150] [--seed 2]
        [--top-p-player P] [--top-p-ball P]

Federer serving to Nadal on hard (`sportsngen.eval.serve_returns.diagnose_returns`).
"""

from __future__ import annotations

import argparse

from sportsngen.eval.command_line import add_points_seed, add_simulator_options, simulator_from_args
from sportsngen.eval.serve_returns import diagnose_returns


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_simulator_options(ap)
    add_points_seed(ap, points=150, seed=2)
    args = ap.parse_args()
    diagnose_returns(simulator_from_args(ap, args), args.points, args.seed)


if __name__ == "__main__":
    main()
