"""Interventions on the server after his serve: does a model's serve outcome depend on how the
server moves once the ball has left his racket?

The leak check (`sportsngen.eval.leaks`) reads correlations: a server who moves slower after
the serves that become aces. In the record (generator version 5) that was foresight, and a
model trained on it ran it backwards: a sampled server who stopped made the serve an ace. A
correlation can also have a common cause the check does not hold (the serve itself). This
module settles which by intervening: each serve is branched `after_frames` frames after its
strike (the flight is set), several times with the same seed, the server's track forced by
hand in each arm (`rollout`'s `forced_pos_m`) while the receiver and the ball stay the
model's:

- ``free``: nothing forced (the diagnostics' branches);
- ``recorded``: the server's own track in `data` after the branch point (the generator's, or
  for a model's own serves the model's);
- ``still``: the server stops at `STOP_ACCEL_MPS2` from his velocity at the branch point and
  stands (generator version 5's server after an ace);
- ``swapped``: the server's run after the branch point of another serve of the same serve
  number, turned to this one's end and side (a realistic run chosen without this serve's
  outcome).

Every forced track runs `horizon_s` past the branch point; one that ends sooner (the rally
ended) goes on by stopping. A model whose receivers do not read the server returns the same
share in every arm: the paired differences to ``recorded`` are 0 within their intervals.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import (
    BRANCH_AFTER_FRAMES,
    HORIZON_S,
    _generic_vocab,
    serve_outcomes,
    serve_strike_frames,
)
from sportsngen.eval.shot_branches import branch_rallies
from sportsngen.model.inputs import OBJECTS
from sportsngen.synth.profiles import PlayerProfile

ARMS = ("free", "recorded", "still", "swapped")
SERVER_SLOT = OBJECTS.index("server")
STOP_ACCEL_MPS2 = PlayerProfile.max_accel_mps2    # the generator's players' acceleration cap
SPEED_AFTER_FRAMES = 12    # the leak check's k: the server's speed this many frames on


def stopping_track(p0_m: np.ndarray, v0_mps: np.ndarray, n_frames: int, fps: float,
                   accel_mps2: float = STOP_ACCEL_MPS2) -> np.ndarray:
    """Players that brake from `p0_m` (n, 3) at velocity `v0_mps` (n, 3; its ground part) at
    `accel_mps2` until they stand -> (n, n_frames, 3), frame j at (j + 1) / fps; height held."""
    v = np.asarray(v0_mps, dtype=float)[:, :2]
    speed = np.hypot(v[:, 0], v[:, 1])
    unit = np.divide(v, speed[:, None], out=np.zeros_like(v), where=speed[:, None] > 0)
    t = np.minimum((np.arange(n_frames) + 1) / fps, (speed / accel_mps2)[:, None])
    dist = speed[:, None] * t - 0.5 * accel_mps2 * t ** 2                   # (n, n_frames)
    out = np.repeat(np.asarray(p0_m, dtype=float)[:, None, :], n_frames, axis=1)
    out[:, :, :2] += unit[:, None, :] * dist[:, :, None]
    return out


def _continue_by_stopping(track: np.ndarray, n_frames: int, fps: float) -> np.ndarray:
    """A (T, 3) track (T >= 2) carried on to `n_frames` frames by `stopping_track`."""
    if len(track) >= n_frames:
        return track[:n_frames]
    v = (track[-1] - track[-2]) * fps
    tail = stopping_track(track[-1:], v[None], n_frames - len(track), fps)[0]
    return np.concatenate([track, tail])


def server_forcing(data: RallyData, arm: str, horizon_s: float = HORIZON_S,
                   after_frames: int = BRANCH_AFTER_FRAMES, seed: int = 0
                   ) -> dict[int, np.ndarray]:
    """The server's forced track of `arm` for each serve of `data` -> rally id -> (T, 3, 3)
    positions from the rally's start, NaN but the server's frames after the branch point
    (`branch_rallies`' `forced_pos_m`). ``free``: an empty dict."""
    if arm not in ARMS:
        raise ValueError(f"arm must be one of {ARMS}, got {arm!r}")
    if arm == "free":
        return {}
    arr = rally_arrays(data, _generic_vocab(data))
    fps = float(data.fps)
    keep = serve_strike_frames(data) + after_frames + 1
    n_after = int(math.ceil(horizon_s * fps)) + 2
    rows = [(ri, int(rid), int(keep[rid])) for ri, rid in enumerate(arr.rally_id)
            if rid in keep.index and 2 <= keep[rid] < arr.length[ri]]
    if not rows:
        raise ValueError("no serve of the data is longer than its branch point")
    server = {rid: arr.pos_m[arr.start[ri]:arr.start[ri] + arr.length[ri], SERVER_SLOT]
              .astype(float) for ri, rid, _ in rows}
    runs = {}                                # the server's track from the last kept frame on
    for _, rid, k in rows:
        if arm == "still":
            p, v = server[rid][k - 1], (server[rid][k - 1] - server[rid][k - 2]) * fps
            runs[rid] = np.concatenate([p[None], stopping_track(p[None], v[None], n_after,
                                                                fps)[0]])
        else:
            runs[rid] = _continue_by_stopping(server[rid][k - 1:], n_after + 1, fps)
    if arm == "swapped":
        number = data.rallies.set_index("rally_id")["serve_number"]
        rng = np.random.default_rng(seed)
        swapped = {}
        for _, ids in pd.Series([r for _, r, _ in rows]).groupby(
                number.reindex([r for _, r, _ in rows]).to_numpy()):
            ids = ids.to_numpy()
            for rid, other in zip(ids, rng.permutation(ids)):
                # Each run is turned into its own server's frame (his end and side) and back.
                mirror = np.sign(runs[other][0, :2]) * np.sign(runs[rid][0, :2])
                step = (runs[other] - runs[other][0])
                step[:, :2] *= np.where(mirror == 0, 1.0, mirror)
                swapped[rid] = runs[rid][0] + step
        runs = swapped
    out = {}
    for _, rid, k in rows:
        f = np.full((k + n_after, 3, 3), np.nan, dtype=np.float32)
        f[k:, SERVER_SLOT] = runs[rid][1:]
        out[rid] = f
    return out


def _server_speed_mps(branches: RallyData, order: pd.Series, strike: pd.Series,
                      k: int = SPEED_AFTER_FRAMES) -> pd.Series:
    """Branch rally id -> the server's ground speed `k` frames after the recorded strike."""
    arr = rally_arrays(branches, _generic_vocab(branches))
    speed = {}
    for ri, rid in enumerate(arr.rally_id):
        f = int(strike[order[rid]]) + k
        if 1 <= f < arr.length[ri]:
            d = arr.pos_m[arr.start[ri] + f, SERVER_SLOT, :2] - \
                arr.pos_m[arr.start[ri] + f - 1, SERVER_SLOT, :2]
            speed[int(rid)] = float(np.hypot(*d)) * branches.fps
    return pd.Series(speed, dtype=float)


def intervention_outcomes(sim, data: RallyData, arms: tuple[str, ...] = ARMS, seed: int = 0,
                          horizon_s: float = HORIZON_S,
                          after_frames: int = BRANCH_AFTER_FRAMES) -> pd.DataFrame:
    """Each serve of `data` branched in every arm of `arms`, the same seed in each -> one row
    per serve and arm: arm, rally_id (of `data`), in_box, returned and the server's speed
    `SPEED_AFTER_FRAMES` frames after the strike (`server_speed_mps`)."""
    strike = serve_strike_frames(data)
    keep = strike + after_frames + 1
    parts = []
    for arm in arms:
        forced = server_forcing(data, arm, horizon_s, after_frames, seed)
        branches, order = branch_rallies(sim, data, keep, seed, horizon_s,
                                         forced_pos_m=forced if forced else None)
        parts.append(_arm_rows(arm, branches, order, strike))
    return pd.concat(parts, ignore_index=True)


def _arm_rows(arm: str, branches: RallyData, order: pd.Series, strike: pd.Series,
              out: pd.DataFrame | None = None, speed: bool = True) -> pd.DataFrame:
    """One arm's rows of `intervention_outcomes` from its branches (`out`: their
    `serve_outcomes`, when already read; `speed` False: the server's speed left NaN)."""
    out = (serve_outcomes(branches) if out is None else out).loc[order.index]
    return pd.DataFrame({
        "arm": arm, "rally_id": order.to_numpy(),
        "in_box": out["in_box"].to_numpy(bool), "returned": out["returned"].to_numpy(bool),
        "server_speed_mps": _server_speed_mps(branches, order, strike)
        .reindex(order.index).to_numpy() if speed else np.nan})


def stopped_server_gap(sim, data: RallyData, free: RallyData, free_order: pd.Series,
                       free_out: pd.DataFrame, seed: int, n_boot: int) -> pd.Series:
    """The diagnostics' intervention: the serves of `data` branched again with the server
    stopped (``still``), the same seed as their free branches (`free`, `free_order`, as
    `diagnostics.serve_branches` gave them, and their `serve_outcomes` `free_out`) -> the
    ``still`` row of `intervention_table` read against ``free``: diff, lo, hi, n_pairs."""
    strike = serve_strike_frames(data)
    forced = server_forcing(data, "still", seed=seed)
    still, order = branch_rallies(sim, data, strike + BRANCH_AFTER_FRAMES + 1, seed, HORIZON_S,
                                  forced_pos_m=forced)
    # The row reads the returns only: the server's speeds are not read.
    rows = pd.concat([_arm_rows("free", free, free_order, strike, free_out, speed=False),
                      _arm_rows("still", still, order, strike, speed=False)],
                     ignore_index=True)
    table = intervention_table(rows, base="free", n_boot=n_boot, seed=seed)
    return table.set_index("arm").loc["still", ["diff", "lo", "hi", "n_pairs"]]


def intervention_table(outcomes: pd.DataFrame, base: str = "recorded", n_boot: int = 1000,
                       seed: int = 0, level: float = 0.95) -> pd.DataFrame:
    """`intervention_outcomes` -> per arm: serves in the box, their return share, the server's
    median speed, and the return share minus `base`'s on the serves in the box in both arms
    (`diff`, with a bootstrap interval `lo`-`hi` over those serves; 0 for `base` itself)."""
    wide = outcomes.pivot(index="rally_id", columns="arm")
    if base not in wide["returned"].columns:
        raise ValueError(f"the outcomes have no {base!r} arm")
    rng = np.random.default_rng(seed)
    rows = []
    for arm in outcomes["arm"].unique():
        box = wide["in_box"][arm].astype(bool)
        both = (box & wide["in_box"][base].astype(bool)).to_numpy()
        d = (wide["returned"][arm].astype(float) - wide["returned"][base].astype(float)) \
            .to_numpy()[both]
        boots = [d[rng.integers(0, len(d), len(d))].mean() for _ in range(n_boot)] \
            if len(d) and n_boot else [np.nan]
        lo, hi = np.quantile(boots, [(1 - level) / 2, (1 + level) / 2])
        rows.append({"arm": arm, "n_in_box": int(box.sum()),
                     "returned": float(wide["returned"][arm][box].mean()) if box.any()
                     else np.nan,
                     "server_speed_mps": float(wide["server_speed_mps"][arm].median()),
                     "diff": float(d.mean()) if len(d) else np.nan,
                     "lo": float(lo), "hi": float(hi), "n_pairs": int(len(d))})
    return pd.DataFrame(rows)
