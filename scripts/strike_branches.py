"""Where a model's serves go wrong: recorded serves branched before, at and after the strike.

    python scripts/strike_branches.py [--model PATH] [--points 300] [--seed 0]
        [--top-p-ball P] [--[no-]contact-odds] [--top-p-contact P] [--after -1 0 1 3]

Per branch point and serve number, the serves in the box, wide and returned, beside the
recorded (`sportsngen.eval.diagnostics.strike_branches`; Federer v Nadal on hard).
"""

from __future__ import annotations

import argparse

from sportsngen.eval.command_line import add_points_seed, add_simulator_options, simulator_from_args
from sportsngen.eval.diagnostics import DiagnosticsSetup, strike_branches, truth_points


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_simulator_options(ap, threads=1)
    add_points_seed(ap, points=300, seed=0)
    ap.add_argument("--after", type=int, nargs="+", default=[-1, 0, 1, 3])
    args = ap.parse_args()
    sim = simulator_from_args(ap, args)
    truth = truth_points(DiagnosticsSetup(n_points=args.points, seed=args.seed))
    table = strike_branches(sim, truth, tuple(args.after), seed=args.seed)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))


if __name__ == "__main__":
    main()
