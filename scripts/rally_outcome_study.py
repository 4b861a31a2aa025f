"""Rally outcome prediction (the paper's Fig. 14 and 15): calibration of the simulator's
P(server wins the point) from random frames of held-out rallies.

    .venv/bin/python scripts/rally_outcome_study.py [--model PATH] [--rallies 60] [--n 32]
        [--seed 0] [--workers 1 --threads 2] [--out docs/figures/outcome]
        [--calibrator logistic|isotonic] [--save-calibrator] [--from-points CSV [CSV ...]]
        [--kernel-n 64]

Branch points of held-out synthetic Federer v Nadal rallies, `--n` rollouts each, beside the
base rate and the Markov serve model; recalibration judged out of fold
(`sportsngen.studies.outcome`). Writes reliability.png, outcome.md, outcome.json and
branch_points.csv into --out. `--save-calibrator` also stores a `--calibrator` map fitted on
all branch points in the model file. `--from-points` reads the branch points an earlier run of
the same model wrote instead of rolling out again; several runs' files (other seeds) are
pooled, with `--kernel-n 0`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.calibration import CALIBRATORS
from sportsngen.studies.outcome import OutcomeStudy, rally_outcome_study


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--rallies", type=int, default=60)
    ap.add_argument("--n", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None, help="threads a process")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes rolling the branch points out (each loads the model)")
    ap.add_argument("--chunk-items", type=int, default=0,
                    help="branch points a chunk (one seed each; the results depend on it); "
                         "0: all in one call, as before there were workers")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/outcome"))
    ap.add_argument("--calibrator", choices=sorted(CALIBRATORS), default="logistic",
                    help="the map --save-calibrator stores (fitted on all branch points)")
    ap.add_argument("--save-calibrator", action="store_true",
                    help="store the --calibrator map in the model file (outcome_calibrator)")
    ap.add_argument("--kernel-n", type=int, default=64,
                    help="plays of the generator's players from each branch point's hand-over "
                         "(sportsngen.eval.expert_outcomes), the reference without the "
                         "outcomes' luck; 0: none")
    ap.add_argument("--from-points", type=Path, nargs="+", default=None,
                    help="branch_points.csv of earlier runs of this model (several: pooled, "
                         "with --kernel-n 0): no rollouts")
    try:
        opts = OutcomeStudy(**vars(ap.parse_args()))
    except ValueError as exc:     # inconsistent flags: argparse's message and exit status
        ap.error(str(exc))
    rally_outcome_study(opts)


if __name__ == "__main__":
    main()
