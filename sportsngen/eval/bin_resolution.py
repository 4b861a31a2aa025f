"""What the output bins themselves cost a rollout, measured without any model.

A model samples a bin, then a point inside it, so even a perfect model places each frame only
to within its bin. Two measurements of what that does to the ball (`docs/evaluation.md`):

- `centre_noise_drift`: a ball flying free, every frame in the centre bin, the point drawn
  uniformly inside it, each next centre the ball centre of `sportsngen.model.centre`. The
  physics step reads the acceleration from the last three frames, so that noise is integrated
  three times; the constant-velocity or gravity-and-drag steps integrate it twice. Returns how
  far the flight drifts from the same flight without noise.
- `serves_redrawn_in_bins`: recorded serves whose two frames after the strike (where the
  ball's offset is large and the bins wide) are drawn again inside their own bins, then flown on
  by the physics step to the first bounce. Returns the share landing in the service box, against
  the record and against the same flight loop on the unchanged record.
- `strikes_redrawn_in_bins`: the same for the strikes after the serve (share landing in the
  opponent's singles court), also with each bin split into parts as a sub-bin head would
  (`ModelConfig.ball_sub_bins`) and the recorded part kept.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import serve_strike_frames
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.model.bins import Bins
from sportsngen.model.bins import ball_bins as model_ball_bins
from sportsngen.model.centre import (
    BALL_RADIUS_M,
    ball_acceleration_mps2,
    flight_acceleration_mps2,
    physics_step_m,
)
from sportsngen.model.config import ModelConfig
from sportsngen.model.inputs import BALL
from sportsngen.tennis.court import is_in_service_box, is_in_singles

MAX_FLIGHT_FRAMES = 80


def ball_bins(n_bins: int = 61, spacing: str = "nonuniform", fps: float = 25.0) -> Bins:
    """The ball's bins of a model with these settings (the default range otherwise), as the
    decoder builds them."""
    return model_ball_bins(ModelConfig(n_bins=n_bins, bin_spacing=spacing, fps=fps))


def centre_noise_drift(n_flights: int = 2000, frames: tuple[int, ...] = (10, 25, 50),
                       use_track_acceleration: bool = True, n_bins: int = 61,
                       spacing: str = "nonuniform", fps: float = 25.0,
                       seed: int = 0) -> dict[int, np.ndarray]:
    """90th percentile of |noisy - exact| position (m, per axis) after each of `frames` frames
    of a 30 m/s rally ball's free flight whose every frame falls in the centre bin, placed
    uniformly inside it; the centre is the physics step, reading the track's acceleration or
    (`use_track_acceleration=False`) gravity and drag alone."""
    gen = torch.Generator().manual_seed(seed)
    half = ball_bins(n_bins, spacing, fps).width(torch.full((3,), n_bins // 2)).double() / 2
    pos = torch.tensor([-11.0, 0.0, 1.0], dtype=torch.float64).repeat(n_flights, 1)
    vel = torch.tensor([30.0, 1.0, 6.0], dtype=torch.float64).repeat(n_flights, 1)
    hist = [pos.clone()]
    for _ in range(2):                       # two clean frames: a velocity and an acceleration
        acc = flight_acceleration_mps2(vel)
        pos = pos + vel / fps + acc / fps ** 2
        vel = vel + acc / fps
        hist.append(pos.clone())
    noisy, exact = list(hist), list(hist)
    out = {}
    for t in range(1, max(frames) + 1):
        for track, noise in ((noisy, True), (exact, False)):
            v = (track[-1] - track[-2]) * fps
            pv = (track[-2] - track[-3]) * fps if use_track_acceleration else None
            nxt = physics_step_m(track[-1], v, pv, fps)
            if noise:
                u = torch.rand(n_flights, 3, generator=gen, dtype=torch.float64)
                nxt = nxt + (2 * u - 1) * half
            track.append(nxt)
        if t in frames:
            out[t] = (noisy[-1] - exact[-1]).abs().quantile(0.9, dim=0).numpy()
    return out


def _first_bounce_m(track: list[torch.Tensor], fps: float) -> tuple[float, float] | None:
    """Fly the ball on from the last three frames of `track` by the physics step (no bounce
    inside a step) to where it reaches the ground: (x, y), or None within
    `MAX_FLIGHT_FRAMES`."""
    hist = list(track)
    for _ in range(MAX_FLIGHT_FRAMES):
        pos, vel = hist[-1], (hist[-1] - hist[-2]) * fps
        acc = ball_acceleration_mps2(vel, (hist[-2] - hist[-3]) * fps, fps)
        nxt = pos + vel / fps + acc / fps ** 2
        if nxt[2] < BALL_RADIUS_M:
            s = (pos[2] - BALL_RADIUS_M) / (pos[2] - nxt[2])
            x, y = (pos[:2] + s * (nxt[:2] - pos[:2])).tolist()
            return x, y
        hist.append(nxt)
    return None


def _landing_in_box(track: list[torch.Tensor], server_end: int, side: str, fps: float) -> bool:
    """Does the ball flown on from `track` (`_first_bounce_m`) land in the service box?"""
    xy = _first_bounce_m(track, fps)
    return xy is not None and bool(is_in_service_box(*xy, server_end, side))


def _redraw(track: list[torch.Tensor], frames: tuple[int, ...], bins: Bins, fps: float,
            gen: torch.Generator, n_sub: int = 0) -> list[torch.Tensor]:
    """`track` with `frames` drawn again inside their own bins around the physics step, in
    order (each next centre from the frames already re-drawn): uniformly inside the bin, or,
    with `n_sub`, inside the recorded offset's own part of the bin split `n_sub` ways (what a
    sub-bin head that knew the part would leave)."""
    track = list(track)
    for k in frames:
        centre = physics_step_m(track[k - 1], (track[k - 1] - track[k - 2]) * fps,
                                (track[k - 2] - track[k - 3]) * fps, fps)
        off = (track[k] - centre).float()[None]
        idx = bins.index(off)
        u = torch.rand(1, 3, generator=gen)
        if n_sub:
            u = (bins.sub_index(off, idx, n_sub) + u) / n_sub
        track[k] = centre + bins.value(idx, u)[0].double()
    return track


def serves_redrawn_in_bins(truth: RallyData, n_bins: int = 61, spacing: str = "nonuniform",
                           seed: int = 0) -> dict[str, float]:
    """Shares of recorded serves landing in the box: as recorded (the rules' first bounce),
    flown on from the record by the physics step ("loop", the method's own error), and with
    the two frames after the strike re-drawn uniformly inside their bins ("redrawn"); plus
    `n`, the serves counted (those with a bounce)."""
    fps = float(truth.fps)
    bins = ball_bins(n_bins, spacing, fps)
    gen = torch.Generator().manual_seed(seed)
    rules = analyse_rally_data(truth)
    arr = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    strike = serve_strike_frames(truth)
    counts = {"record": 0, "loop": 0, "redrawn": 0, "n": 0}
    for ri, rid in enumerate(arr.rally_id):
        rule = rules.loc[rid]
        if rid not in strike.index or not len(rule["bounce_frames"]):
            continue
        f = int(strike[rid])
        ball = arr.pos_m[arr.start[ri]:arr.start[ri] + arr.length[ri], BALL].astype(np.float64)
        if f < 3 or f + 3 > len(ball):
            continue
        end, side = int(rule["server_end"]), str(rule["side"])
        bx, by = rule["bounces_m"][0][:2]
        counts["n"] += 1
        counts["record"] += bool(is_in_service_box(bx, by, end, side))
        track = [torch.as_tensor(p) for p in ball[:f + 3]]
        counts["loop"] += _landing_in_box(track, end, side, fps)
        track = _redraw(track, (f + 1, f + 2), bins, fps, gen)
        counts["redrawn"] += _landing_in_box(track, end, side, fps)
    n = max(counts["n"], 1)
    return {"record": counts["record"] / n, "loop": counts["loop"] / n,
            "redrawn": counts["redrawn"] / n, "n": counts["n"]}


def strikes_redrawn_in_bins(truth: RallyData, shots: tuple[int, ...] = (1, 2, 3, 4),
                            n_bins: int = 61, spacing: str = "nonuniform", n_sub: int = 0,
                            seed: int = 0) -> pd.DataFrame:
    """The serve's measurement for the strikes after it (1 the return, 2 the server's first
    rally ball, ...): each recorded strike flown on from its record by the physics step
    ("loop"; it has no net, and flies a volleyed ball on to where it would have landed), and
    with the two frames after the strike re-drawn inside their bins ("redrawn"; with
    `n_sub`, inside the recorded part of each bin split `n_sub` ways) ->
    per shot: `n`, the shares whose first bounce lies in the opponent's singles court for
    the record (the shots table), the loop and the re-drawn track."""
    fps = float(truth.fps)
    bins = ball_bins(n_bins, spacing, fps)
    gen = torch.Generator().manual_seed(seed)
    arr = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    row = {int(rid): i for i, rid in enumerate(arr.rally_id)}
    first = truth.frames.groupby("rally_id")["frame"].min()
    server_end = truth.rallies.set_index("rally_id")["server_end"]
    out = []
    for shot in shots:
        rec, loop, redrawn = [], [], []
        for s in truth.shots[truth.shots["shot_index"] == shot].itertuples():
            i = row[int(s.rally_id)]
            f = int(s.frame - first[s.rally_id])
            ball = arr.pos_m[arr.start[i]:arr.start[i] + arr.length[i], BALL].astype(np.float64)
            # The shots table's frame is the contact's, rounded: where the ball there is
            # still coming in (toward the hitter's baseline), the strike's frames start one
            # later, else the step read the lift across the contact and flew the ball on
            # without it (recorded returns landing 2 m long).
            if 1 <= f < len(ball) and (ball[f, 0] - ball[f - 1, 0]) * np.sign(s.contact_x) > 0:
                f += 1
            if f < 3 or f + 3 > len(ball):
                continue
            # An odd shot is the receiver's and lands on the server's half.
            side = int(server_end[s.rally_id]) * (1 if shot % 2 else -1)
            track = [torch.as_tensor(p) for p in ball[:f + 3]]
            rec.append(s.outcome != "error")
            for kept, got in ((loop, track), (redrawn, _redraw(track, (f + 1, f + 2), bins,
                                                                fps, gen, n_sub))):
                xy = _first_bounce_m(got, fps)
                kept.append(xy is not None and bool(is_in_singles(*xy, side)))
        out.append({"shot": shot, "n": len(rec), "record_in_play": float(np.mean(rec)),
                    "loop_in_play": float(np.mean(loop)),
                    "redrawn_in_play": float(np.mean(redrawn))})
    return pd.DataFrame(out)
