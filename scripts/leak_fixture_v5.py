"""Write the per-contact kinematics table of generator version 5 that pins its leaks in the tests.

    PYTHONPATH=. .venv/bin/python scripts/leak_fixture_v5.py \\
        [--out tests/data/leaks_v5_fvn_hard.csv]

300 points of Roger Federer v Rafael Nadal on hard (seed 5), `contact_kinematics` at k = 6 and
12 frames, the columns `leak_auc` needs (stratified: the players' names too), under a comment
line naming the generator
version. Refuses to run on another generator version: the file is a record of version 5, whose
players "know the future" (issue 16), for `tests/test_leaks.py`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.eval.leaks import (
    CONTACT_SPEED_COLUMNS,
    STRATA_COLUMNS,
    TABLE_COLUMNS,
    contact_kinematics,
)
from sportsngen.synth import generate_matches
from sportsngen.synth.dataset import GENERATOR_VERSION

PLAYERS = ("Roger Federer", "Rafael Nadal")
N_POINTS, SEED, SURFACE = 300, 5, "hard"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("tests/data/leaks_v5_fvn_hard.csv"))
    args = ap.parse_args()
    if GENERATOR_VERSION != "5":
        raise SystemExit(f"this table records generator version 5; this is {GENERATOR_VERSION}")
    data = generate_matches([PLAYERS], SURFACE, n_points=N_POINTS, seed=SEED, workers=1)
    kin = contact_kinematics(data, ks=(6, 12))[
        list(TABLE_COLUMNS + STRATA_COLUMNS + CONTACT_SPEED_COLUMNS)]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write(f"# generator version {GENERATOR_VERSION}: {N_POINTS} points of "
                 f"{PLAYERS[0]} v {PLAYERS[1]} on {SURFACE}, seed {SEED}; written by "
                 "scripts/leak_fixture_v5.py (contact_kinematics, k = 6, 12)\n")
        kin.to_csv(fh, index=False)
    print(f"wrote {args.out}: {len(kin)} rows, {args.out.stat().st_size / 1e3:.0f} KB")


if __name__ == "__main__":
    main()
