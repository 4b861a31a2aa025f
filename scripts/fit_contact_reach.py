"""Add and fit a model file's shifts of the ball's odds of a racket contact by where the ball
is from its hitter (`model.contact_reach`; `sportsngen.train.table_fits.fit_contact_reach_file`).

    python scripts/fit_contact_reach.py --model FILE --out FILE [--more-data NAME]
        [--prior-frames 20] [--threads 2]
"""

from __future__ import annotations

from sportsngen.train.table_cli import table_parser
from sportsngen.train.table_fits import fit_contact_reach_file


def main() -> None:
    fit_contact_reach_file(**vars(table_parser(
        __doc__, "--prior-frames", 20.0,
        "pseudo-frames at the head's own odds added to each cell's record").parse_args()))


if __name__ == "__main__":
    main()
