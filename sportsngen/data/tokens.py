"""Windows of tracking frames -> model inputs (object tokens, context) and next-frame targets.

Per frame there are three objects in a fixed order, [server, receiver, ball]. Each object token
carries an identity index (a learned embedding in the model) and eight numbers normalised by
constants of the sport: position (3), velocity (3, backward finite difference, so a token never
sees the future), distance to the ball (0 for the ball) and time since the rally began. The
context of a window is its rally's surface, tournament, first/second serve and a numeric score
vector. The target of a frame is every object's position at the next frame; the model turns it
into bin indices around a centre (`sportsngen.model.centre`) with `sportsngen.model.bins`.

`rally_arrays` converts a `RallyData` once into flat numpy arrays; `WindowDataset` cuts windows
from them (random crops and augmentation when training, a fixed tiling otherwise). Each frame also
carries a "near contact" flag (within `CONTACT_TOL_FRAMES` of a racket contact in the shots
table), so that validation can score the ball in flight and at the racket separately.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import torch
from torch.utils.data import Dataset, get_worker_info

from sportsngen.data.tracking import DIRECTIONS, ERROR_KINDS, OUTCOMES, STROKES, SURFACES, RallyData
from sportsngen.errors import ArgumentError
from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M

OBJECTS = ("server", "receiver", "ball")
N_OBJECTS = len(OBJECTS)
BALL = 2                     # index of the ball among the objects of a frame
BALL_ID, GENERIC_ID = 0, 1   # identity indices reserved before the named players
N_SPECIAL_IDS = 2
N_FEATURES = 8               # position 3, velocity 3, distance to ball 1, elapsed time 1

# Normalising constants (sport scale, so features are O(1)).
POS_SCALE_M = (BASELINE_X_M, SINGLES_HALF_WIDTH_M, 3.0)
VEL_SCALE_MPS = 10.0
DIST_SCALE_M = 10.0
TIME_SCALE_S = 10.0

SCORE_FIELDS = ("server_sets", "receiver_sets", "server_games", "receiver_games",
                "server_points", "receiver_points", "in_tiebreak")
SCORE_SCALE = (3.0, 3.0, 6.0, 6.0, 4.0, 4.0, 1.0)
LABELS = {"stroke": STROKES, "direction": DIRECTIONS, "outcome": OUTCOMES,
          "error_kind": ERROR_KINDS}

# The paper's ball noise at 25 Hz: +-25 mm in x, +-12.5 mm in y and z.
BALL_NOISE_M_AT_25HZ = (0.025, 0.0125, 0.0125)
UNKNOWN_POLICIES = ("generic", "warn", "error")
CONTACT_TOL_FRAMES = 1       # a frame is "near contact" within this many frames of a shot's frame


@dataclass
class Vocab:
    """Names -> indices for players (after the ball and generic ids), surfaces, tournaments.

    Tournament index 0 is "unknown". A generic model has no players: everyone maps to the
    generic identity.
    """

    players: tuple[str, ...] = ()
    surfaces: tuple[str, ...] = SURFACES
    tournaments: tuple[str, ...] = ()

    @classmethod
    def from_data(cls, data: RallyData, generic: bool = False) -> Vocab:
        """Players and tournaments seen in `data` (sorted); no players when `generic`."""
        r = data.rallies
        players = () if generic else tuple(sorted(set(r["server"]) | set(r["receiver"])))
        return cls(players=players, tournaments=tuple(sorted(set(r["tournament"]))))

    @property
    def n_ids(self) -> int:
        return N_SPECIAL_IDS + len(self.players)

    def _lookup(self, kind: str, name: str, names: tuple[str, ...], unknown: str,
                fallback: int, offset: int) -> int:
        if name in names:
            return names.index(name) + offset
        if unknown not in UNKNOWN_POLICIES:
            raise ArgumentError(f"unknown policy must be one of {UNKNOWN_POLICIES}, "
                                f"got {unknown!r}")
        if unknown == "error":
            raise ArgumentError(f"unknown {kind} {name!r}; known: {list(names)}")
        if unknown == "warn":
            warnings.warn(f"unknown {kind} {name!r}: using the generic one", stacklevel=3)
        return fallback

    def player_index(self, name: str, unknown: str = "warn") -> int:
        """Identity index of a player; unknown -> generic (silently, with a warning) or error."""
        if not self.players:  # a generic model: everyone is the generic player, by design
            return GENERIC_ID
        return self._lookup("player", name, self.players, unknown, GENERIC_ID, N_SPECIAL_IDS)

    def surface_index(self, name: str, unknown: str = "warn") -> int:
        """Index of a surface; an unknown one -> the first ("hard") or error, by policy."""
        return self._lookup("surface", name, self.surfaces, unknown, 0, 0)

    def tournament_index(self, name: str, unknown: str = "generic") -> int:
        """Index of a tournament, 0 for an unknown one."""
        return self._lookup("tournament", name, self.tournaments, unknown, 0, 1)

    def with_player(self, name: str) -> Vocab:
        """A copy with `name` appended (existing indices unchanged)."""
        if name in self.players:
            raise ValueError(f"player {name!r} is already in the vocabulary")
        return Vocab(self.players + (name,), self.surfaces, self.tournaments)

    def to_dict(self) -> dict:
        return {"players": list(self.players), "surfaces": list(self.surfaces),
                "tournaments": list(self.tournaments)}

    @classmethod
    def from_dict(cls, d: dict) -> Vocab:
        return cls(tuple(d["players"]), tuple(d["surfaces"]), tuple(d["tournaments"]))


def score_vector(server_sets, receiver_sets, server_games, receiver_games, server_points,
                 receiver_points, in_tiebreak) -> np.ndarray:
    """Normalised score features (order `SCORE_FIELDS`, server's view); scalars or arrays.

    The same quantities as the first seven of `MatchState.score_vector()` (see
    `score_features`): points are deuce-reduced (a long deuce game maps onto 40-40 or
    advantage, a long tie-break onto 6-6 or one point more) so they stay bounded.
    """
    sp = np.asarray(server_points, dtype=np.float32)
    rp = np.asarray(receiver_points, dtype=np.float32)
    tb = np.asarray(in_tiebreak, dtype=np.float32)
    excess = np.maximum(np.minimum(sp, rp) - np.where(tb > 0, 6.0, 3.0), 0.0)
    cols = [server_sets, receiver_sets, server_games, receiver_games, sp - excess, rp - excess, tb]
    out = np.stack([np.asarray(c, dtype=np.float32) / s for c, s in zip(cols, SCORE_SCALE)],
                   axis=-1)
    return out.astype(np.float32)


def score_features(match_score_vector) -> np.ndarray:
    """Model score features from `MatchState.score_vector()` (its first seven fields, raw
    counts from the server's view, already deuce-reduced): for the simulator."""
    v = np.asarray(match_score_vector, dtype=np.float32)[..., :len(SCORE_FIELDS)]
    return (v / np.asarray(SCORE_SCALE, dtype=np.float32)).astype(np.float32)


@dataclass
class RallyArrays:
    """All rallies of a `RallyData` as flat arrays; rally i owns rows start[i]:+length[i]."""

    pos_m: np.ndarray        # (n_rows, 3 objects, 3) float32
    labels: np.ndarray       # (n_rows, 4) int64: stroke, direction, outcome, error_kind
    near_contact: np.ndarray  # (n_rows,) bool: within CONTACT_TOL_FRAMES of a racket contact
    start: np.ndarray        # (n_rallies,) int64
    length: np.ndarray       # (n_rallies,) int64
    rally_id: np.ndarray     # (n_rallies,) int64
    ident: np.ndarray        # (n_rallies, 3) int64: server, receiver, ball identity indices
    surface: np.ndarray      # (n_rallies,) int64
    tournament: np.ndarray   # (n_rallies,) int64
    serve: np.ndarray        # (n_rallies,) int64: 0 first serve, 1 second serve
    score: np.ndarray        # (n_rallies, 7) float32
    fps: float
    meta: dict = field(default_factory=dict)
    # (n_rallies,) int64 or None: a rally's frames before this one are inputs only, never
    # targets (an expert's answer to a model's own rollout, `sportsngen.train.expert`).
    learn_from: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.rally_id)

    def learn_from_frames(self) -> np.ndarray:
        """(n_rallies,) the first frame whose next frame is a target (0 for recorded rallies)."""
        if self.learn_from is None:
            return np.zeros(len(self.rally_id), dtype=np.int64)
        return self.learn_from

    def select(self, idx: np.ndarray) -> RallyArrays:
        """The rallies at positions `idx`, re-packed."""
        idx = np.asarray(idx, dtype=np.int64)
        rows = np.concatenate([np.arange(s, s + n) for s, n in
                               zip(self.start[idx], self.length[idx])]) if len(idx) else \
            np.zeros(0, dtype=np.int64)
        length = self.length[idx]
        start = np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.int64)
        return RallyArrays(self.pos_m[rows], self.labels[rows], self.near_contact[rows], start,
                           length,
                           self.rally_id[idx], self.ident[idx], self.surface[idx],
                           self.tournament[idx], self.serve[idx], self.score[idx], self.fps,
                           dict(self.meta),
                           None if self.learn_from is None else self.learn_from[idx])

    @staticmethod
    def concat(parts: list[RallyArrays]) -> RallyArrays:
        """The rallies of every part, in order, re-packed (one frame rate)."""
        if not parts:
            raise ValueError("nothing to concatenate")
        fps = {float(p.fps) for p in parts}
        if len(fps) > 1:
            raise ValueError(f"rally arrays at different frame rates {sorted(fps)}")
        length = np.concatenate([p.length for p in parts])
        start = np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.int64)

        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(p, name) for p in parts])
        learn = None
        if any(p.learn_from is not None for p in parts):
            learn = np.concatenate([p.learn_from_frames() for p in parts])
        return RallyArrays(cat("pos_m"), cat("labels"), cat("near_contact"), start, length,
                           cat("rally_id"), cat("ident"), cat("surface"), cat("tournament"),
                           cat("serve"), cat("score"), parts[0].fps, dict(parts[0].meta), learn)


