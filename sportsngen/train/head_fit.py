"""A serve or strike head fitted alone on a frozen decoder, from the decoder's states read once.

`train.py ... train_only=serve_head` runs the whole decoder forward every step to train a head
of 0.13 M weights on the one serve a window holds: 4,000 steps (14 minutes on 2 cores) showed
the head each serve at most about twice. With the decoder frozen its states at the serves do
not change, so here they are read once (`collect_head_states`: one pass over the rallies'
first windows, cut at their serves: 600 rallies in 2 s against 12-13 s for full windows) and
the head is fitted on them for as many passes as its validation loss keeps falling
(`fit_head`: seconds a thousand steps), keeping the best state. The states are those the
training windows give: windows from each rally's first frame, and with `flip` (training's
augmentation) each also turned about the net's centre, which in the world frame is another
state (in the server's frame, `model.frame: server`, the same one, so it is read once).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader, Subset, default_collate
from tqdm.auto import tqdm

from sportsngen.data.tokens import RallyArrays
from sportsngen.model import strike, strike_heads
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL, flip_xy
from sportsngen.train.metrics import window_states
from sportsngen.train.windows import WindowDataset

HEADS = ("serve", "strike")
# The `WindowDataset` item's entries with a frame axis (second after the batch's).
_PER_FRAME = ("pos_m", "vel_mps", "next_pos_m", "prev_vel_mps", "t_s", "valid", "has_next",
              "labels", "near_contact")
_TURNED = ("pos_m", "vel_mps", "next_pos_m", "prev_vel_mps")   # what the flip turns


@dataclass
class HeadStates:
    """The ball token's output state at each target of a head, with the target's bins."""

    h: torch.Tensor          # (N, d)
    bins: torch.Tensor       # (N, 4) int64
    rally_id: np.ndarray     # (N,)
    serve: np.ndarray        # (N,) 0 first serve, 1 second serve (the rally's)
    contact_m: np.ndarray    # (N, 3) the ball where it is struck (the target's frame)
    receiver: np.ndarray     # (N,) bool: the hitter is the rally's receiver (the ball on his end)
    server_id: np.ndarray    # (N,) int64: the rally's server's identity (the Vocab's index)
    receiver_id: np.ndarray | None = None   # (N,) int64: the rally's receiver's, where read
    shot: np.ndarray | None = None   # (N,) int64: the strike's number, where fixed (`take`)
    surface: np.ndarray | None = None    # (N,) int64: the rally's surface index, where read

    def __len__(self) -> int:
        return len(self.bins)

    @staticmethod
    def concat(parts: list[HeadStates]) -> HeadStates:
        def optional(k: str) -> np.ndarray | None:
            return None if any(getattr(p, k) is None for p in parts) else \
                np.concatenate([getattr(p, k) for p in parts])
        return HeadStates(torch.cat([p.h for p in parts]), torch.cat([p.bins for p in parts]),
                          *(np.concatenate([getattr(p, k) for p in parts])
                            for k in ("rally_id", "serve", "contact_m", "receiver",
                                      "server_id")), receiver_id=optional("receiver_id"),
                          shot=np.concatenate([p.shot_numbers() for p in parts]),
                          surface=optional("surface"))

    def take(self, keep: np.ndarray) -> HeadStates:
        """The rows where `keep` ((N,) bool) holds, in order, with their shot numbers counted
        on the whole (`shot_numbers`)."""
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != (len(self),):
            raise ValueError(f"keep has shape {keep.shape}, the states {len(self)} rows")
        i = torch.as_tensor(np.flatnonzero(keep))
        return HeadStates(self.h[i], self.bins[i],
                          *(getattr(self, k)[keep] for k in ("rally_id", "serve", "contact_m",
                                                             "receiver", "server_id")),
                          receiver_id=None if self.receiver_id is None
                          else self.receiver_id[keep], shot=self.shot_numbers()[keep],
                          surface=None if self.surface is None else self.surface[keep])

    def hitter_id(self) -> np.ndarray:
        """(N,) int64: the identity of the player who strikes each target (the receiver's
        where `receiver`)."""
        if self.receiver_id is None:
            raise ValueError("these states hold no receivers' identities (read them with "
                             "collect_head_states)")
        return np.where(self.receiver, self.receiver_id, self.server_id)

    def opponent_id(self) -> np.ndarray:
        """(N,) int64: the identity of the player whose ball each target answers (the server
        where the receiver strikes, else the receiver)."""
        if self.receiver_id is None:
            raise ValueError("these states hold no receivers' identities (read them with "
                             "collect_head_states)")
        return np.where(self.receiver, self.server_id, self.receiver_id)

    def returns(self) -> np.ndarray:
        """(N,) bool: the returns among rally strikes read in order (`collect_head_states`
        reads each rally's windows in turn, its strikes in time): a rally's first strike, where
        the receiver struck it. A rally whose return was not a target (its next frames cut by
        the window) has none, rather than a later strike taken for it."""
        return self._run_starts() & self.receiver.astype(bool)

    def shot_numbers(self) -> np.ndarray:
        """(N,) int64: each rally strike's number in its rally (1 the return, 2 the server's
        first rally ball, ...), counted along the strikes read in order as `returns` reads
        them: the receiver strikes the odd shots and the server the even ones, so a strike
        the windows missed between two read ones (its next frames cut by a window's end) is
        counted by the turn of the hitter; two missed in a row are not. Rows taken from
        others (`take`, `concat`) keep the numbers counted there."""
        if self.shot is not None:
            return self.shot
        recv = self.receiver.astype(bool)
        start = self._run_starts()
        same_hitter = np.zeros(len(recv), dtype=bool)
        same_hitter[1:] = recv[1:] == recv[:-1]
        step = np.where(start, np.where(recv, 1, 2), np.where(same_hitter, 2, 1))
        total = np.cumsum(step)
        # Each run's count restarts: subtract the total before its first strike.
        before = np.maximum.accumulate(np.where(start, total - step, 0))
        return (total - before).astype(np.int64)

    def _run_starts(self) -> np.ndarray:
        """(N,) bool: the first strike read of each rally (a new rally id in the order)."""
        first = np.ones(len(self.rally_id), dtype=bool)
        first[1:] = self.rally_id[1:] != self.rally_id[:-1]
        return first


def _head(model: SportsNGEN, which: str):
    if which not in HEADS:
        raise ValueError(f"head must be one of {HEADS}, got {which!r}")
    head = model.serve_head if which == "serve" else model.strike_head
    if head is None:
        raise ValueError(f"the model has no {which} head (model.{which}_head is off)")
    return head


def _turned(batch: dict) -> dict:
    """A collated batch turned 180 degrees about the vertical through the net's centre (the
    training augmentation's flip)."""
    return {k: flip_xy(v) if k in _TURNED else v for k, v in batch.items()}


def window_batches(model: SportsNGEN, arrays: RallyArrays, first_only: bool, flip: bool,
                   batch_size: int = 32):
    """Collated training windows of `arrays` (each rally's first window only, or all that tile
    it), and with `flip` each also turned as training's augmentation turns half of them (in
    the world frame only: the server's frame undoes the turn) -> (an iterator of batches,
    their number)."""
    ds = WindowDataset(arrays, model.cfg.window_frames, None)
    if first_only:
        ds = Subset(ds, ds.first_windows())
    loader = DataLoader(ds, batch_size=batch_size, shuffle=False, collate_fn=default_collate)
    turns = (False, True) if flip and model.cfg.frame == "world" else (False,)
    return ((_turned(b) if t else b) for t in turns for b in loader), len(loader) * len(turns)


def cut_batch(batch: dict, t: int) -> dict:
    """A batch's windows cut after their first `t` frames: a frame's states see only the
    frames up to it, so the decoder need run no further than the last frame read."""
    return {k: v[:, :t] if k in _PER_FRAME else v for k, v in batch.items()}


def cached_states(path: str | Path | None, key, read: Callable[[], dict]) -> tuple[dict, bool]:
    """`read()`'s states (a dict of `HeadStates` and the like), kept in `path` with `key`
    (what they were read with) and the version of the strike labels
    (`strike.STRIKE_LABELS_VERSION`): read from `path` where it holds them for both (a file
    read with another key or labels is refused: `ValueError`), else read and, with a `path`,
    kept there. The decoder's states take minutes to read and seconds to fit on. -> (the
    states, whether they came from `path`)."""
    if path is not None and Path(path).exists():
        cached = torch.load(path, weights_only=False)
        got = (cached.get("key"), cached.get("labels"))
        if got != (key, strike.STRIKE_LABELS_VERSION):
            raise ValueError(f"{path} holds states read with {got[0]} (strike labels version "
                             f"{got[1]}), not {key} (version {strike.STRIKE_LABELS_VERSION}): "
                             "remove it or name another file")
        return {k: v for k, v in cached.items() if k not in ("key", "labels")}, True
    states = read()
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        torch.save({"key": key, "labels": strike.STRIKE_LABELS_VERSION, **states}, path)
    return states, False


def strike_view_batches(model: SportsNGEN, arrays: RallyArrays, lead_frames: int,
                        batch_size: int = 32):
    """Collated windows, one a rally strike of `arrays`, each ending `lead_frames` after its
    strike (from the rally's first frame where the strike comes earlier): the history a
    rollout's band and `eval.strike_draws` give a strike, where windows tiling a rally give
    the strikes late in a rally anything from none to a window of it. The strikes are found
    on the tiling windows by `model.strike_targets` alone (no decoder). -> (an iterator of
    batches, their number)."""
    window = model.cfg.window_frames
    if not 3 <= lead_frames < window:
        raise ValueError(f"lead_frames must be in [3, {window}) (the strike's three next frames "
                         f"are its target), got {lead_frames}")
    tiles = WindowDataset(arrays, window, None)
    items = []
    for b0 in range(0, len(tiles), 256):
        part = [tiles[k] for k in range(b0, min(b0 + 256, len(tiles)))]
        batch = default_collate(part)
        mask, _ = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                       batch["has_next"])
        for row, t in mask.nonzero().tolist():
            ri, start = tiles.items[b0 + row]
            at = start + t
            items.append((ri, max(at - (window - lead_frames), 0), at))
    ds = WindowDataset(arrays, window, None, items=[(ri, s) for ri, s, _ in items])
    loader = DataLoader(ds, batch_size=batch_size, shuffle=False, collate_fn=default_collate)
    # Each window's own strike: its frame in the window.
    own = torch.as_tensor([at - s for _, s, at in items], dtype=torch.int64)

    def batches():
        for b0, batch in enumerate(loader):
            batch["own_frame"] = own[b0 * batch_size:b0 * batch_size + len(batch["pos_m"])]
            yield batch
    return batches(), len(loader)


