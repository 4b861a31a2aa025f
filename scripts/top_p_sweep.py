"""Top-p sweep (the paper's Fig. 7): realism metrics of simulated play against nucleus top-p.

    .venv/bin/python scripts/top_p_sweep.py [--model PATH] [--values 0.5 0.6 0.7 0.8 0.9 0.95 1.0]
        [--points 100] [--out docs/figures/top_p] [--write-default]
        [--kind both|player|ball] [--other P]

For each top-p, simulated Federer v Nadal points on hard against the generator's ground truth;
the best value (smallest score) is stored in the model file with `--write-default`
(`sportsngen.studies.top_p`). Writes top_p.png, top_p.md and top_p.csv into --out.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.studies.top_p import top_p_sweep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--values", type=float, nargs="+",
                    default=[0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0])
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/top_p"))
    ap.add_argument("--write-default", action="store_true")
    ap.add_argument("--kind", choices=("both", "player", "ball"), default="both",
                    help="which object kind's top-p the values set")
    ap.add_argument("--other", type=float, default=0.7,
                    help="the other kind's top-p when --kind is player or ball")
    top_p_sweep(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
