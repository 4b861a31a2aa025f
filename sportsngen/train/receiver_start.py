"""Fit a model's per-server shifts of the receiver's odds of starting his run at the serve.

`ModelConfig.receiver_start` (`sportsngen.model.receiver_start`) adds, per server, serve and
frames waited so far, a shift to the receiver's centre bin (no change of velocity) while he
waits for the serve. Each is found here by matching, as `train.serve_bias` finds the serve's:
on the recorded frames of a server's serves at which the receiver has waited that long (the
serve struck and flying at him, he standing, within `WAIT_FRAMES` of the contact; the
decoder's states read once from each rally's first window, turned as training turns them),
the shift that makes the players' head's mean odds of his leaving the centre bin equal the
record's share of frames at which he starts, pulled toward the head's own odds by
`prior_frames` pseudo-frames. The odds fall as the shift rises, so a bisection finds it.
Matching the mean odds is the condition that maximises the likelihood of the record's
start/wait frames in the shift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
from tqdm.auto import tqdm

from sportsngen.data.tokens import RallyArrays
from sportsngen.model import receiver_start
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import cut_batch, window_batches
from sportsngen.train.metrics import window_states
from sportsngen.train.serve_bias import bisect_shift, pulled_toward

MAX_SHIFT = 6.0          # logits


@dataclass
class WaitStates:
    """The receiver's output state at each recorded frame at which he waits for a serve."""

    h: torch.Tensor          # (N, d)
    start: np.ndarray        # (N,) bool: he leaves the centre bin at the next frame
    frames_after: np.ndarray  # (N,) frames since the serve's contact
    wait: np.ndarray         # (N,) frames he has waited, this one included
    rally_id: np.ndarray     # (N,)
    serve: np.ndarray        # (N,) 0 first serve, 1 second serve
    server_id: np.ndarray    # (N,) int64: the server's identity (the Vocab's index)

    def __len__(self) -> int:
        return len(self.start)

    @staticmethod
    def concat(parts: list[WaitStates]) -> WaitStates:
        return WaitStates(torch.cat([p.h for p in parts]),
                          *(np.concatenate([getattr(p, k) for p in parts])
                            for k in ("start", "frames_after", "wait", "rally_id", "serve",
                                      "server_id")))


def with_receiver_start(model: SportsNGEN) -> SportsNGEN:
    """`model` with the per-server table added (`cfg.receiver_start`), at zero: it plays as
    before until `fit_receiver_start` fills it. -> a new model (the same one if it has it)."""
    return with_flag(model, "receiver_start", ["receiver_start"])


@torch.no_grad()
def collect_wait_states(model: SportsNGEN, arrays: RallyArrays, flip: bool = False,
                        batch_size: int = 32, progress: bool = True) -> WaitStates:
    """The decoder's receiver states at every recorded frame of `arrays` at which he waits for
    the serve (module doc), from each rally's first window; with `flip`, also from every
    window turned as training's augmentation turns half of them (world frame only)."""
    was_training = model.training
    model.eval()
    batches, total = window_batches(model, arrays, True, flip, batch_size)
    centre = model.cfg.n_bins // 2
    parts = []
    for batch in tqdm(batches, desc="receiver states", total=total, disable=not progress):
        served, _ = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                         batch["has_next"], serves=True)
        has = served.any(1)
        if not bool(has.any()):
            continue
        t_serve = torch.where(has, served.float().argmax(1), torch.full_like(has, -10 ** 6,
                                                                             dtype=torch.long))
        after = torch.arange(served.shape[1])[None] - t_serve[:, None]
        # From the serve's own token (whose velocity is the toss's: no wait yet), as a rollout
        # counts the wait.
        wait = (after >= 0) & (after <= receiver_start.WAIT_FRAMES) & batch["has_next"].bool() \
            & receiver_start.receiver_waiting(batch["pos_m"], batch["vel_mps"])
        if not bool(wait.any()):
            continue
        t = int(wait.nonzero()[:, 1].max()) + 1
        cut = cut_batch(batch, t)
        h = window_states(model, cut)[..., receiver_start.RECEIVER, :]
        w = wait[:, :t]
        pbins, _ = model.target_bins(cut["pos_m"], cut["vel_mps"], cut["next_pos_m"],
                                     cut.get("prev_vel_mps"))
        rows = w.nonzero()[:, 0]
        parts.append(WaitStates(
            h[w], (pbins[..., receiver_start.RECEIVER, :] != centre).any(-1)[w].numpy(),
            after[:, :t][w].numpy(), receiver_start.wait_counts(w)[w].numpy(),
            batch["rally_id"][rows].numpy(),
            batch["serve"][rows].numpy(), batch["ident"][rows, 0].numpy().astype(np.int64)))
    model.train(was_training)
    if not parts:
        raise ValueError(f"no recorded receiver waits for a serve in the {len(arrays)} "
                         "rallies given")
    return WaitStates.concat(parts)


def _logits(model: SportsNGEN, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The players' head's logits of the first axis, and of the second given the first's
    centre bin, at states h (N, d)."""
    c = model.cfg.n_bins // 2
    prev = torch.full((len(h), 2), c, dtype=torch.long)
    head = model.player_head
    return head.dim_logits(h, prev, 0), head.dim_logits(h, prev, 1)


def _solve(first: torch.Tensor, second: torch.Tensor, target: float) -> float:
    """The shift whose mean start odds equal `target` (they fall as the shift rises)."""
    return bisect_shift(lambda s: float(receiver_start.start_probability(
        first, second, torch.tensor([s]))[0].mean()), target, MAX_SHIFT, rising=False)


@torch.no_grad()
def fit_receiver_start(model: SportsNGEN, states: WaitStates, prior_frames: float = 200.0,
                       min_frames: int = 20) -> pd.DataFrame:
    """Fill `model.receiver_start` (in place) from the recorded waits `states`, per server,
    serve and wait (`receiver_start.wait_bin`) with at least `min_frames` frames (others keep
    0). -> per (server_id, serve, wait): n frames, the record's share of starts, the head's
    mean odds before and after, the shift."""
    if model.receiver_start is None:
        raise ValueError("the model has no receiver-start table (cfg.receiver_start): add it "
                         "with with_receiver_start")
    if prior_frames < 0 or min_frames < 1:
        raise ValueError("prior_frames must be >= 0 and min_frames >= 1")
    keys = pd.DataFrame({"server_id": states.server_id, "serve": states.serve,
                         "wait": receiver_start.wait_bin(torch.as_tensor(states.wait)).numpy()})
    rows = []
    for (sid, srv, k), g in keys.groupby(["server_id", "serve", "wait"]):
        if len(g) < min_frames or not 0 <= srv < receiver_start.N_SERVES:
            continue
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        first, second = _logits(model, states.h[i])
        n = len(i)
        record = float(states.start[i.numpy()].mean())
        before = float(receiver_start.start_probability(first, second,
                                                        torch.zeros(1))[0].mean())
        target = pulled_toward(record, before, n, prior_frames)
        shift = _solve(first, second, target)
        model.receiver_start[int(sid), int(srv), int(k)] = shift
        after = float(receiver_start.start_probability(first, second,
                                                       torch.tensor([shift]))[0].mean())
        rows.append({"server_id": int(sid), "serve": int(srv), "wait": int(k) + 1, "n": n,
                     "record": record, "head": before, "target": target, "after": after,
                     "shift": shift})
    return pd.DataFrame(rows)