@torch.no_grad()
def collect_head_states(model: SportsNGEN, arrays: RallyArrays, which: str = "serve",
                        flip: bool = False, batch_size: int = 32,
                        progress: bool = True, lead_frames: int | None = None) -> HeadStates:
    """The decoder's states at every target of the `which` head ("serve": the serves, read
    from each rally's first window; "strike": the rally strikes, from windows tiling each
    rally, or with `lead_frames` each from its own window ending that many frames after it,
    as a rollout reads it: `strike_view_batches`) in `arrays`; with `flip`, also from every
    window turned as training's augmentation turns half of them (in the world frame only:
    the server's frame undoes the turn)."""
    _head(model, which)
    if lead_frames is not None and (which != "strike" or flip):
        raise ValueError("lead_frames reads the rally strikes (which='strike'), unturned")
    was_training = model.training
    model.eval()
    # A rally's serve lies in its first window.
    if lead_frames is None:
        batches, total = window_batches(model, arrays, which == "serve", flip, batch_size)
    else:
        batches, total = strike_view_batches(model, arrays, lead_frames, batch_size)
    hs, bins, rid, srv, contact, receiver, server_id, receiver_id, surface = \
        ([] for _ in range(9))
    for batch in tqdm(batches, desc=f"{which} states", total=total, disable=not progress):
        mask, b = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                       batch["has_next"], serves=which == "serve")
        if lead_frames is not None:
            # Each window's own strike alone, at its frame (another strike within the lead is
            # read from its own window).
            frames = torch.arange(mask.shape[1])
            mask = mask & (frames[None] == batch.pop("own_frame")[:, None])
        if not bool(mask.any()):
            continue
        # A frame's states see only the frames up to it: the decoder runs up to the last
        # target (a serve comes within the first second or two of a 6 s window).
        t = int(mask.nonzero()[:, 1].max()) + 1
        cut = cut_batch(batch, t)
        h = window_states(model, cut)
        hs.append(h[..., BALL, :][mask[:, :t]])
        bins.append(b[mask])
        rows = mask.nonzero()[:, 0]
        rid.append(batch["rally_id"][rows].numpy())
        srv.append(batch["serve"][rows].numpy())
        contact.append(batch["pos_m"][..., BALL, :][mask].double().numpy())
        receiver.append(strike_heads.ball_on_receivers_end(batch["pos_m"][mask]).numpy())
        server_id.append(batch["ident"][rows, 0].numpy())
        receiver_id.append(batch["ident"][rows, 1].numpy())
        surface.append(batch["surface"][rows].numpy())
    model.train(was_training)
    if not hs:
        raise ValueError(f"no {which} targets in the {len(arrays)} rallies given")
    return HeadStates(torch.cat(hs), torch.cat(bins), np.concatenate(rid), np.concatenate(srv),
                      np.concatenate(contact), np.concatenate(receiver),
                      np.concatenate(server_id).astype(np.int64),
                      np.concatenate(receiver_id).astype(np.int64),
                      surface=np.concatenate(surface).astype(np.int64))


