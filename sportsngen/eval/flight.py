"""The ball's free flight, frame by frame: how far each next frame lies from where a bin
centre (`sportsngen.model.centre`) puts it.

On tracking data this says how much of the ball's motion a centre leaves for the model to
learn (the generator's ball follows the physics step to well under a millimetre); on a model's
rollouts it says how physical the sampled flight is (the learned-engine issue's target: a p90
of at most 2 mm).

Free flight is decided from the track alone, so data and rollouts are read the same way: a
frame t counts when, over frames t - 2 .. t + 1 (those the step reads and predicts), the ball is
at least `MIN_HEIGHT_M` above the ground (no bounce), at least `MIN_PLAYER_DISTANCE_M` from both
players (no racket contact) and moving at `MIN_SPEED_MPS` or more (not held or rolling).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from sportsngen.model.bins import ball_bins
from sportsngen.model.centre import ball_centre_m
from sportsngen.model.config import ModelConfig
from sportsngen.model.inputs import BALL

MIN_HEIGHT_M = 0.3
MIN_PLAYER_DISTANCE_M = 2.5
MIN_SPEED_MPS = 5.0
WINDOW = (-2, 1)   # frames around t that must all be in flight


@dataclass(frozen=True)
class FlightResiduals:
    """Per free-flight frame: next position minus centre, metres (n, 3)."""

    residual_m: np.ndarray
    mode: str

    def summary(self, cfg: ModelConfig | None = None) -> dict[str, float]:
        """Median and p90 of |residual| per dimension (mm) and, given a model config, the share
        of frames whose next position lies in the centre bin of all three dimensions."""
        a = np.abs(self.residual_m) * 1000.0
        out: dict[str, float] = {"frames": float(len(a))}
        for d, name in enumerate("xyz"):
            out[f"median_{name}_mm"] = float(np.median(a[:, d])) if len(a) else float("nan")
            out[f"p90_{name}_mm"] = float(np.quantile(a[:, d], 0.9)) if len(a) else float("nan")
        if cfg is not None and len(a):
            out["centre_bin_share"] = centre_bin_share(self.residual_m, cfg)
        return out


def centre_bin_share(residual_m: np.ndarray, cfg: ModelConfig) -> float:
    """Share of residuals (n, 3) inside the centre bin of the model's ball bins in x, y and z."""
    idx = ball_bins(cfg).index(torch.as_tensor(residual_m, dtype=torch.float32))
    return float((idx == cfg.n_bins // 2).all(dim=-1).float().mean())


def free_flight_frames(pos_m: np.ndarray, fps: float) -> np.ndarray:
    """(T,) bool: frames of one rally (T, 3, 3) [server, receiver, ball] in free flight (module
    doc); False where the window leaves the track."""
    t = len(pos_m)
    ball = pos_m[:, BALL]
    speed = np.zeros(t)
    speed[1:] = np.linalg.norm(np.diff(ball, axis=0), axis=1) * fps
    speed[:1] = speed[1:2]  # the first frame has no difference of its own
    near = np.linalg.norm(pos_m[:, :BALL, :2] - ball[:, None, :2], axis=-1).min(axis=1)
    ok = (ball[:, 2] >= MIN_HEIGHT_M) & (near >= MIN_PLAYER_DISTANCE_M) & (speed >= MIN_SPEED_MPS)
    ok &= np.isfinite(pos_m).all(axis=(1, 2))
    out = np.zeros(t, dtype=bool)
    lo, hi = WINDOW
    if t >= hi - lo + 1:
        out[-lo:t - hi] = np.lib.stride_tricks.sliding_window_view(ok, hi - lo + 1).all(axis=1)
    return out


def flight_residuals(tracks: list[np.ndarray], fps: float,
                     mode: str = "physics") -> FlightResiduals:
    """Residuals of the next frame from the ball centre `mode` over the free-flight frames of
    `tracks` (each (T, 3, 3), any length)."""
    parts = []
    for pos in tracks:
        pos = np.asarray(pos, dtype=np.float64)
        frames = np.flatnonzero(free_flight_frames(pos, fps))
        if len(frames) == 0:
            continue
        ball = torch.as_tensor(pos[:, BALL])
        vel = (ball[frames] - ball[frames - 1]) * fps
        prev = (ball[frames - 1] - ball[frames - 2]) * fps
        centre = ball_centre_m(ball[frames], vel, prev, fps, mode)
        parts.append((ball[frames + 1] - centre).numpy())
    res = np.concatenate(parts) if parts else np.zeros((0, 3))
    return FlightResiduals(res, mode)


def rally_tracks(pos_m: np.ndarray, start: np.ndarray, length: np.ndarray) -> list[np.ndarray]:
    """Split flat frames (N, 3, 3) into rallies by `start` and `length` (`RallyArrays`)."""
    return [pos_m[s:s + n] for s, n in zip(start, length)]
