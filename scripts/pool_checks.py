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
import json

import pandas as pd

from sportsngen.eval.check_noise import format_pooled, pool_gaps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="check_simulation.py --json files")
    args = ap.parse_args()
    noises = []
    for path in args.runs:
        with open(path) as fh:
            run = json.load(fh)
        if "noise" not in run:
            raise SystemExit(f"{path} holds no noise rows: re-run check_simulation.py on it")
        noises.append(pd.DataFrame(run["noise"]))
    pooled = pool_gaps(noises)
    print(f"{len(args.runs)} runs; mean gap (sim - truth) ± its standard error, z; "
          "* outside tolerance, ! a bias (|z| over 3) outside tolerance")
    print(format_pooled(pooled))


if __name__ == "__main__":
    main()
