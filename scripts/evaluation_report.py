"""docs/evaluation.md: SportsNGEN against the shot-cycle baseline and the ground truth.

    .venv/bin/python scripts/evaluation_report.py [--model PATH] [--points 150]
        [--truth-points 1500] [--seed 0] [--out docs]

Four matchups on hard: the generator's ground truth, the SportsNGEN simulator and the
shot-cycle model fitted on that truth, compared by the same code
(`sportsngen.studies.evaluation_report`). Also writes the full report of SportsNGEN against the
ground truth for Federer v Nadal into docs/figures/evaluation/, and the SportsNGEN rallies of
all four matchups into outputs/eval/sportsngen_sim (a RallyData folder for
scripts/render_style_graphs.py --simulated).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.studies.evaluation_report import evaluation_report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--points", type=int, default=150)
    ap.add_argument("--truth-points", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("docs"))
    evaluation_report(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
