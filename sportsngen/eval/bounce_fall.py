"""How fast the ball falls after its bounces: the spin a bounce gives, read from any track.

A bounce's friction gives a rally ball topspin, and the rising ball then falls faster than
gravity and drag alone take it: the generator's clay and hard rally balls fall at a median
12.5-13.5 m/s^2 in the frames after a bounce (gravity and drag alone: about 10.3). The
free-flight residual (`eval.flight`) cannot see a ball that has lost that spin, because the
physics centre reads the spin from the track itself: a spinless track is a consistent one.
Read here from the positions alone (the second difference of the height, frames after the
bounce), data and rollouts alike, it found the bundled file's rollouts falling at 10.8-12.0
m/s^2, their rally balls met high (docs/evaluation.md, fiftieth part).

Bounces and racket contacts are the rally rules' (`eval.physical.rally_events`, as
`bounce_ratios` reads them); a frame counts up to the frame before the next contact.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from sportsngen.eval.physical import iter_tracks, rally_events
from sportsngen.tennis.rally import BALL

AFTER_FRAMES = (2, 4, 6, 8)


def fall_after_bounces(z_m: np.ndarray, bounce_frames, contact_frames,
                       after_frames: Sequence[int] = AFTER_FRAMES,
                       fps: float = 25.0) -> np.ndarray:
    """One ball track's heights `z_m` (T,), its bounce and contact frames (indices into it) ->
    (n, 2) rows (j, vertical acceleration m/s^2): the second difference of the height centred
    j frames after each bounce, for each j in `after_frames` (each >= 2, so it holds no bounce
    frame) whose three frames all come before the next contact and inside the track."""
    want = np.asarray(after_frames, dtype=int)
    if (want < 2).any():
        raise ValueError(f"after_frames must all be 2 or more, got {list(after_frames)}")
    z = np.asarray(z_m, dtype=float)
    k = np.asarray(bounce_frames, dtype=int).reshape(-1)
    hits = np.sort(np.asarray(contact_frames, dtype=int).reshape(-1))
    if len(k) == 0 or len(z) < 3:
        return np.zeros((0, 2))
    after = np.searchsorted(hits, k, side="right")
    stop = np.where(after < len(hits), hits[np.minimum(after, len(hits) - 1)], len(z))
    stop = np.minimum(stop, len(z))
    c = k[:, None] + want[None, :]                                       # (bounces, j)
    ok = c + 1 < stop[:, None]
    cc = np.where(ok, c, 1)                  # a masked row reads frames 0-2 (len(z) >= 3)
    acc = (z[cc + 1] - 2 * z[cc] + z[cc - 1]) * fps * fps
    return np.stack([np.broadcast_to(want, c.shape)[ok], acc[ok]], axis=1)


def post_bounce_fall(data, after_frames: Sequence[int] = AFTER_FRAMES) -> pd.DataFrame:
    """`data` (a `RallyData`) -> one row per j in `after_frames`: n (ball frames j after a
    bounce, before the next contact) and the median and quartiles of the ball's vertical
    acceleration there (m/s^2, `fall_after_bounces`; negative is down), over every rally."""
    found: list[np.ndarray] = [np.zeros((0, 2))]
    for tr in iter_tracks(data):
        events = rally_events(tr, data.fps)
        for i, rid in enumerate(tr.rallies["rally_id"].to_numpy()):
            if rid not in events.index:
                continue
            e = events.loc[rid]
            found.append(fall_after_bounces(tr.pos_m[i, :tr.length[i], BALL, 2],
                                            e["bounce_frames"], e["contact_frames"],
                                            after_frames, data.fps))
    rows = np.concatenate(found)
    out = []
    for j in np.asarray(after_frames, dtype=int):
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
