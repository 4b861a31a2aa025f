"""Hawk-Eye ball statistics of generated play (or of real keypoint files) against the real
figures of ``../shared/data/hawkeye`` (Hawk-Eye keypoints, AO 2020 and RG 2019-2020, via
CourtVision).

    python scripts/hawkeye_report.py --points 2000 --seed 0 --out /tmp/hawkeye
        # the README's matchups, generated one after another (~20 s each for 2,000 points)
    python scripts/hawkeye_report.py --keypoints DIR --out /tmp/hawkeye_real
        # real files in the ryurko/hawkeye layout (`sportsngen.data.keypoints`)

Writes ``<out>.md`` (a table: statistics by group, "generated / real", bold outside the
README's tolerance) and ``<out>.csv`` (`sportsngen.eval.hawkeye.compare`'s columns), and prints
the statistics outside tolerance. ``--before CSV`` (an earlier run's csv; generator version
5's figures are kept in ``docs/figures/hawkeye_generator_v5.csv``) adds them in brackets.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from sportsngen.data.paths import HAWKEYE_TARGETS_MISSING, hawkeye_targets_path
from sportsngen.eval.hawkeye import comparison_markdown, keypoint_strikes
from sportsngen.eval.hawkeye_report import (
    README_GROUPS,
    generated_strikes,
    hawkeye_report,
    outside_tolerance,
)

# The files' names of the README's players -> the names of the figures and the profiles.
FILE_NAMES = {"R.FEDERER": "Roger Federer", "R.NADAL": "Rafael Nadal",
              "N.DJOKOVIC": "Novak Djokovic", "A.MURRAY": "Andy Murray",
              "S.WILLIAMS": "Serena Williams", "M.SHARAPOVA": "Maria Sharapova"}


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
    if hawkeye_targets_path() is None:
        print(HAWKEYE_TARGETS_MISSING, file=sys.stderr)
        return 2
    if args.keypoints is not None:
        from sportsngen.data.keypoints import read_keypoints

        strikes = keypoint_strikes(read_keypoints(args.keypoints, player_names=FILE_NAMES,
                                                  progress=True))
        source = f"real keypoint files under {args.keypoints}"
    else:
        strikes = generated_strikes(args.points, args.seed, progress=True)
        source = f"{args.points} generated points per matchup, seed {args.seed}"
    stats, cmp = hawkeye_report(strikes, groups=README_GROUPS)
    title = args.title or f"Hawk-Eye statistics: {source} / real"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cmp.to_csv(args.out.with_suffix(".csv"), index=False)
    before = pd.read_csv(args.before) if args.before is not None else None
    args.out.with_suffix(".md").write_text(comparison_markdown(cmp, title, before=before))
    off = outside_tolerance(cmp)
    print(f"{len(off)} of {int(cmp['within'].notna().sum())} comparisons outside tolerance:")
    for _, r in off.iterrows():
        print(f"  {r['player']:>15} {r['surface']:<5} {r['statistic']:<32} "
              f"gen {r['generated']:8.3f}  real {r['real']:8.3f}  diff {r['difference']:+.3f} "
              f"(tol {r['tolerance']:g}, excess {r['excess']:.3f})")
    print(f"wrote {args.out.with_suffix('.md')} and {args.out.with_suffix('.csv')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
