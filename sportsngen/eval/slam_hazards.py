"""Shot by shot, how often a named player's service points end: the real 2011 slams (US Open and
Wimbledon) beside the generator (the calibration's service points against population players);
`scripts/rally_hazards.py` is the command line.

Hazard at rally length L: the share of points reaching L shots that end there
(`sportsngen.eval.stats.rally_hazards`); odd L are won by the server, even L by the receiver.
The binned shares of the 2011 acceptance average this away; this is where the rally's shape is
read (a server advantage that fades too fast piles the receivers' errors on the first rally
balls). Needs ../shared/data/slam_pointbypoint for the real column.

Source of the real points: Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint,
CC BY-NC-SA 4.0.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import pandas as pd

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import read_slam_events
from sportsngen.eval.stats import rally_hazards
from sportsngen.synth import calibrate as cal
from sportsngen.synth import profiles as prof

EVENTS = ("2011-usopen", "2011-wimbledon")
N_OPPONENTS = 48


def slam_hazards(players: Sequence[str], n_points: int = 3000, seed: int = 5,
                 max_length: int = 10) -> int:
    """Print each player's hazard table, real beside generated (`n_points` service points,
    seeds from `seed`). -> 0, 1 without the slam data, 2 for a player with no named profile
    (said on stderr)."""
    if slam_dir() is None:
        print(SHARED_DATA_MISSING, file=sys.stderr)
        return 1
    points = read_slam_events(events=list(EVENTS))
    named = cal.read_profiles(prof.PROFILES_JSON)
    for i, name in enumerate(players):
        if name not in named:
            print(f"no named profile {name!r}; known: {sorted(named)}", file=sys.stderr)
            return 2
        p = named[name]
        real = rally_hazards(points.loc[points["server"] == name, "rally"], max_length)
        opponents = cal.population_opponents(p, named, N_OPPONENTS, seed + 1000 + i)
        gen = cal.service_outcomes(p, opponents, n_points, seed + i)
        sim = rally_hazards(gen["rally"], max_length)
        table = pd.DataFrame({"real": real["hazard"], "generated": sim["hazard"],
                              "real n": real["reached"], "generated n": sim["reached"]})
        print(f"\n{name} serving: hazard by rally length (odd: the server wins)")
        print(table.round(3).to_string())
    return 0
