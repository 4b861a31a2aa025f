"""Hawk-Eye ball statistics of generated play (or of real keypoint files) against the real
figures of ``../shared/data/hawkeye`` (Hawk-Eye keypoints, AO 2020 and RG 2019-2020, via
CourtVision).

    python scripts/hawkeye_report.py --points 2000 --seed 0 --out /tmp/hawkeye
        # the README's matchups, generated one after another (~20 s each for 2,000 points)
    python scripts/hawkeye_report.py --keypoints DIR --out /tmp/hawkeye_real
        # real files in the ryurko/hawkeye layout (`sportsngen.data.keypoints`)

Writes ``<out>.md`` and ``<out>.csv`` and prints the statistics outside tolerance
(`sportsngen.eval.hawkeye_report.write_hawkeye_report`); ``--before CSV`` (an earlier run's,
e.g. ``docs/figures/hawkeye_generator_v5.csv``) adds its figures in brackets.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sportsngen.eval.hawkeye_report import write_hawkeye_report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2000, help="generated points per matchup")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first matchup (+1 each)")
    ap.add_argument("--out", type=Path, required=True, help="output path without suffix")
    ap.add_argument("--keypoints", type=Path, help="measure real keypoint files instead")
    ap.add_argument("--title", default=None, help="title of the markdown table")
    ap.add_argument("--before", type=Path, default=None,
                    help="an earlier run's csv: its figures in brackets (italic if outside)")
    args = ap.parse_args(argv)
    return write_hawkeye_report(args.out, args.points, args.seed, args.keypoints, args.title,
                                args.before)


if __name__ == "__main__":
    sys.exit(main())
