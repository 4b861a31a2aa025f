"""Add and fit a model file's per-server shifts of the serve head's odds of a long and a wide
serve and of its speed (`model.serve_bias`; `sportsngen.train.table_fits.fit_serve_bias_file`).

    python scripts/fit_serve_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-serves 100] [--threads 2] [--short | --lateral]

On the file's own training split (and every serve of conf/data/NAME.yaml); `--short` and
`--lateral` fit the short serves' or the lateral bands' shifts on a file that has the table.
"""

from __future__ import annotations

from sportsngen.train.table_cli import table_parser
from sportsngen.train.table_fits import fit_serve_bias_file


def main() -> None:
    ap = table_parser(__doc__, "--prior-serves", 100.0,
                      "pseudo-serves at the head's own odds added to each server's record",
                      "also read every serve of this data config (conf/data/NAME.yaml)")
    ap.add_argument("--short", action="store_true",
                    help="fit the short serves' shift on a file that has the table")
    ap.add_argument("--lateral", action="store_true",
                    help="fit the lateral bands' shifts on a file that has the table")
    fit_serve_bias_file(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
