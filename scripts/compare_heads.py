"""Compare the decoder's output heads, bin spacings and bin centres by held-out likelihood.

    nice -n 10 .venv/bin/python scripts/compare_heads.py --steps 2000 1000 --seeds 0 1 \\
        --seed-variants 2

Every variant is trained on the same frozen data, the same `tiny` model, seed, steps and
`n_bins`, then scored on its held-out rallies by continuous NLL, comparable across binnings
(`sportsngen.studies.heads`).
Results go to `outputs/compare_heads/<variant>_steps<n>_seed<k>/` (model, logs, `result.json`; an
existing `result.json` is reused unless --force; --reevaluate scores it again) and the tables
to `docs/figures/compare_heads.md`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sportsngen.studies.heads import compare_heads

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, nargs="+", default=[600],
                   help="training steps of every variant; the first is the main comparison")
    p.add_argument("--seeds", type=int, nargs="+", default=[0],
                   help="seeds of the main comparison (two or more: a noise estimate)")
    p.add_argument("--seed-variants", type=int, default=None,
                   help="run the seeds after the first only for the first N variants")
    p.add_argument("--n-bins", type=int, default=21)
    p.add_argument("--only", nargs="*", default=None, help="variant names to run")
    p.add_argument("--batch-size", type=int, default=32, help="evaluation batch size")
    p.add_argument("--out", type=Path, default=REPO / "outputs" / "compare_heads")
    p.add_argument("--md", type=Path, default=REPO / "docs" / "figures" / "compare_heads.md")
    p.add_argument("--data", default="synthetic_tiny", help="a conf/data config to freeze")
    p.add_argument("--data-path", type=Path, default=None,
                   help="a RallyData folder to freeze and train on instead of --data")
    p.add_argument("--force", action="store_true", help="retrain even if a result exists")
    p.add_argument("--reevaluate", action="store_true",
                   help="score existing runs again (on the data matching their fingerprint)")
    argv = sys.argv[1:]
    compare_heads(**vars(p.parse_args(argv)), argv=argv)


if __name__ == "__main__":
    main()