def _fitted(model: SportsNGEN, which: str) -> list[torch.nn.Module]:
    """The modules a head's fit moves: the head, and the strike head's role and shot shifts
    if any (the players' shifts are fitted on their own: `train.strike_inputs`)."""
    head = _head(model, which)
    if which != "strike":
        return [head]
    return [head] + [m for m in (model.strike_role, model.strike_shot) if m is not None]


def head_inputs(model: SportsNGEN, which: str, states: HeadStates, idx) -> torch.Tensor:
    """The head's input at `states[idx]`: the ball token's state, for a strike head with
    `cfg.strike_roles` shifted by the hitter's role and the serve, with `cfg.strike_shots` by
    the strike's number (`HeadStates.shot_numbers`), with `cfg.strike_players` by the hitter's
    and the opponent's rows (where the states hold the receivers' identities)."""
    h = states.h[idx]
    if which != "strike" or (model.strike_role is None and model.strike_shot is None):
        return h
    role = None if model.strike_role is None else strike_heads.role_index(
        torch.as_tensor(states.receiver[idx]), torch.as_tensor(states.serve[idx]))
    shot = None if model.strike_shot is None else \
        torch.as_tensor(states.shot_numbers()[idx])
    hitter = opponent = None
    if model.strike_player is not None and states.receiver_id is not None:
        hitter = torch.as_tensor(states.hitter_id()[idx])
        opponent = torch.as_tensor(states.opponent_id()[idx])
    return model.strike_input(h, role, shot, hitter, opponent)


