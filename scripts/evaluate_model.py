"""Held-out next-frame metrics of an exported model file, as a markdown table.

    .venv/bin/python scripts/evaluate_model.py --model outputs/train/.../model.pt
    .venv/bin/python scripts/evaluate_model.py --model m.pt --data synthetic_tiny
    .venv/bin/python scripts/evaluate_model.py --model m.pt --data /path/to/rallydata \\
        --held-out-fraction 1     # every rally of data the model never saw

Held out = the rallies the training data module put in validation (same data, seed and
fraction, read from the model file unless given). Per object kind: the model's NLL (nats per
object token) and top-1 bin accuracy, beside the constant-velocity predictor's (Gaussian with
per-dimension sigma fitted on these same tokens) and the top-1 of the bin holding the
constant-velocity extrapolation; the ball also in flight and at racket contact (+-1 frame).
See `sportsngen.train.evaluate.print_held_out`.
"""

from __future__ import annotations

import argparse

from sportsngen.train.evaluate import print_held_out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", required=True, help="a model file written by train.py")
    p.add_argument("--data", default=None,
                   help="synthetic_small | synthetic_tiny | toy | a RallyData folder "
                        "(default: the data the model was trained on)")
    p.add_argument("--held-out-fraction", type=float, default=None,
                   help="validation fraction of the split (default: the training one; "
                        "1 = every rally)")
    p.add_argument("--seed", type=int, default=None, help="split seed (default: training's)")
    p.add_argument("--batch-size", type=int, default=32)
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    p.add_argument("--json", default=None, help="also write every figure to this JSON file")
    args = p.parse_args()
    print_held_out(args.model, args.data, args.held_out_fraction, args.seed, args.batch_size,
                   args.device, args.threads, args.json)


if __name__ == "__main__":
    main()
