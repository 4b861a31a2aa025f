"""Write the per-contact kinematics table of generator version 5 that pins its leaks in the tests.

    PYTHONPATH=. .venv/bin/python scripts/leak_fixture_v5.py \\
        [--out tests/data/leaks_v5_fvn_hard.csv] [--data FOLDER]

300 points of Roger Federer v Rafael Nadal on hard (seed 5), `contact_kinematics` at k = 6 and
12 frames (`sportsngen.eval.leak_fixture`). Refuses to generate on another generator version:
the file is a record of version 5, whose players "know the future" (issue 16), for
`tests/test_leaks.py`.

When the check changes after version 5 is gone: `sportsngen.eval.leak_fixture`'s doc says how
to generate version 5's points for `--data`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.errors import ArgumentError
from sportsngen.eval.leak_fixture import write_leak_fixture


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("tests/data/leaks_v5_fvn_hard.csv"))
    ap.add_argument("--data", type=Path, default=None,
                    help="the points, saved from version 5's tree (module doc)")
    args = ap.parse_args()
    try:
        write_leak_fixture(args.out, args.data)
    except ArgumentError as exc:
        raise SystemExit(str(exc)) from None


if __name__ == "__main__":
    main()
