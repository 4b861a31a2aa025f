"""Training windows: `WindowDataset` cuts windows of a model window's length (or several, for
the band mask) from a `RallyArrays` (random crops and augmentation when training, a fixed tiling
otherwise), with each frame's next-frame target; `Augment` says which augmentations run (the
flip, the paper's ball noise, players' shifts); `check_finite` names the rallies of a batch with
NaN or infinite numbers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch.utils.data import Dataset, get_worker_info

from sportsngen.data.tokens import LABELS, RallyArrays
from sportsngen.model.inputs import BALL, N_OBJECTS, flip_xy

# The paper's ball noise at 25 Hz: +-25 mm in x, +-12.5 mm in y and z.
BALL_NOISE_M_AT_25HZ = (0.025, 0.0125, 0.0125)


def ball_noise_amplitudes(fps: float) -> tuple[np.ndarray, np.ndarray]:
    """(position m, velocity m/s) half-widths of the uniform ball noise at frame rate `fps`.

    The paper's values are per frame at 25 Hz; the position noise scales with the frame
    interval so that it stays the same fraction of a frame's motion, and the velocity noise is
    that position noise over one frame (the same in m/s at any rate).
    """
    pos = np.asarray(BALL_NOISE_M_AT_25HZ, dtype=np.float32) * (25.0 / fps)
    return pos, pos * fps


def player_shifts_m(rng: np.random.Generator, radius_m: float) -> np.ndarray:
    """(2 players, 2) horizontal offsets (m), each uniform in a disc of `radius_m`."""
    r = radius_m * np.sqrt(rng.random(2))
    a = rng.uniform(0.0, 2.0 * np.pi, 2)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=-1).astype(np.float32)


@dataclass
class Augment:
    """Training augmentation switches."""

    flip: bool = True          # x-and-y flip with probability 1/2
    ball_noise: bool = False   # uniform noise on the ball's input position and velocity
    random_crop: bool = True   # random window starts (else a fixed tiling)
    # Each player's whole window moved on the court by a constant offset, uniform in a disc of
    # this radius (m); his moves (the targets) are kept. Rollouts leave a player a few tenths of
    # a metre from where the record had him, where a model that saw only exact geometry gives a
    # ball passing him little chance of a contact (exposure bias): this shows it those states.
    # Measured at 0.4 m on the version-6 fine-tune: held-out loss 0.722 against 0.732, but aces
    # 18-24 % against 9-17 % on two seeds (docs/evaluation.md), so 0 by default.
    player_shift_m: float = 0.0


class WindowDataset(Dataset):
    """Windows of `window_frames` frames cut from `RallyArrays`.

    Without `augment`, windows tile each rally from its start (the last one padded), or are
    the `items` given ((rally index, first frame) each). With it, each rally gives
    ceil(length / window) windows at random starts, flipped and noised.
    """

    def __init__(self, arrays: RallyArrays, window_frames: int, augment: Augment | None = None,
                 seed: int = 0, items: list[tuple[int, int]] | None = None):
        if window_frames < 2:
            raise ValueError(f"window_frames must be at least 2, got {window_frames}")
        self.a = arrays
        self.window = int(window_frames)
        self.augment = augment
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self._worker: int | None = None
        n_win = -(-arrays.length // self.window)
        self.items = [(i, k * self.window) for i, n in enumerate(n_win) for k in range(n)] \
            if items is None else [(int(i), int(s)) for i, s in items]
        bad = [(i, s) for i, s in self.items
               if not (0 <= i < len(arrays.length) and 0 <= s < arrays.length[i])]
        if bad:
            raise ValueError(f"{len(bad)} window(s) outside their rallies, first {bad[0]} "
                             "(rally index, first frame)")

    def __len__(self) -> int:
        return len(self.items)

    def first_windows(self) -> list[int]:
        """Indices of the windows that start at their rally's first frame (one a rally, in
        rally order; without augmentation's random crops, where a rally's serve lies)."""
        return [i for i, (_, start) in enumerate(self.items) if start == 0]

    def __getitem__(self, idx: int) -> dict:
        info = get_worker_info()
        if info is not None and info.id != self._worker:  # each loader worker its own stream
            self.rng = np.random.default_rng([self.seed, info.seed % 2 ** 32])
            self._worker = info.id
        ri, s = self.items[idx]
        a, w, aug = self.a, self.window, self.augment
        n = int(a.length[ri])
        learn = 0 if a.learn_from is None else int(a.learn_from[ri])
        if aug is not None and aug.random_crop:
            # A rally learnt from frame `learn` on: windows that hold frames from there.
            lo = max(learn - w + 2, 0) if learn > 0 else 0
            s = int(self.rng.integers(min(lo, max(n - w, 0)), max(n - w, 0) + 1))
        rows = a.pos_m[a.start[ri]:a.start[ri] + n]
        m = min(w, n - s)
        pos = np.zeros((w, N_OBJECTS, 3), dtype=np.float32)
        nxt = np.zeros_like(pos)
        prev = np.zeros_like(pos)
        pos[:m] = rows[s:s + m]
        prev[:m] = rows[max(s - 1, 0):s + m - 1] if s > 0 else np.concatenate(
            [rows[:1], rows[:m - 1]])
        n_next = min(m, n - s - 1)
        nxt[:n_next] = rows[s + 1:s + 1 + n_next]
        vel = (pos - prev) * a.fps  # backward difference: 0 at the rally's first frame
        valid = np.arange(w) < m
        has_next = (np.arange(w) < n_next) & (s + np.arange(w) >= learn)
        vel[~valid] = 0.0
        # The velocity a frame earlier (the ball's physics centre reads its acceleration):
        # 0 for the rally's first two frames.
        prev_vel = np.zeros_like(vel)
        prev_vel[1:] = vel[:-1]
        if s >= 2:
            prev_vel[0] = (rows[s - 1] - rows[s - 2]) * a.fps
        prev_vel[~valid] = 0.0
        labels = np.zeros((w, len(LABELS)), dtype=np.int64)
        labels[:m] = a.labels[a.start[ri] + s:a.start[ri] + s + m]
        near = np.zeros(w, dtype=bool)
        near[:m] = a.near_contact[a.start[ri] + s:a.start[ri] + s + m]
        if aug is not None:
            if aug.ball_noise:
                p_amp, v_amp = ball_noise_amplitudes(a.fps)
                pos[:m, BALL] += self.rng.uniform(-1, 1, (m, 3)).astype(np.float32) * p_amp
                vel[:m, BALL] += self.rng.uniform(-1, 1, (m, 3)).astype(np.float32) * v_amp
                pos[:m, BALL, 2] = np.maximum(pos[:m, BALL, 2], 0.0)
            if aug.player_shift_m > 0:
                shift = player_shifts_m(self.rng, aug.player_shift_m)
                pos[:m, :BALL, :2] += shift
                nxt[:n_next, :BALL, :2] += shift
            if aug.flip and self.rng.random() < 0.5:
                pos, vel, nxt = flip_xy(pos), flip_xy(vel), flip_xy(nxt)
                prev_vel = flip_xy(prev_vel)
        return {
            "rally_id": int(a.rally_id[ri]), "pos_m": pos, "vel_mps": vel, "next_pos_m": nxt,
            "prev_vel_mps": prev_vel,
            "t_s": ((s + np.arange(w)) / a.fps).astype(np.float32), "valid": valid,
            "has_next": has_next, "ident": a.ident[ri], "surface": int(a.surface[ri]),
            "tournament": int(a.tournament[ri]), "serve": int(a.serve[ri]),
            "score": a.score[ri], "labels": labels, "near_contact": near,
        }


def check_finite(batch: dict) -> None:
    """Raise ValueError naming the rallies whose window holds NaN or infinite numbers."""
    bad = torch.zeros(batch["pos_m"].shape[0], dtype=torch.bool, device=batch["pos_m"].device)
    for key in ("pos_m", "vel_mps", "prev_vel_mps", "next_pos_m", "t_s", "score"):
        if key not in batch:  # prev_vel_mps: batches built by hand may leave it out
            continue
        x = batch[key]
        bad |= ~torch.isfinite(x).reshape(x.shape[0], -1).all(dim=1)
    if bad.any():
        ids = [int(v) for v in batch["rally_id"][bad].tolist()]
        raise ValueError(f"NaN or infinite value in the batch, rally {ids[0]}"
                         + (f" (and rallies {ids[1:]})" if len(ids) > 1 else ""))
