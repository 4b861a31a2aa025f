"""Tracking -> the model's tokens: the vocabulary of identities, surfaces and tournaments
(`Vocab`), and `rally_arrays`, which converts a `RallyData` once into flat numpy arrays in the
model's input schema (`sportsngen.model.inputs`: the objects of a frame in a fixed order,
[server, receiver, ball], their identity rows, each rally's context and numeric score vector)
and the frames' event labels. Each frame also carries a "near contact" flag (within
`CONTACT_TOL_FRAMES` of a racket contact in the shots table), so that validation can score the
ball in flight and at the racket separately. Training windows are cut from these arrays by
`sportsngen.train.windows`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from sportsngen.data.tracking import DIRECTIONS, ERROR_KINDS, OUTCOMES, STROKES, SURFACES, RallyData
from sportsngen.errors import ArgumentError
from sportsngen.model.inputs import (
    BALL,
    BALL_ID,
    GENERIC_ID,
    N_OBJECTS,
    N_SPECIAL_IDS,
    SCORE_FIELDS,
    score_vector,
)

LABELS = {"stroke": STROKES, "direction": DIRECTIONS, "outcome": OUTCOMES,
          "error_kind": ERROR_KINDS}
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
