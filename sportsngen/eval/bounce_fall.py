"""How fast the ball falls after its bounces: the spin a bounce gives, read from any track.

A bounce's friction gives a rally ball topspin, and the rising ball then falls faster than
gravity and drag alone take it: the generator's clay and hard rally balls fall at a median
12.5-13.5 m/s^2 in the frames after a bounce (gravity and drag alone: about 10.3). The
free-flight residual (`eval.flight`) cannot see a ball that has lost that spin, because the
physics centre reads the spin from the track itself: a spinless track is a consistent one.
Read here from the positions alone (the second difference of the height, frames after the
bounce), data and rollouts alike, it found the bundled file's rollouts falling at 10.8-12.0
m/s^2, their rally balls met high (docs/evaluation.md, fiftieth part).

A bounce is a frame where the ball is below `BOUNCE_Z_M`, lower than the frames either side,
and rises by at least `MIN_RISE_M` into the next (a rolling or a dead ball is none); a frame
counts up to the frame before the next racket contact (the shots table's frames).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

BOUNCE_Z_M = 0.12
MIN_RISE_M = 0.04          # 1 m/s upward at 25 frames a second
AFTER_FRAMES = (2, 4, 6, 8)


def post_bounce_fall(data, after_frames: Sequence[int] = AFTER_FRAMES,
                     fps: float = 25.0) -> pd.DataFrame:
    """`data` (a `RallyData`, or anything with its `frames` and `shots` tables) -> one row per
    j in `after_frames` (each >= 2, so the second difference holds no bounce frame): n (ball
    frames j after a bounce, before the next contact) and the median and quartiles of the
    ball's vertical acceleration there (m/s^2, the second difference of its height centred on
    that frame; negative is down)."""
    if any(int(j) < 2 for j in after_frames):
        raise ValueError(f"after_frames must all be 2 or more, got {list(after_frames)}")
    ball = data.frames[data.frames["object"] == "ball"].sort_values(["rally_id", "frame"])
    contacts = {rid: np.sort(g.to_numpy()) for rid, g in
                data.shots.groupby("rally_id")["frame"]}
    want = np.asarray(after_frames, dtype=int)
    found: list[np.ndarray] = [np.zeros((0, 2))]
    for rid, g in ball.groupby("rally_id", sort=False):
        z = g["z"].to_numpy(float)
        frame = g["frame"].to_numpy(int)
        if len(z) < 4:
            continue
        mid = z[1:-1]
        k = np.flatnonzero((mid < BOUNCE_Z_M) & (mid <= z[:-2]) & (z[2:] - mid >= MIN_RISE_M)) + 1
        if len(k) == 0:
            continue
        hits = contacts.get(rid, np.zeros(0, dtype=int))
        # The first contact after each bounce, as an index into this rally's frames.
        nxt = np.searchsorted(frame, hits)
        after = np.searchsorted(nxt, k, side="right")
        stop = np.where(after < len(nxt), nxt[np.minimum(after, len(nxt) - 1)], len(z))
        c = k[:, None] + want[None, :]                                   # (bounces, j)
        ok = (c + 1 < stop[:, None]) & (c + 1 < len(z))
        cc = np.where(ok, c, 1)
        acc = (z[np.minimum(cc + 1, len(z) - 1)] - 2 * z[cc] + z[cc - 1]) * fps * fps
        found.append(np.stack([np.broadcast_to(want, c.shape)[ok], acc[ok]], axis=1))
    rows = np.concatenate(found)
    out = []
    for j in want:
        a = rows[rows[:, 0] == j, 1]
        q = np.quantile(a, [0.25, 0.5, 0.75]) if len(a) else [np.nan] * 3
        out.append({"frames_after": int(j), "n": int(len(a)), "q25_mps2": float(q[0]),
                    "median_mps2": float(q[1]), "q75_mps2": float(q[2])})
    return pd.DataFrame(out)


def format_bounce_fall(sim: pd.DataFrame, truth: pd.DataFrame) -> str:
    """One line per frame after the bounce: n and the median fall, sim / truth."""
    lines = [f"{'frames after':>12} {'n':>13} {'median m/s²':>15}"]
    for (_, s), (_, t) in zip(sim.iterrows(), truth.iterrows()):
        lines.append(f"{int(s['frames_after']):>12} {int(s['n']):>6} / {int(t['n']):<6}"
                     f" {s['median_mps2']:>6.2f} / {t['median_mps2']:<6.2f}")
    return "\n".join(lines)
