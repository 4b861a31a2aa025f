"""Calibrate the named player profiles to their real 2011 serving statistics and their
2019-2020 Hawk-Eye ball figures, or print the acceptance tables
(`sportsngen.synth.calibrate.calibrate_profiles`; seeds in synth/data/profile_seeds.json).

    python scripts/calibrate_profiles.py [--rounds 6] [--points 1500] [--hawkeye-points 2000]
    python scripts/calibrate_profiles.py --report 8000          # 2011 acceptance table
    python scripts/calibrate_profiles.py --hawkeye-report 2000  # Hawk-Eye acceptance table

Output: ``sportsngen/synth/data/profiles.json`` (or `--out`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.synth.calibrate import calibrate_profiles
from sportsngen.synth.profiles import PROFILES_JSON


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--points", type=int, default=1500,
                    help="2011 service points per player and round (0: skip)")
    ap.add_argument("--hawkeye-points", type=int, default=0,
                    help="Hawk-Eye points per matchup and round (0: skip)")
    ap.add_argument("--damping", type=float, default=0.8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2011)
    ap.add_argument("--init", action="store_true", help="start from the seeds (profile_seeds.json)")
    ap.add_argument("--only", nargs="*", help="calibrate only these players")
    ap.add_argument("--tour-for-thin", action="store_true",
                    help="players with one match of Hawk-Eye data (Murray on clay, Sharapova) "
                         "follow their tour's figures")
    ap.add_argument("--out", type=Path, default=PROFILES_JSON,
                    help="profiles file to start from (unless --init) and to write")
    ap.add_argument("--report", type=int, metavar="N_POINTS", default=0,
                    help="only print the 2011 acceptance table (N_POINTS a player)")
    ap.add_argument("--hawkeye-report", type=int, metavar="N_POINTS", default=0,
                    help="only print the Hawk-Eye acceptance table (N_POINTS a matchup)")
    calibrate_profiles(**vars(ap.parse_args()))


if __name__ == "__main__":
    main()
