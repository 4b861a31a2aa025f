"""Horizon study (the paper's Fig. 18): position error of rollouts against time after a branch.

    .venv/bin/python scripts/horizon_study.py [--model PATH] [--rallies 60] [--n 4]
        [--horizon-s 1.75] [--out docs/figures/horizon]

Held-out synthetic rallies branched at 1 to 4 s, `--n` rollouts each for `--horizon-s`: RMSE
of the ball's and players' positions against the track, beside linear extrapolation
(`sportsngen.studies.horizon`). Writes horizon.png, horizon.md and horizon.csv into --out.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.studies.horizon import horizon_study


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--rallies", type=int, default=60)
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--horizon-s", type=float, default=1.75)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/horizon"))
    horizon_study(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
