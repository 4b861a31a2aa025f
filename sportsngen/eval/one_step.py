"""What the decoder's next frame depends on: frames drawn one step from the record's history.

A rollout compounds its own errors, so a dependence found in rollouts may be the decoder's or
the drift's. One frame drawn from each recorded rally's own frames before it separates them:
the state is the record's, and only the draw is the model's. Set beside the record's own next
frame, a dependence the record lacks is the decoder's fit.

The one it reads (`server_serve_coupling`): the model's server ran back slower after faster
serves on its own serves (rank correlation about -0.3 within first serves, the record's about
0), which put the leak check's cell of his speed 12 frames after an ace below its band
(docs/evaluation.md, sixty-fifth part) until the check held the serve's seen pace (sixty-seventh
part): a dependence on what he saw is no leak, but the record's server has none, so it is a
fault of fidelity, read here. Drawn one step from the record, the coupling is there
9 frames after the strike (second serves: about -0.5, where the record's run is one profile), with
the simulator's rules switched off too: the decoder's own, not the rollout's drift
(sixty-sixth part). Ranks magnify it: in speed it is 0.14-0.15 m/s per 10 m/s of second-serve
speed, where the record's server runs the same profile after every second serve.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy.stats import spearmanr

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import _generic_vocab, serve_strike_frames
from sportsngen.eval.shot_branches import branch_rallies
from sportsngen.model.inputs import OBJECTS

SERVER_SLOT = OBJECTS.index("server")
COUPLING_AFTER_FRAMES = 9   # the server's speed this many frames after the serve's strike
COUPLING_DRAWS = 8          # draws of that frame per serve
PACE_SCALES = (0.9, 1.1)    # the serve's pace re-flown at these factors (server_pace_response)
# Draws a serve at each pace: half of 8's time (9.1 against 17.9 s on seed 1's 400 points) for
# a second-serve slope of -0.125 +- 0.017 against -0.114 +- 0.015 m/s per 10 m/s.
PACE_DRAWS = 4


def one_step_frames(sim, data: RallyData, frames: pd.Series, draws: int = COUPLING_DRAWS,
                    seed: int = 0) -> dict[int, np.ndarray]:
    """Rally id -> (draws, 3, 3): frame `frames[rid]` (counted from the rally's first) drawn
    `draws` times by `sim` (its rules applied) from the record's frames before it. Rallies
    whose track does not reach that frame are left out."""
    if draws < 1:
        raise ValueError(f"draws must be at least 1, got {draws}")
    # Only the positions are read: the event classifier's labels (a whole padded window a
    # branch, half of this function's time) are left out.
    out, order = branch_rallies(sim, data, frames, seed, 1.0 / sim.fps, copies=draws,
                                label_events=False)
    arr = rally_arrays(out, _generic_vocab(out))
    got: dict[int, list[np.ndarray]] = {}
    for i, bid in enumerate(arr.rally_id):
        rid = int(order[bid])
        f = int(frames[rid])
        if arr.length[i] > f:
            got.setdefault(rid, []).append(arr.pos_m[arr.start[i] + f])
    return {rid: np.stack(v) for rid, v in got.items()}


def _drawn_server_speeds(arr, fps: float, drawn: dict[int, np.ndarray],
                         frames: pd.Series) -> tuple[pd.Series, pd.Series]:
    """The server's ground speed (m/s) at each rally's frame `frames[rid]`: drawn (mean of
    the draws in `drawn`) and recorded, both from the record's frame before it (`arr`, the
    record's `rally_arrays`), rounded to 1 mm/s as the leak check's speeds (positions are
    float32, and finer differences are rounding, which ranks would read as an order)."""
    where = dict(zip(arr.rally_id.tolist(), arr.start.tolist()))
    model, record = {}, {}
    for rid, d in drawn.items():
        at = where[rid] + int(frames[rid])
        before = arr.pos_m[at - 1, SERVER_SLOT, :2]
        speed = np.linalg.norm(d[:, SERVER_SLOT, :2] - before, axis=-1).mean()
        model[rid] = round(float(speed) * fps, 3)
        record[rid] = round(float(np.linalg.norm(arr.pos_m[at, SERVER_SLOT, :2] - before))
                            * fps, 3)
    return pd.Series(model, dtype=float), pd.Series(record, dtype=float)


def server_serve_coupling(sim, data: RallyData, after_frames: int = COUPLING_AFTER_FRAMES,
                          draws: int = COUPLING_DRAWS, seed: int = 0) -> pd.DataFrame:
    """The server's ground speed `after_frames` after each recorded serve's strike, drawn one
    step from the record (mean of `draws`) and recorded, against the serve's speed -> per serve
    number: n, the rank correlations (`model_corr`, `record_corr`), the least-squares slopes
    (`model_slope`, `record_slope`: m/s of his speed per 10 m/s of the serve's) and the median
    speeds (m/s). Ranks magnify a small dependence where the record's speed barely varies;
    the slopes give its size.
    The record's servers run back the same way whatever the serve's speed (generator version
    6: their recovery is planned before the serve's fate is known)."""
    strike = serve_strike_frames(data)
    frames = strike + after_frames
    model, record = _drawn_server_speeds(rally_arrays(data, _generic_vocab(data)), data.fps,
                                         one_step_frames(sim, data, frames, draws, seed), frames)
    serves = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")["speed_mps"]
    number = data.rallies.set_index("rally_id")["serve_number"]
    table = pd.DataFrame({"serve_number": number.reindex(model.index),
                          "serve_mps": serves.reindex(model.index),
                          "model_mps": model, "record_mps": record}).dropna()
    out = []
    for n, g in table.groupby("serve_number"):
        ok = len(g) >= 3 and g["serve_mps"].nunique() > 1
        row = {"serve_number": int(n), "n": len(g)}
        for side in ("model", "record"):
            speed = g[f"{side}_mps"]
            # One speed for every serve has no order to correlate (NaN).
            row[f"{side}_corr"] = float(spearmanr(speed, g["serve_mps"])[0]) \
                if ok and speed.nunique() > 1 else np.nan
            row[f"{side}_slope"] = float(np.polyfit(g["serve_mps"], speed, 1)[0]) * 10.0 \
                if ok else np.nan
        out.append({**row, "model_median_mps": float(g["model_mps"].median()),
                    "record_median_mps": float(g["record_mps"].median())})
    return pd.DataFrame(out)


def paced_serves(data: RallyData, scale: float, until_frames: int) -> RallyData:
    """The record with each serve's ball re-flown at `scale` times its pace on the same path:
    its positions at strike + 1 .. strike + `until_frames` - 1 moved to the strike's ball
    position plus `scale` times their displacement from it. Nothing else changes (the players'
    tracks, the later frames, the tables)."""
    if scale <= 0:
        raise ValueError(f"scale must be positive, got {scale}")
    f = data.frames
    first = f.groupby("rally_id")["frame"].min()
    strike = serve_strike_frames(data)
    rel = (f["frame"] - f["rally_id"].map(first)).to_numpy()
    at = f["rally_id"].map(strike).to_numpy(dtype=float)       # NaN: no serve
    ball = (f["object"] == "ball").to_numpy()
    moved = ball & (rel > at) & (rel < at + until_frames)
    origin = f[ball & (rel == at)].set_index("rally_id")[["x", "y", "z"]]
    xyz = f.loc[moved, ["x", "y", "z"]].to_numpy(float)
    o = origin.reindex(f.loc[moved, "rally_id"]).to_numpy(float)
    frames = f.copy()
    frames.loc[moved, ["x", "y", "z"]] = o + scale * (xyz - o)
    return replace(data, frames=frames)


def server_pace_response(sim, data: RallyData, after_frames: int = COUPLING_AFTER_FRAMES,
                         scales: tuple[float, float] = PACE_SCALES,
                         draws: int = PACE_DRAWS, seed: int = 0) -> pd.DataFrame:
    """What the ball's pace does to the server's draw, all else held: each recorded serve's
    ball re-flown at the two `scales` of its pace on its own path up to the frame before
    strike + `after_frames` (`paced_serves`), that frame drawn one step (`draws` times, the
    same seed for both), and the server's speed there compared -> per serve number: n, the
    mean over serves of his speed's change per 10 m/s of the serve's pace (`slope`, m/s) and
    its standard error (`se`), and his mean speeds at each scale. The record's server has no
    such dependence (his run is planned at the strike); `server_serve_coupling` reads the
    dependence across serves, this the part the ball causes."""
    lo, hi = scales
    if not 0 < lo < hi:
        raise ValueError(f"scales must be two increasing positive factors, got {scales}")
    frames = serve_strike_frames(data) + after_frames
    arr = rally_arrays(data, _generic_vocab(data))    # the players' frames: any pace's
    speeds = [_drawn_server_speeds(arr, data.fps, one_step_frames(
        sim, paced_serves(data, s, after_frames), frames, draws, seed), frames)[0]
        for s in scales]
    serves = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")["speed_mps"]
    number = data.rallies.set_index("rally_id")["serve_number"]
    table = pd.DataFrame({"lo": speeds[0], "hi": speeds[1]}).dropna()
    table["slope"] = (table["hi"] - table["lo"]) / ((hi - lo) * serves.reindex(table.index)) * 10
    table["serve_number"] = number.reindex(table.index)
    out = []
    for n, g in table.dropna().groupby("serve_number"):
        se = float(g["slope"].std(ddof=1) / np.sqrt(len(g))) if len(g) > 1 else np.nan
        out.append({"serve_number": int(n), "n": len(g), "slope": float(g["slope"].mean()),
                    "se": se, "lo_mps": float(g["lo"].mean()), "hi_mps": float(g["hi"].mean())})
    return pd.DataFrame(out)