@torch.no_grad()
def head_nll(model: SportsNGEN, which: str, states: HeadStates,
             batch_size: int = 4096) -> float:
    """Mean -log p(bins | state) of `model`'s `which` head over `states` (nats a target)."""
    head = _head(model, which)
    total = 0.0
    for i in range(0, len(states), batch_size):
        part = slice(i, i + batch_size)
        total += float(head.nll(head_inputs(model, which, states, part), states.bins[part]).sum())
    return total / max(len(states), 1)


def fit_head(model: SportsNGEN, which: str, train: HeadStates, val: HeadStates,
             steps: int = 3000, lr: float = 1e-3, batch_size: int = 256,
             weight_decay: float = 0.01, warmup_steps: int = 50, eval_every: int = 250,
             seed: int = 0, progress: bool = True) -> list[dict]:
    """Fit `model`'s `which` head (in place; a strike head with its role shift where
    `cfg.strike_roles`) on `train` with AdamW, a linear warm-up and a cosine decay; every
    `eval_every` steps the validation NLL, and at the end the head is left at its best one.
    -> the history [{"step", "val_nll"}], step 0 the head as it came."""
    if steps < 1 or batch_size < 1 or eval_every < 1:
        raise ValueError("steps, batch_size and eval_every must be positive")
    if len(train) == 0 or len(val) == 0:
        raise ValueError("fit_head needs training and validation targets")
    head = _head(model, which)
    mods = _fitted(model, which)
    g = torch.Generator().manual_seed(seed)
    opt = torch.optim.AdamW([p for m in mods for p in m.parameters()], lr=lr,
                            weight_decay=weight_decay)

    def rate(step: int) -> float:
        if step < warmup_steps:
            return (step + 1) / warmup_steps
        done = (step - warmup_steps) / max(steps - warmup_steps, 1)
        return 0.5 * (1.0 + math.cos(math.pi * done))

    sched = torch.optim.lr_scheduler.LambdaLR(opt, rate)
    head.eval()
    history = [{"step": 0, "val_nll": head_nll(model, which, val)}]
    best = (history[0]["val_nll"], [copy.deepcopy(m.state_dict()) for m in mods])
    bar = tqdm(range(steps), desc=f"fit {which} head", disable=not progress)
    for step in bar:
        head.train()
        idx = torch.randint(len(train), (batch_size,), generator=g)
        loss = head.nll(head_inputs(model, which, train, idx), train.bins[idx]).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if (step + 1) % eval_every == 0 or step + 1 == steps:
            head.eval()
            v = head_nll(model, which, val)
            history.append({"step": step + 1, "val_nll": v})
            if v < best[0]:
                best = (v, [copy.deepcopy(m.state_dict()) for m in mods])
            bar.set_postfix(val_nll=f"{v:.3f}", best=f"{best[0]:.3f}")
    for m, state in zip(mods, best[1]):
        m.load_state_dict(state)
    head.eval()
    return history
