"""The checks' ceiling: the generator itself, run as the simulator, against each check's truth.

    .venv/bin/python scripts/check_ceiling.py [--samples 3] [--points 500] [--truth-points 3000]

For the eight checks of docs/evaluation.md: each truth as `check_simulation.py` generates it,
against `--samples` other generator samples of `--points` points a server, the same statistics
and tolerances (`sportsngen.studies.ceiling`). Prints, per pair, how many of the twelve fall
within tolerance, how many `eval.check_noise` expected, and the mean square of the pairs'
z-scores (1 where the standard errors are right). About 6 minutes on 2 cores.
"""

from __future__ import annotations

import argparse

from sportsngen.studies.ceiling import check_ceiling


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=3)
    ap.add_argument("--points", type=int, default=500, help="generated points a server")
    ap.add_argument("--truth-points", type=int, default=3000)
    check_ceiling(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
