"""Write the per-contact kinematics table of generator version 5 that pins its leaks in the tests.

    PYTHONPATH=. .venv/bin/python scripts/leak_fixture_v5.py \\
        [--out tests/data/leaks_v5_fvn_hard.csv] [--data FOLDER]

300 points of Roger Federer v Rafael Nadal on hard (seed 5), `contact_kinematics` at k = 6 and
12 frames (`sportsngen.eval.leak_fixture`). Refuses to generate on another generator version:
the file is a record of version 5, whose players "know the future" (issue 16), for
`tests/test_leaks.py`.

When the check changes after version 5 is gone, generate the points in version 5's tree (the
parent of commit 9cf9119) and extract the table with today's check. Generate from outside
the checkout: `python -c` puts the working directory first on the path, so run from the
checkout it would import today's generator, not version 5's.

    git worktree add /tmp/v5tree 9cf9119^
    (cd /tmp && PYTHONPATH=/tmp/v5tree $OLDPWD/.venv/bin/python -c "from sportsngen.synth \\
        import generate_matches; generate_matches([('Roger Federer', 'Rafael Nadal')], \\
        'hard', n_points=300, seed=5, workers=1).save('/tmp/v5data')")
    PYTHONPATH=. .venv/bin/python scripts/leak_fixture_v5.py --data /tmp/v5data
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
