"""Initial conditions of simulated rallies: the first frames of historical rallies.

A simulated point starts from the first `n_frames` frames (the start of the toss) of a real
(training) rally of the same server, serve number and side, so the decoder continues a serve
that starts the way that player starts his serves. Examples are kept per (server, serve number,
side) up to a cap, in the orientation they were recorded; `draw` rotates one by 180 degrees
about the net centre when the simulated server serves from the other end (a rotation keeps the
deuce court the deuce court).

The receiver stands where he waits for a serve, which differs by player far more than the
server's toss does (the generator's Nadal 3.6 m behind the baseline on hard, Federer 0.8 m,
as the Hawk-Eye figures it is calibrated to). A pool that records its receivers (`receiver`)
takes the receiver's frames from an example in which the simulated receiver received that
serve number on that side (preferring the surface); without one, a point started with another
point's receiver, at that player's stance (`docs/evaluation.md`, issue 17, thirteenth part).

The pool travels inside the model file (`to_dict` / `from_dict`, under the key
`initial_conditions` of its extra data), so a simulator needs nothing but the model file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.model.inputs import flip_xy

N_FRAMES_DEFAULT = 10            # 0.4 s of the toss at 25 Hz: the serve itself is simulated
MAX_PER_KEY_DEFAULT = 100        # examples kept per (server, serve number, side)


@dataclass
class InitialConditions:
    pos_m: np.ndarray            # (N, n_frames, 3, 3) float32: server, receiver, ball
    server: np.ndarray           # (N,) str
    serve_number: np.ndarray     # (N,) int64, 1 or 2
    side: np.ndarray             # (N,) str, "deuce" or "ad"
    server_end: np.ndarray       # (N,) int64, +1 or -1
    surface: np.ndarray          # (N,) str
    fps: float
    receiver: np.ndarray | None = None   # (N,) str; None in pools stored before it existed

    def __len__(self) -> int:
        return len(self.pos_m)

    @property
    def n_frames(self) -> int:
        return int(self.pos_m.shape[1])

    @property
    def servers(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.server.tolist())))

    @classmethod
    def from_rally_data(cls, data: RallyData, n_frames: int = N_FRAMES_DEFAULT,
                        max_per_key: int = MAX_PER_KEY_DEFAULT,
                        seed: int = 0) -> InitialConditions:
        """Up to `max_per_key` random rallies per (server, serve number, side) of `data`, each
        at least `n_frames` long; their first `n_frames` frames."""
        if n_frames < 1:
            raise ValueError(f"n_frames must be at least 1, got {n_frames}")
        arr = rally_arrays(data, Vocab.from_data(data), unknown="generic")
        r = data.rallies.reset_index(drop=True)
        ok = arr.length >= n_frames
        rng = np.random.default_rng(seed)
        keys = r["server"].astype(str) + "|" + r["serve_number"].astype(str) + "|" + \
            r["side"].astype(str)
        chosen = []
        for _, idx in keys[ok].groupby(keys[ok]).groups.items():
            idx = np.asarray(idx)
            chosen.append(rng.permutation(idx)[:max_per_key])
        if not chosen:
            raise ValueError(f"no rally has {n_frames} frames to start a simulation from")
        sel = np.sort(np.concatenate(chosen))
        rows = arr.start[sel][:, None] + np.arange(n_frames)
        return cls(pos_m=arr.pos_m[rows].astype(np.float32),
                   server=r["server"].to_numpy(dtype=str)[sel],
                   serve_number=r["serve_number"].to_numpy(dtype=np.int64)[sel],
                   side=r["side"].to_numpy(dtype=str)[sel],
                   server_end=r["server_end"].to_numpy(dtype=np.int64)[sel],
                   surface=r["surface"].to_numpy(dtype=str)[sel], fps=float(data.fps),
                   receiver=r["receiver"].to_numpy(dtype=str)[sel])

    def _pick(self, cand: np.ndarray, surface: str | None, rng: np.random.Generator) -> int:
        if surface is not None and (cand & (self.surface == surface)).any():
            cand = cand & (self.surface == surface)
        return int(rng.choice(np.flatnonzero(cand)))

    def _oriented(self, i: int, server_end: int) -> np.ndarray:
        pos = self.pos_m[i]
        return flip_xy(pos) if int(self.server_end[i]) != server_end else pos.copy()

    def draw(self, server: str, serve_number: int, side: str, server_end: int,
             rng: np.random.Generator, surface: str | None = None,
             receiver: str | None = None) -> np.ndarray:
        """(n_frames, 3, 3) first frames for this serve: one of the server's own examples of
        that serve number and side (preferring `surface`), any server's when he has none; with
        `receiver` and a pool that records receivers, the receiver's frames from one of his own
        examples of that serve number and side (preferring `surface`), turned to this end."""
        if side not in ("deuce", "ad"):
            raise ValueError(f"side must be 'deuce' or 'ad', got {side!r}")
        if server_end not in (1, -1):
            raise ValueError(f"server_end must be +1 or -1, got {server_end}")
        base = (self.serve_number == serve_number) & (self.side == side)
        cand = base & (self.server == server)
        if not cand.any():
            cand = base
        if not cand.any():
            raise ValueError(f"no initial condition for serve {serve_number} from the {side} "
                             "side")
        pos = self._oriented(self._pick(cand, surface, rng), server_end)
        if receiver is not None and self.receiver is not None:
            own = base & (self.receiver == receiver)
            if own.any():
                pos[:, 1] = self._oriented(self._pick(own, surface, rng), server_end)[:, 1]
        return pos

    def merged(self, other: InitialConditions) -> InitialConditions:
        """Both pools (e.g. a fine-tuned player's serves added to the generic model's); the
        receivers are kept only where both pools record them."""
        if other.n_frames != self.n_frames or other.fps != self.fps:
            raise ValueError("initial conditions differ in frames or frame rate")
        receiver = None if self.receiver is None or other.receiver is None else \
            np.concatenate([self.receiver, other.receiver])
        return InitialConditions(*(np.concatenate([getattr(self, f), getattr(other, f)])
                                   for f in ("pos_m", "server", "serve_number", "side",
                                             "server_end", "surface")), fps=self.fps,
                                 receiver=receiver)

    def to_dict(self) -> dict:
        return {"pos_m": self.pos_m, "server": self.server.tolist(),
                "serve_number": self.serve_number, "side": self.side.tolist(),
                "server_end": self.server_end, "surface": self.surface.tolist(),
                "fps": self.fps,
                "receiver": None if self.receiver is None else self.receiver.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> InitialConditions:
        return cls(pos_m=np.asarray(d["pos_m"], dtype=np.float32),
                   server=np.asarray(d["server"], dtype=str),
                   serve_number=np.asarray(d["serve_number"], dtype=np.int64),
                   side=np.asarray(d["side"], dtype=str),
                   server_end=np.asarray(d["server_end"], dtype=np.int64),
                   surface=np.asarray(d["surface"], dtype=str), fps=float(d["fps"]),
                   receiver=None if d.get("receiver") is None
                   else np.asarray(d["receiver"], dtype=str))
