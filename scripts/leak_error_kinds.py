"""What drives the leak check's error-against-in separation for the opponent: his speed k frames
after rally contacts that will be errors, by where the error goes (net, long, wide), beside
contacts that land in, all before the outcome is visible.

    python scripts/leak_error_kinds.py [--points 1500] [--seed 1] [--k 12]

Federer v Nadal on hard. A ball flying long or wide sends the opponent running harder than one
landing in: a cause he sees in the ball's flight, not a leak.
"""

from __future__ import annotations

import argparse

import numpy as np

from sportsngen.eval.leaks import contact_kinematics
from sportsngen.synth import generate_matches
from sportsngen.tennis.court import BASELINE_X_M


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--k", type=int, default=12)
    args = ap.parse_args()
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", args.points,
                            seed=args.seed)
    t = contact_kinematics(data, (args.k,))
    # error/in contacts whose landing is not yet visible at contact + k
    t = t[(t["error_vs_in"] >= 0) & t["opponent_speed_mps"].notna() &
          (t["at_frame"] < t["land_frame"])]
    shots = data.shots.set_index(["rally_id", "shot_index"])[["outcome", "bounce_x"]]
    t = t.join(shots, on=["rally_id", "shot_index"])
    bx = t["bounce_x"].to_numpy(dtype=float)
    kind = np.where(t["outcome"] != "error", "in",
                    np.where(np.isnan(bx), "net",
                             np.where(np.abs(bx) > BASELINE_X_M, "long", "wide")))
    table = t.groupby(kind)["opponent_speed_mps"].agg(["count", "mean", "median"])
    print(f"opponent speed (m/s) {args.k} frames after rally contacts, by the shot's fate")
    print(table.round(2).to_string())


if __name__ == "__main__":
    main()