def rally_arrays(data: RallyData, vocab: Vocab, unknown: str = "warn") -> RallyArrays:
    """Convert `data` once into `RallyArrays` (vectorised over frames).

    Raises ValueError naming the rally when an object is missing at some frame, an object is
    neither the server, the receiver nor the ball, or a coordinate is not finite.
    """
    r = data.rallies.reset_index(drop=True)
    f = data.frames
    if len(r) == 0:
        raise ValueError("no rallies in the data")
    rid_to_pos = {int(v): i for i, v in enumerate(r["rally_id"])}
    ridx = f["rally_id"].map(rid_to_pos).to_numpy(dtype=np.int64)
    obj = f["object"].to_numpy(dtype=object)
    slot = np.full(len(f), -1, dtype=np.int64)
    slot[obj == "ball"] = BALL
    slot[obj == r["server"].to_numpy(dtype=object)[ridx]] = 0
    slot[obj == r["receiver"].to_numpy(dtype=object)[ridx]] = 1
    if (slot < 0).any():
        i = int(np.flatnonzero(slot < 0)[0])
        raise ValueError(f"rally {int(f['rally_id'].iat[i])}: object {obj[i]!r} is neither the "
                         "server, the receiver nor the ball (only singles is supported)")
    frame = f["frame"].to_numpy(dtype=np.int64)
    first = np.full(len(r), np.iinfo(np.int64).max)
    np.minimum.at(first, ridx, frame)
    last = np.full(len(r), -1)
    np.maximum.at(last, ridx, frame)
    if (last < 0).any():
        bad = int(r["rally_id"].iat[int(np.flatnonzero(last < 0)[0])])
        raise ValueError(f"rally {bad}: no frames")
    length = (last - first + 1).astype(np.int64)
    start = np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.int64)
    row = start[ridx] + frame - first[ridx]
    n_rows = int(length.sum())
    pos = np.full((n_rows, N_OBJECTS, 3), np.nan, dtype=np.float32)
    pos[row, slot] = f[["x", "y", "z"]].to_numpy(dtype=np.float32)
    count = np.zeros((n_rows, N_OBJECTS), dtype=np.int64)
    np.add.at(count, (row, slot), 1)
    bad_row = (count != 1).any(axis=1) | ~np.isfinite(pos).all(axis=(1, 2))
    if bad_row.any():
        ri = int(np.searchsorted(start, np.flatnonzero(bad_row)[0], side="right") - 1)
        raise ValueError(f"rally {int(r['rally_id'].iat[ri])}: every frame needs exactly one "
                         "finite server, receiver and ball position")
    labels = np.zeros((n_rows, len(LABELS)), dtype=np.int64)
    is_ball = slot == BALL
    for j, (col, vocab_l) in enumerate(LABELS.items()):
        codes = {v: i for i, v in enumerate(vocab_l)}
        labels[row[is_ball], j] = f.loc[is_ball, col].map(codes).fillna(0).to_numpy(np.int64)
    names = sorted(set(r["server"]) | set(r["receiver"]))  # one lookup (and warning) a name
    pid = {name: vocab.player_index(name, unknown) for name in names}
    ident = np.stack([r["server"].map(pid).to_numpy(np.int64),
                      r["receiver"].map(pid).to_numpy(np.int64),
                      np.full(len(r), BALL_ID, dtype=np.int64)], axis=1)
    surf_idx = {s: vocab.surface_index(s, unknown) for s in set(r["surface"])}
    tour_idx = {t: vocab.tournament_index(t) for t in set(r["tournament"])}
    score = score_vector(*(r[c].to_numpy() for c in SCORE_FIELDS))
    return RallyArrays(
        pos_m=pos, labels=labels, near_contact=_near_contact(data.shots, rid_to_pos, first, start,
                                                            length),
        start=start, length=length,
        rally_id=r["rally_id"].to_numpy(np.int64), ident=ident,
        surface=r["surface"].map(surf_idx).to_numpy(np.int64),
        tournament=r["tournament"].map(tour_idx).to_numpy(np.int64),
        serve=(r["serve_number"].to_numpy(np.int64) - 1).clip(0, 1), score=score,
        fps=float(data.fps))


