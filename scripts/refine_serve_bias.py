"""Refit a model file's per-server serve shifts (`model.serve_bias`) on its own rollouts until
each named server's rolled-out serves fault as often as his record
(`sportsngen.train.table_fits.refine_serve_bias_file`). Run after `scripts/fit_serve_bias.py`.

    python scripts/refine_serve_bias.py --model FILE --out FILE
        [--more-data synthetic_named] [--players "A,B"] [--serves 400] [--rounds 3]
        [--seed 0] [--threads 2] [--csv rounds.csv]
"""

from __future__ import annotations

from sportsngen.train.table_cli import table_parser
from sportsngen.train.table_fits import refine_serve_bias_file


def main() -> None:
    ap = table_parser(__doc__)
    ap.add_argument("--players", default=None,
                    help="comma-separated servers (default: the training data's named players)")
    ap.add_argument("--serves", type=int, default=400, help="rollouts a server, serve, round")
    ap.add_argument("--rounds", type=int, default=3, help="updates before the last measurement")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--csv", default=None, help="write the rounds table here")
    refine_serve_bias_file(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
