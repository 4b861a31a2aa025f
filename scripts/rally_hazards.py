"""Shot by shot, how often a named player's service points end: the real 2011 slams (US Open and
Wimbledon) beside the generator (the calibration's service points against population players).

    python scripts/rally_hazards.py [--players "Rafael Nadal" "Novak Djokovic"] [--points 3000]
        [--seed 5] [--max-length 10]

Hazard at rally length L: the share of points reaching L shots that end there
(`sportsngen.eval.stats.rally_hazards`); odd L are won by the server, even L by the receiver.
The binned shares of the 2011 acceptance average this away; this is where the rally's shape is
read (a server advantage that fades too fast piles the receivers' errors on the first rally
balls). Needs ../shared/data/slam_pointbypoint for the real column.

Source of the real points: Jeff Sackmann / Tennis Abstract, tennis_slam_pointbypoint,
CC BY-NC-SA 4.0.
"""

from __future__ import annotations

import argparse
import sys

import pandas as pd

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.slam import read_slam_events
from sportsngen.eval.stats import rally_hazards
from sportsngen.synth import calibrate as cal
from sportsngen.synth import profiles as prof

EVENTS = ("2011-usopen", "2011-wimbledon")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--players", nargs="+", default=["Rafael Nadal", "Novak Djokovic"])
    ap.add_argument("--points", type=int, default=3000, help="generated service points a player")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--max-length", type=int, default=10)
    args = ap.parse_args(argv)
    if slam_dir() is None:
        print(SHARED_DATA_MISSING, file=sys.stderr)
        return 1
    points = read_slam_events(events=list(EVENTS))
    named = cal.read_profiles(prof.PROFILES_JSON)
    for i, name in enumerate(args.players):
        if name not in named:
            print(f"no named profile {name!r}; known: {sorted(named)}", file=sys.stderr)
            return 2
        p = named[name]
        real = rally_hazards(points.loc[points["server"] == name, "rally"], args.max_length)
        opponents = cal.population_opponents(p, named, 48, args.seed + 1000 + i)
        gen = cal.service_outcomes(p, opponents, args.points, args.seed + i)
        sim = rally_hazards(gen["rally"], args.max_length)
        table = pd.DataFrame({"real": real["hazard"], "generated": sim["hazard"],
                              "real n": real["reached"], "generated n": sim["reached"]})
        print(f"\n{name} serving: hazard by rally length (odd: the server wins)")
        print(table.round(3).to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main())
