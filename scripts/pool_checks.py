"""Pool several runs of `scripts/check_simulation.py --json` (other seeds, or other matchups):
each player's statistics' mean gap to the truth over the runs, its standard error and z.

    .venv/bin/python scripts/pool_checks.py RUN.json [RUN.json ...]

Over several seeds the mean gap tells a bias from the truth's draw (`eval.check_noise`): a
statistic whose mean gap is outside its tolerance with |z| over 3 is the model's, not the seed's.
"""

from __future__ import annotations

import argparse

from sportsngen.errors import ArgumentError
from sportsngen.eval.check_noise import pooled_report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="check_simulation.py --json files")
    args = ap.parse_args()
    try:
        print(pooled_report(args.runs))
    except ArgumentError as exc:
        raise SystemExit(str(exc)) from None


if __name__ == "__main__":
    main()