def _near_contact(shots, rid_to_pos: dict, first: np.ndarray, start: np.ndarray,
                  length: np.ndarray) -> np.ndarray:
    """(n_rows,) bool: rows within CONTACT_TOL_FRAMES frames of a shot's contact frame. Shots
    of rallies not in `rid_to_pos` are ignored; contacts near a rally's ends are clipped to it."""
    n_rows = int(length.sum())
    near = np.zeros(n_rows, dtype=bool)
    if shots is None or len(shots) == 0:
        return near
    ri = shots["rally_id"].map(rid_to_pos)
    keep = ri.notna().to_numpy()
    ri = ri.to_numpy()[keep].astype(np.int64)
    local = shots["frame"].to_numpy(np.int64)[keep] - first[ri]
    for d in range(-CONTACT_TOL_FRAMES, CONTACT_TOL_FRAMES + 1):
        k = local + d
        ok = (k >= 0) & (k < length[ri])
        near[start[ri[ok]] + k[ok]] = True
    return near


def object_features(pos_m: torch.Tensor, vel_mps: torch.Tensor, t_s: torch.Tensor) -> torch.Tensor:
    """(..., T, 3, 3) positions and velocities, (..., T) times -> (..., T, 3, N_FEATURES)."""
    scale = torch.tensor(POS_SCALE_M, dtype=pos_m.dtype, device=pos_m.device)
    dist = torch.linalg.vector_norm(pos_m - pos_m[..., BALL:BALL + 1, :], dim=-1, keepdim=True)
    t = (t_s / TIME_SCALE_S)[..., None, None].expand(*pos_m.shape[:-1], 1)
    return torch.cat([pos_m / scale, vel_mps / VEL_SCALE_MPS, dist / DIST_SCALE_M, t], dim=-1)


def flip_xy(arr):
    """Rotate by 180 degrees about the vertical through the net centre: (x, y) -> (-x, -y).
    A numpy array or a torch tensor (a collated batch's); a new one either way."""
    out = arr.clone() if torch.is_tensor(arr) else arr.copy()
    out[..., :2] *= -1
    return out


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
