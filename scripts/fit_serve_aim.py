"""Add and fit a model file's per-server aim of the serve inside the box (`model.serve_aim`) on
the serves the model plays from its own tosses (`sportsngen.train.table_fits.fit_serve_aim_file`;
the file must have the serve table of `scripts/fit_serve_bias.py`).

    python scripts/fit_serve_aim.py --model FILE --out FILE [--data synthetic_named]
        [--players "A,B"] [--max-rallies 12000] [--prior-serves 100] [--seed 0] [--threads 2]
"""

from __future__ import annotations

from sportsngen.train.table_cli import model_parser
from sportsngen.train.table_fits import fit_serve_aim_file


def main() -> None:
    ap = model_parser(__doc__)
    ap.add_argument("--data", default="synthetic_named", help="data config (conf/data/NAME)")
    ap.add_argument("--players", default=None,
                    help="comma-separated servers (default: the file's named players)")
    ap.add_argument("--max-rallies", type=int, default=12000,
                    help="at most this many of their rallies, drawn at random (--seed)")
    ap.add_argument("--prior-serves", type=float, default=100.0,
                    help="pseudo-serves at the head's own aim added to each server's record")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    if args.max_rallies < 1:
        ap.error(f"--max-rallies must be at least 1, got {args.max_rallies}")
    fit_serve_aim_file(**vars(args))


if __name__ == "__main__":
    main()
