"""The players alone: rollouts in which the ball flies as recorded and only the players are the
model's, and how often the ball then passes out of their reach.

A simulated rally ball lost beyond a player's reach (`eval.reach`, by gap) may be lost because
the model's ball went where no player could reach it or because the model's player did not go
where the ball went. Handing the players the record's ball separates the two: each recorded
rally is branched `after_frames` frames after its serve's contact, every later frame the ball is
set to the record's and both players are drawn by the model, and at each recorded contact after
the serve the player who made it is measured against the ball's path:

- ``gap_m``: how close the ball's path came to him (horizontally, below `REACH_MAX_Z_M`) from
  `SETTLE_FRAMES` frames after the contact before it to `PAST_FRAMES` frames past his own,
  the path past the contact flown on by physics (`model.forecast.ball_forecast`, as if he had
  let it go), so a player who would take the ball a metre deeper is not counted as missing it;
- ``gap_record_m``: the same for the record's player (0.5-0.8 m, a racket's reach);
- ``run_m``: how far the record's player ran from the contact before to his own;
- ``along_m_<k>``: how far each had run toward the record's contact `k` frames after the
  contact before (`along_record_m_<k>` the record's).

A model whose players reach every ball the record's reached has rows with gap_m near
gap_record_m at every run length; `chase_table` gives the share beyond `FAR_M` by shot and by
run length, the model beside the record.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.reach import REACH_MAX_Z_M
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.model.forecast import STEP_S, ball_forecast
from sportsngen.model.inputs import BALL
from sportsngen.sim.constraints import KeepChasing
from sportsngen.sim.frame_draws import redraw_rejected
from sportsngen.sim.rollout import cpu_threads, step_features, window_features
from sportsngen.tennis.rally import RallyTracker

AFTER_FRAMES = 3           # the branch: frames kept after the serve's contact
SETTLE_FRAMES = 5          # the path read from this many frames after the contact before
PAST_FRAMES = 15           # ... to this many past the player's own contact, flown on
FAR_M = 1.5                # a ball passing further than this was out of his reach
ALONG_FRAMES = tuple(range(0, 45, 5))
RUN_BINS_M = (0.0, 1.0, 2.0, 3.0, 4.0, 30.0)


def _path_on(ball: np.ndarray, frame: int, fps: float) -> np.ndarray:
    """The recorded ball up to `frame` (exclusive), then flown on by physics for
    `PAST_FRAMES` frames from its last three frames before it: (frame + PAST_FRAMES, 3).
    A frame's difference is the velocity half a frame earlier (under gravity, 0.2 m/s off
    at the frame itself), so the flight starts midway between the last two frames."""
    mid = torch.as_tensor((ball[frame - 1] + ball[frame - 2]) / 2, dtype=torch.float32)[None]
    v = torch.as_tensor((ball[frame - 1] - ball[frame - 2]) * fps, dtype=torch.float32)[None]
    pv = torch.as_tensor((ball[frame - 2] - ball[frame - 3]) * fps, dtype=torch.float32)[None]
    track = ball_forecast(mid, v, pv, fps, path=True)[1][0].numpy()
    t_rows = (np.arange(len(track)) + 1) * STEP_S          # the path's rows, from mid
    t_frames = (np.arange(PAST_FRAMES) + 1.5) / fps        # frames frame.. from mid
    on = np.stack([np.interp(t_frames, t_rows, track[:, a]) for a in range(3)], axis=1)
    return np.concatenate([ball[:frame], on], axis=0)


def path_gap_m(player_xy: np.ndarray, path: np.ndarray, lo: int, hi: int) -> float:
    """The least horizontal distance between a player's track (T, 2) and the ball's `path`
    (T', 3) over frames lo..hi (inclusive, clipped to both), where the ball is below
    `REACH_MAX_Z_M`; NaN where there is no such frame."""
    hi = min(hi, len(player_xy) - 1, len(path) - 1)
    if hi < lo:
        return float("nan")
    b = path[lo:hi + 1]
    ok = b[:, 2] < REACH_MAX_Z_M
    if not ok.any():
        return float("nan")
    return float(np.linalg.norm(player_xy[lo:hi + 1] - b[:, :2], axis=1)[ok].min())


def _along(track: np.ndarray, record: np.ndarray, lo: int, hi: int, k: int) -> float:
    """How far `track` (T, 2) ran from frame lo over k frames along the record's run from lo
    to hi."""
    u = record[hi] - record[lo]
    n = float(np.linalg.norm(u))
    if n < 1e-6 or lo + k >= len(track):
        return float("nan")
    return float((track[lo + k] - track[lo]) @ (u / n))


@torch.no_grad()
def players_on_the_record(model, vocab, truth: RallyData, after_frames: int = AFTER_FRAMES,
                          top_p_player: float = 1.0, seed: int = 0,
                          max_rallies: int | None = None,
                          keep_chasing: bool = False) -> pd.DataFrame:
    """Each recorded rally with a return, branched `after_frames` frames after its serve's
    contact and rolled out with the ball set to the record's every frame (module doc) -> one
    row per recorded contact after the serve: rally_id, shot (1 the return), role, player,
    gap_m, gap_record_m, run_m, frames (from the contact before), along_m_<k> and
    along_record_m_<k>. `keep_chasing`: the players are drawn under the simulator's rule
    that a player late for the ball does not slow down (`sim.constraints.KeepChasing`)."""
    if after_frames < 1:
        raise ValueError(f"after_frames must be >= 1, got {after_frames}")
    rules = analyse_rally_data(truth)
    arr = rally_arrays(truth, vocab, unknown="generic")
    rallies = truth.rallies.set_index("rally_id")
    groups: dict[int, list[int]] = {}
    for ri, rid in enumerate(arr.rally_id):
        contacts = list(rules.loc[rid, "contact_frames"])
        k = contacts[0] + after_frames if contacts else -1
        if len(contacts) >= 2 and 3 <= k < contacts[1]:
            groups.setdefault(k, []).append(ri)
    picked = sorted(ri for idx in groups.values() for ri in idx)
    if max_rallies is not None:
        keep = set(picked[:max_rallies])
        groups = {k: [i for i in idx if i in keep] for k, idx in groups.items()}
        groups = {k: idx for k, idx in groups.items() if idx}
    if not groups:
        raise ValueError("no recorded rally has a return to branch before")
    fps = model.cfg.fps
    dev = next(model.parameters()).device
    gen = torch.Generator(device=dev)
    gen.manual_seed(int(seed))
    rows = []
    model.eval()
    with cpu_threads(None):
        for k, idx in sorted(groups.items()):
            length = int(max(arr.length[i] for i in idx))
            rec = np.stack([np.concatenate([arr.pos_m[arr.start[i]:arr.start[i] + arr.length[i]],
                                            np.repeat(arr.pos_m[arr.start[i] + arr.length[i]
                                                                - 1][None],
                                                      length - arr.length[i], axis=0)])
                            for i in idx]).astype(np.float32)        # (B, L, 3, 3)
            hist = torch.as_tensor(rec, device=dev).clone()
            ident = torch.as_tensor(arr.ident[idx], device=dev)
            ctx = model.context_tokens(*(torch.as_tensor(a[idx], device=dev) for a in (
                arr.surface, arr.tournament, arr.serve)),
                torch.as_tensor(arr.score[idx], device=dev, dtype=torch.float32))
            hs, cache = model(window_features(hist, 0, k, fps), ident, ctx, return_cache=True)
            h = hs[:, -1]
            rule, rows_b = None, np.arange(len(idx))
            if keep_chasing:
                plan = rallies.loc[arr.rally_id[idx]]
                tracker = RallyTracker(plan["server_end"].to_numpy(), plan["side"].to_numpy(),
                                       plan["serve_number"].to_numpy(), fps, 1e6)
                for q in range(k):
                    tracker.update(rec[:, q])
                rule = KeepChasing(tracker, fps=fps)
            for n in range(k, length):
                if n > k:
                    h = model.forward_step(step_features(hist, n, fps), cache)[0]
                pos = hist[:, n - 1]
                vel = (pos - hist[:, n - 2]) * fps
                prev_vel = (hist[:, n - 2] - hist[:, n - 3]) * fps
                nxt = model.sample_next(h, pos, vel, top_p_player, 1.0, gen, prev_vel)
                nxt[:, BALL] = hist[:, n, BALL]
                if rule is not None:
                    nxt = redraw_rejected(model, rule, rows_b, n, h, pos, vel, prev_vel, nxt,
                                          top_p_player, 1.0, gen)[0]
                    nxt[:, BALL] = hist[:, n, BALL]
                    tracker.update(nxt.cpu().numpy())
                hist[:, n, :BALL] = nxt[:, :BALL]
            out = hist.cpu().numpy()
            for j, i in enumerate(idx):
                rid = arr.rally_id[i]
                rows.extend(_contact_rows(rid, rallies.loc[rid], out[j, :arr.length[i]],
                                          rec[j, :arr.length[i]],
                                          list(rules.loc[rid, "contact_frames"]), fps))
    return pd.DataFrame(rows)


def _contact_rows(rid, rally, sim: np.ndarray, rec: np.ndarray, contacts: list[int],
                  fps: float) -> list[dict]:
    rows = []
    for s in range(1, len(contacts)):
        f, lo = contacts[s], contacts[s - 1]
        if f >= len(rec) or f < 3:
            continue
        p = 0 if s % 2 == 0 else 1          # the server plays the even shots
        path = _path_on(rec[:, BALL], f, fps)
        a, b = lo + SETTLE_FRAMES, f + PAST_FRAMES
        row = {"rally_id": int(rid), "shot": s, "role": "server" if p == 0 else "receiver",
               "player": str(rally["server" if p == 0 else "receiver"]),
               "gap_m": path_gap_m(sim[:, p, :2], path, a, b),
               "gap_record_m": path_gap_m(rec[:, p, :2], path, a, b),
               "run_m": float(np.linalg.norm(rec[f, p, :2] - rec[lo, p, :2])),
               "frames": f - lo}
        for q in ALONG_FRAMES:
            row[f"along_m_{q}"] = _along(sim[:, p, :2], rec[:, p, :2], lo, f, q)
            row[f"along_record_m_{q}"] = _along(rec[:, p, :2], rec[:, p, :2], lo, f, q)
        rows.append(row)
    return rows


def chase_table(rows: pd.DataFrame, far_m: float = FAR_M) -> pd.DataFrame:
    """Rows of `players_on_the_record` -> by group ("shot k", the shots from 4 on together,
    "run a-b m" over the shots after the return, and "all after the return"): n, the median
    gap of the model's and the record's player, and the share of balls passing beyond `far_m`
    of each."""
    def summary(name, d):
        return {"group": name, "n": len(d), "gap_m": d["gap_m"].median(),
                "gap_record_m": d["gap_record_m"].median(),
                "far": float((d["gap_m"] > far_m).mean()),
                "far_record": float((d["gap_record_m"] > far_m).mean())}
    out = []
    shot = rows["shot"].clip(upper=4)
    for s in sorted(shot.unique()):
        out.append(summary(f"shot {s}" + ("+" if s == 4 else ""), rows[shot == s]))
    later = rows[rows["shot"] >= 2]
    bins = pd.cut(later["run_m"], RUN_BINS_M, right=False)
    for interval, d in later.groupby(bins, observed=True):
        out.append(summary(f"run {interval.left:g}-{interval.right:g} m", d))
    out.append(summary("all after the return", later))
    return pd.DataFrame(out)


def along_table(rows: pd.DataFrame, min_run_m: float = 3.0) -> pd.DataFrame:
    """Rows of `players_on_the_record` -> the median run toward the record's contact, frame by
    frame from the contact before (`ALONG_FRAMES`), of the model's player and the record's, on
    the shots after the return whose record ran at least `min_run_m`: where the model's run
    falls behind."""
    d = rows[(rows["shot"] >= 2) & (rows["run_m"] >= min_run_m)]
    return pd.DataFrame({"frames after the contact before": list(ALONG_FRAMES),
                         "model (m)": [d[f"along_m_{q}"].median() for q in ALONG_FRAMES],
                         "record (m)": [d[f"along_record_m_{q}"].median()
                                        for q in ALONG_FRAMES]}).set_index(
        "frames after the contact before").T.reset_index(names="")
