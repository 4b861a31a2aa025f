"""Add and fit a model file's per-server shifts of the receiver's odds of starting his run at
the serve (`model.receiver_start`; `sportsngen.train.table_fits.fit_receiver_start_file`).

    python scripts/fit_receiver_start.py --model FILE --out FILE [--more-data NAME]
        [--prior-frames 200] [--threads 2]
"""

from __future__ import annotations

from sportsngen.train.table_cli import table_parser
from sportsngen.train.table_fits import fit_receiver_start_file


def main() -> None:
    fit_receiver_start_file(**vars(table_parser(
        __doc__, "--prior-frames", 200.0,
        "pseudo-frames at the head's own odds added to each server's record").parse_args()))


if __name__ == "__main__":
    main()
