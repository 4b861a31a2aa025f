"""Calibrate the named player profiles to their real 2011 serving statistics and their
2019-2020 Hawk-Eye ball figures (`sportsngen.synth.calibrate`), or print the acceptance tables.

    python scripts/calibrate_profiles.py [--rounds 6] [--points 1500] [--hawkeye-points 2000]
    python scripts/calibrate_profiles.py --report 8000          # 2011 acceptance table
    python scripts/calibrate_profiles.py --hawkeye-report 2000  # Hawk-Eye acceptance table

Output: ``sportsngen/synth/data/profiles.json`` (or `--out`).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from sportsngen.synth import calibrate as cal
from sportsngen.synth import profiles as prof


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
                    help="calibrate players with one match of Hawk-Eye data (Murray on clay, "
                         "Sharapova) to their tour's figures (calibrate.calibration_targets)")
    ap.add_argument("--out", type=Path, default=prof.PROFILES_JSON,
                    help="profiles file to start from (unless --init) and to write")
    ap.add_argument("--report", type=int, metavar="N_POINTS", default=0,
                    help="only print the 2011 acceptance table (whole matches, N_POINTS a "
                         "player)")
    ap.add_argument("--hawkeye-report", type=int, metavar="N_POINTS", default=0,
                    help="only print the Hawk-Eye acceptance table (N_POINTS a matchup)")
    args = ap.parse_args()
    t0 = time.time()
    targets = cal.load_targets()
    if args.init or not args.out.exists():
        seeds = cal.profile_seeds()
        named = {n: cal.initial_profile(n, targets.loc[n], s) for n, s in seeds.items()}
    else:
        named = cal.read_profiles(args.out)
    if args.report:
        print("simulated / real (2011); '!' = outside tolerance", flush=True)
        cal.acceptance_2011(named, targets, args.report, args.seed + 7, args.workers)
    if args.hawkeye_report:
        print(cal.acceptance_hawkeye(named, args.hawkeye_report, args.seed + 7, args.workers))
    if not (args.report or args.hawkeye_report):
        cal.calibrate(named, args.rounds, args.points, args.hawkeye_points, args.seed,
                      args.workers, args.damping, only=args.only, out=args.out,
                      tour_for_thin=args.tour_for_thin,
                      log=lambda s: print(f"[{time.time() - t0:.0f} s] {s}", flush=True))
    print(f"done in {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
