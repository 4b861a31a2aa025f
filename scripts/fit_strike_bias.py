"""Add and fit a model file's per-hitter shifts of the strike head's odds of a rally ball long,
wide or into the net (`model.strike_bias`), or one of the tables fitted on top of them
(`sportsngen.train.strike_fits`, whose docstring says what each flag fits and on which file).

    python scripts/fit_strike_bias.py --model FILE --out FILE [--more-data NAME]
        [--prior-strikes 200] [--width | --returns | --pressure | --shape | --shots |
        --players | --late | --depth | --return-surface] [--states FILE] [--view 8]
        [--draws K] [--more-data-only] [--surface] [--threads 2]
        (e.g. --pressure --view 8 --draws 4 --surface)
"""

from __future__ import annotations

from sportsngen.errors import ArgumentError
from sportsngen.train.strike_fits import FITS, fit_strike_tables_file
from sportsngen.train.table_cli import table_parser


def main() -> None:
    ap = table_parser(__doc__, "--prior-strikes", 200.0,
                      "pseudo-strikes at the head's own odds added to each hitter's record",
                      "also read every rally strike of this data config (conf/data/NAME.yaml)")
    how = ap.add_mutually_exclusive_group()
    for flag, what in FITS:
        how.add_argument(flag, action="store_true", help=what)
    ap.add_argument("--late-only", action="store_true",
                    help="with --late: fit the late table alone, on top of the file's other "
                         "tables as they are")
    ap.add_argument("--states", default=None,
                    help="cache of the decoder's states: written on the first run, read after")
    ap.add_argument("--view", type=int, default=None, metavar="LEAD",
                    help="each strike's state from its own window ending LEAD (8) frames after "
                         "it, as a rollout reads it (run with MALLOC_MMAP_THRESHOLD_=65536)")
    ap.add_argument("--more-data-only", action="store_true",
                    help="read the --more-data rallies alone, not the file's training split")
    ap.add_argument("--surface", action="store_true",
                    help="then add (or refit from zero) the hitters' surfaces table "
                         "(model.strike_surface) on top of every other table")
    ap.add_argument("--draws", type=int, default=0,
                    help="match each strike's odds at that many of the head's own draws of "
                         "the earlier dimensions, as a rollout draws (with --pressure, ...)")
    try:
        fit_strike_tables_file(**vars(ap.parse_args()))
    except ArgumentError as exc:
        ap.error(str(exc))


if __name__ == "__main__":
    main()
