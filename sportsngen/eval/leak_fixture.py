"""The per-contact kinematics table of generator version 5 that pins its leaks in the tests
(`tests/data/leaks_v5_fvn_hard.csv`, read by `tests/test_leaks.py`); `scripts/leak_fixture_v5.py`
is the command line.

300 points of Roger Federer v Rafael Nadal on hard (seed 5), `contact_kinematics` at k = 6 and
12 frames, the columns `leak_auc` needs (stratified: the players' names too), under a comment
line naming the generator version. The file is a record of version 5, whose players "know the
future" (issue 16): it is refused on another generator version.

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

from pathlib import Path

from sportsngen.data.tracking import RallyData
from sportsngen.errors import ArgumentError
from sportsngen.eval.leaks import (
    CONTACT_SPEED_COLUMNS,
    HITTER_STRATA_COLUMNS,
    OPPONENT_STRATA_COLUMNS,
    STRATA_COLUMNS,
    TABLE_COLUMNS,
    contact_kinematics,
)
from sportsngen.synth import generate_matches
from sportsngen.synth.dataset import GENERATOR_VERSION

PLAYERS = ("Roger Federer", "Rafael Nadal")
N_POINTS, SEED, SURFACE = 300, 5, "hard"


def fixture_points(data: Path | None = None) -> RallyData:
    """Version 5's points: read from `data` (saved from version 5's tree; its meta must name
    the seed and points) or, on version 5 itself, generated. `ArgumentError` otherwise."""
    if data is not None:
        points = RallyData.load(data)
        want = {"seed": SEED, "n_points": N_POINTS}
        if {k: points.meta.get(k) for k in want} != want:
            raise ArgumentError(f"{data}: meta {points.meta} is not {want}")
        return points
    if GENERATOR_VERSION != "5":
        raise ArgumentError(f"this table records generator version 5; this is "
                            f"{GENERATOR_VERSION} (see --data)")
    return generate_matches([PLAYERS], SURFACE, n_points=N_POINTS, seed=SEED, workers=1)


def write_leak_fixture(out: Path, data: Path | None = None) -> None:
    """Write the table of `fixture_points(data)` to `out` under its comment line."""
    kin = contact_kinematics(fixture_points(data), ks=(6, 12))[
        list(TABLE_COLUMNS + STRATA_COLUMNS + OPPONENT_STRATA_COLUMNS + HITTER_STRATA_COLUMNS
             + CONTACT_SPEED_COLUMNS)]
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w") as fh:
        fh.write(f"# generator version 5: {N_POINTS} points of "
                 f"{PLAYERS[0]} v {PLAYERS[1]} on {SURFACE}, seed {SEED}; written by "
                 "scripts/leak_fixture_v5.py (contact_kinematics, k = 6, 12)\n")
        kin.to_csv(fh, index=False)
    print(f"wrote {out}: {len(kin)} rows, {out.stat().st_size / 1e3:.0f} KB")
