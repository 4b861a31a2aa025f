"""Simulated runs pooled against one large generated truth: the biases one check cannot show
(`sportsngen.eval.pooled_truth`, whose docstring explains the comparison).

    python scripts/bias_to_truth.py SIM_DIR [SIM_DIR ...] [--truth-points 12000]
        [--truth-seed 777] [--cache outputs/truths] [--json OUT]

SIM_DIR: `scripts/check_simulation.py --save-sim` folders; truths cached under --cache.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.pooled_truth import bias_to_truth

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sims", nargs="+", type=Path, help="check_simulation.py --save-sim folders")
    ap.add_argument("--truth-points", type=int, default=12000)
    ap.add_argument("--truth-seed", type=int, default=777)
    ap.add_argument("--cache", type=Path, default=REPO / "outputs" / "truths")
    ap.add_argument("--json", type=Path, default=None, help="write the pooled rows here")
    args = ap.parse_args()
    bias_to_truth(args.sims, args.truth_points, args.truth_seed, args.cache, args.json)


if __name__ == "__main__":
    main()
