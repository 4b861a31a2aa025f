"""What drives the leak check's error-against-in separation for the opponent: his speed k frames
after rally contacts that will be errors, by where the error goes (net, long, wide), beside
contacts that land in, all before the outcome is visible; `scripts/leak_error_kinds.py` is the
command line.

A ball flying long or wide sends the opponent running harder than one landing in: a cause he
sees in the ball's flight, not a leak.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.eval.leaks import contact_kinematics
from sportsngen.synth import generate_matches
from sportsngen.tennis.court import BASELINE_X_M


def opponent_speed_by_fate(data: RallyData, k: int) -> pd.DataFrame:
    """The opponent's speed (m/s) `k` frames after error / in rally contacts whose landing is
    not yet visible then: count, mean and median by the shot's fate (in, net, long, wide)."""
    t = contact_kinematics(data, (k,))
    t = t[(t["error_vs_in"] >= 0) & t["opponent_speed_mps"].notna() &
          (t["at_frame"] < t["land_frame"])]
    shots = data.shots.set_index(["rally_id", "shot_index"])[["outcome", "bounce_x"]]
    t = t.join(shots, on=["rally_id", "shot_index"])
    bx = t["bounce_x"].to_numpy(dtype=float)
    kind = np.where(t["outcome"] != "error", "in",
                    np.where(np.isnan(bx), "net",
                             np.where(np.abs(bx) > BASELINE_X_M, "long", "wide")))
    return t.groupby(kind)["opponent_speed_mps"].agg(["count", "mean", "median"])


def leak_error_kinds(n_points: int = 1500, seed: int = 1, k: int = 12) -> None:
    """Print `opponent_speed_by_fate` of `n_points` generated points of Federer v Nadal on
    hard."""
    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points, seed=seed)
    table = opponent_speed_by_fate(data, k)
    print(f"opponent speed (m/s) {k} frames after rally contacts, by the shot's fate")
    print(table.round(2).to_string())
