"""Train every ablation of conf/experiment/ablation_*.yaml at tiny scale and compare held-out NLL.

    nice -n 10 .venv/bin/python scripts/run_ablations.py --steps 1000 --seeds 0 1

Every ablation and the full model ("default") trained with `experiment=tiny`'s overrides on
synthetic_tiny frozen in `<out>/data`, the same seed and steps, scored on its held-out rallies
(`sportsngen.studies.ablations`). Results go to `outputs/ablations/<name>_steps<N>_seed<k>/`
(model, logs, `result.json`; an existing `result.json` is reused unless --force) and the table
to `docs/figures/ablations.md`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sportsngen.studies.ablations import ABLATIONS, run_ablations

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1000, help="training steps of every run")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--only", nargs="*", default=None,
                   help=f"ablation names to run (of {list(ABLATIONS)})")
    p.add_argument("--out", type=Path, default=REPO / "outputs" / "ablations")
    p.add_argument("--md", type=Path, default=REPO / "docs" / "figures" / "ablations.md")
    p.add_argument("--force", action="store_true", help="retrain even if a result exists")
    argv = sys.argv[1:]
    args = p.parse_args(argv)
    unknown = sorted(set(args.only or []) - set(ABLATIONS))
    if unknown:
        p.error(f"unknown ablations {unknown}; known: {list(ABLATIONS)}")
    run_ablations(**vars(args), argv=argv)


if __name__ == "__main__":
    main()
