"""Pool several runs of `scripts/check_simulation.py --json` (other seeds, or other matchups):
each player's statistics' mean gap to the truth over the runs, its standard error and z.

    .venv/bin/python scripts/pool_checks.py RUN.json [RUN.json ...]

One check compares 500 simulated points a server with a 3,000-point truth, and a right
simulator (the generator itself) misses about one statistic in sixty of the tolerances
(`eval.check_noise`). Over several seeds the mean gap tells a bias from the truth's draw: a
statistic whose mean gap is outside its tolerance with |z| over 3 is the model's, not the
seed's. Runs written before the checks recorded their noise are refused by name.
"""

from __future__ import annotations

import argparse

from sportsngen.errors import ArgumentError
from sportsngen.eval.check_noise import format_pooled, pool_gaps, read_noise_runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="check_simulation.py --json files")
    args = ap.parse_args()
    try:
        pooled = pool_gaps(read_noise_runs(args.runs))
    except ArgumentError as exc:
        raise SystemExit(str(exc)) from None
    print(f"{len(args.runs)} runs; mean gap (sim - truth) ± its standard error, z; "
          "* outside tolerance, ! a bias (|z| over 3) outside tolerance")
    print(format_pooled(pooled))


if __name__ == "__main__":
    main()
