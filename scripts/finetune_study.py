"""Fine-tuning study (the paper's Fig. 13): a generic model adapted to a player it never saw.

    .venv/bin/python scripts/finetune_study.py [--player "John Isner"] [--ks 0 50 200 1000]
        [--base-steps 1500] [--ft-steps 300] [--points 600] [--out docs/figures/finetune]
        [--base-points 15000] [--player-points 2000]
        [--work outputs/finetune_study] [--threads 2] [--reuse]
    .venv/bin/python scripts/finetune_study.py --base bundled --player "Unseen M 002"
        [--population-seed 200] ...

A base model (trained without the player, or `--base MODEL`/`bundled` with an unseen
population player) fine-tuned on k of the player's sequences, each simulated against the
generator's ground truth (`sportsngen.studies.finetune`). Writes finetune.md, finetune.csv and
finetune.png into --out. `--reuse` skips trainings whose model file already exists in --work.
Every step runs `train.py` in a subprocess, so the commands in the printed log reproduce each
model.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.studies.finetune import finetune_study

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--player", default="John Isner")
    ap.add_argument("--ks", type=int, nargs="+", default=[0, 50, 200, 1000])
    ap.add_argument("--base-steps", type=int, default=1500)
    ap.add_argument("--ft-steps", type=int, default=300)
    ap.add_argument("--base-points", type=int, default=15000, help="points of the base data")
    ap.add_argument("--player-points", type=int, default=2000,
                    help="points of the player's own data (k rallies are taken from it)")
    ap.add_argument("--points", type=int, default=600)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="outputs/finetune_study")
    ap.add_argument("--out", default="docs/figures/finetune")
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--base", default=None,
                    help="a trained model file (or 'bundled') to use as the base")
    ap.add_argument("--population-seed", type=int, default=200,
                    help="population seed of an 'Unseen M 00k' player")
    finetune_study(**vars(ap.parse_args()), root=ROOT)


if __name__ == "__main__":
    main()
