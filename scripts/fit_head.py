"""Fit a model file's serve (or strike) head alone on its frozen decoder's states, read once,
on the file's own training split (`sportsngen.train.head_refit.fit_head_file`).

    python scripts/fit_head.py --model FILE --out FILE [--head serve|strike]
        [--steps 4000] [--lr 1e-3] [--batch-size 256] [--seed 0] [--threads 2]
        [--more-points N --more-seed S] [--more-data NAME] [--no-flip] [--states FILE]
        [--strike-roles] [--own-serves]
"""

from __future__ import annotations

from sportsngen.train.head_fit import HEADS
from sportsngen.train.head_refit import fit_head_file
from sportsngen.train.table_cli import table_parser


def main() -> None:
    ap = table_parser(__doc__, data_help="draw the more points from this data config "
                      "(conf/data/NAME.yaml), e.g. synthetic_named")
    ap.add_argument("--head", choices=HEADS, default="serve")
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--batch-size", type=int, default=256)
    ap.add_argument("--eval-every", type=int, default=250)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--more-points", type=int, default=0,
                    help="also train on this many more points of the file's data config")
    ap.add_argument("--more-seed", type=int, default=None,
                    help="the more points' seed (default 1000, or --more-data's own)")
    ap.add_argument("--no-flip", action="store_true",
                    help="only the windows as recorded (default: also turned, as training does)")
    ap.add_argument("--strike-roles", action="store_true",
                    help="add and fit the strike head's shift by role (model.strike_roles)")
    ap.add_argument("--own-serves", action="store_true",
                    help="also fit the serve head at the serves the model plays from its own "
                         "tosses, paired with the record's")
    ap.add_argument("--states", default=None,
                    help="cache of the states read: written on the first run, read after")
    fit_head_file(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
