"""Physical sanity of generated tracking, per surface; `scripts/check_synth_physics.py` is the
command line.

Toss contact height, the ball never below its radius nor through the net cord (checked at every
25 Hz crossing of x = 0, height interpolated linearly), players' peak speed and acceleration
from finite differences, and the median ball speed ratio after/before a bounce (frames around
each local minimum of ball height).
"""

from __future__ import annotations

import numpy as np

from sportsngen.synth import generate_matches
from sportsngen.synth.physics import BALL_RADIUS_M
from sportsngen.tennis.court import net_height_m

PLAYERS = ["Roger Federer", "Rafael Nadal", "Novak Djokovic"]


def check(surface: str, n_points: int = 600, seed: int = 5) -> str:
    """One line of the checks on `n_points` generated points on `surface`."""
    d = generate_matches(PLAYERS, surface, n_points, seed=seed)
    f = d.frames.sort_values(["rally_id", "object", "frame"])
    ball = f[f["object"] == "ball"]
    x, y, z, rid = (ball[c].to_numpy() for c in ("x", "y", "z", "rally_id"))
    same = rid[1:] == rid[:-1]

    cross = same & (np.sign(x[1:]) != np.sign(x[:-1])) & (x[1:] != 0)
    w = np.abs(x[:-1]) / (np.abs(x[:-1]) + np.abs(x[1:]) + 1e-12)
    z_net = z[:-1] + w * (z[1:] - z[:-1])
    y_net = y[:-1] + w * (y[1:] - y[:-1])
    below = cross & (z_net - BALL_RADIUS_M < net_height_m(y_net) - 0.02)

    pl = f[f["object"] != "ball"]
    px, py, pr, po = (pl[c].to_numpy() for c in ("x", "y", "rally_id", "object"))
    same_p = (pr[1:] == pr[:-1]) & (po[1:] == po[:-1])
    vx, vy = np.diff(px) * d.fps, np.diff(py) * d.fps
    speed = np.where(same_p, np.hypot(vx, vy), np.nan)
    accel = np.hypot(np.diff(vx), np.diff(vy)) * d.fps
    accel = accel[same_p[1:] & same_p[:-1]]

    v_ball = np.linalg.norm(np.diff(ball[["x", "y", "z"]].to_numpy(), axis=0), axis=1) * d.fps
    mid = z[1:-1]
    low = (mid < z[:-2]) & (mid < z[2:]) & (mid < 0.5) & same[1:] & same[:-1]
    mins = np.flatnonzero(low) + 1
    mins = mins[(mins > 3) & (mins < len(z) - 4)]
    ok = (rid[mins - 3] == rid[mins]) & (rid[mins + 3] == rid[mins])
    ratio = v_ball[mins[ok] + 1] / v_ball[mins[ok] - 2]

    toss = d.shots.loc[d.shots["stroke"] == "serve", "contact_z"]
    return (f"{surface}: {len(d.points())} points; serve contact z median {toss.median():.2f} m "
            f"(range {toss.min():.2f}-{toss.max():.2f}); ball min z {z.min():.4f} m; "
            f"{cross.sum()} net crossings, {below.sum()} below the cord; players max speed "
            f"{np.nanmax(speed):.2f} m/s, max acceleration {accel.max():.2f} m/s^2; median "
            f"bounce speed ratio {np.median(ratio):.3f} (n={ok.sum()})")


def check_synth_physics(surfaces=("hard", "clay", "grass")) -> None:
    """Print `check` of each surface."""
    for surface in surfaces:
        print(check(surface))
