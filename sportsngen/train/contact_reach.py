"""Fit a model's shifts of the ball's odds of a racket contact by where the ball is from its
hitter (`model.contact_reach`).

On every recorded frame of the training rallies at which the ball comes toward the player on
its end, the ball head's mass on the frame's strike bins, its jolt bins and the rest
(`model.contact_reach.bin_kinds`) is read once (windows tiling each rally), with the frame's
cell (`reach_cells`) and which of the three the record's next frame falls in. Per cell, the two
shifts whose mean odds of a strike and of a jolt equal the record's shares, each pulled toward
the head's own mean odds by `prior_frames` pseudo-frames, are found by bisection, one after the
other a few rounds (each moves the other's odds a little through the softmax): matching the
mean odds is the condition that maximises the likelihood of the record's next frames in the
cell's shifts. Cells with fewer than `min_frames` frames keep 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
from tqdm.auto import tqdm

from sportsngen.data.tokens import RallyArrays
from sportsngen.model import contact_reach
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import window_batches
from sportsngen.train.metrics import window_states
from sportsngen.train.serve_bias import bisect_shift, pulled_toward

MAX_SHIFT = 8.0          # logits: a cell the record never strikes in goes to ~1e-4 a frame


@dataclass
class ContactStates:
    """Each recorded frame at which the ball comes to a player: its cell, the head's log-mass
    of a strike, a jolt and the rest on the next frame, and which the record's next frame is."""

    cell: np.ndarray          # (N,) int64
    logits: torch.Tensor      # (N, 3) float32: log-probabilities of (strike, jolt, rest)
    kind: np.ndarray          # (N,) int64: 0 strike, 1 jolt, 2 rest
    rally_id: np.ndarray      # (N,) int64

    def __len__(self) -> int:
        return len(self.cell)

    @staticmethod
    def concat(parts: list[ContactStates]) -> ContactStates:
        return ContactStates(np.concatenate([p.cell for p in parts]),
                             torch.cat([p.logits for p in parts]),
                             np.concatenate([p.kind for p in parts]),
                             np.concatenate([p.rally_id for p in parts]))


def with_contact_reach(model: SportsNGEN) -> SportsNGEN:
    """`model` with the contact table added (`cfg.contact_reach`), at zero: it plays as before
    until `fit_contact_reach` fills it. -> a new model (the same one if it has it)."""
    return with_flag(model, "contact_reach", ["contact_reach"])


def kind_logits(model: SportsNGEN, h: torch.Tensor, pos_m: torch.Tensor,
                centre_m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Ball output states h (N, d) at frames (N, 3, 3) whose bins are centred at `centre_m`
    -> the head's log-probabilities of (strike, jolt, rest) on its first axis (N, 3),
    before any table, and the frames' strike and jolt bins ((N, n_bins) bool each)."""
    first = model.ball_head.dim_logits(h, torch.zeros(len(h), 3, dtype=torch.long), 0)
    strike, jolt = model.contact_bin_kinds(pos_m, centre_m)
    rest = ~(strike | jolt)
    first = first.log_softmax(-1)
    out = torch.stack([first.masked_fill(~m, float("-inf")).logsumexp(-1)
                       for m in (strike, jolt, rest)], dim=-1)
    return out, strike, jolt


@torch.no_grad()
def collect_contact_states(model: SportsNGEN, arrays: RallyArrays, batch_size: int = 32,
                           progress: bool = True) -> ContactStates:
    """The head's odds of a strike and of a jolt at every recorded frame of `arrays` whose
    ball comes to a player (module doc), from windows tiling each rally."""
    if model.cfg.head != "factorised":
        raise ValueError("the contact table shifts the factorised ball head's first axis")
    was_training = model.training
    model.eval()
    batches, total = window_batches(model, arrays, False, False, batch_size)
    parts = []
    for batch in tqdm(batches, desc="contact states", total=total, disable=not progress):
        cells = contact_reach.reach_cells(batch["pos_m"], batch["vel_mps"], model.cfg.fps)
        keep = batch["has_next"].bool() & (cells >= 0)
        if not bool(keep.any()):
            continue
        h = window_states(model, batch)[..., BALL, :][keep]
        # One centre for the head's bin kinds and the record's target bin.
        centre = model.centres(batch["pos_m"], batch["vel_mps"], batch.get("prev_vel_mps"))
        _, ball_bins = model.offset_bins(model.to_model_frame(batch["next_pos_m"] - centre,
                                                              batch["pos_m"]))
        logits, strike, jolt = kind_logits(model, h, batch["pos_m"][keep], centre[keep])
        target = ball_bins[..., 0][keep]
        rows = torch.arange(len(target))
        kind = torch.where(strike[rows, target], 0, torch.where(jolt[rows, target], 1, 2))
        parts.append(ContactStates(cells[keep].numpy(), logits.float(), kind.numpy(),
                                   batch["rally_id"][keep.nonzero()[:, 0]].numpy()))
    model.train(was_training)
    if not parts:
        raise ValueError(f"no recorded ball comes to a player in the {len(arrays)} rallies")
    return ContactStates.concat(parts)


def _cell_shifts(table: torch.Tensor | None, cells: np.ndarray) -> torch.Tensor:
    """(N, 2) each frame's strike and jolt shifts (0 without a table)."""
    c = torch.as_tensor(cells)
    if table is None:
        return torch.zeros(len(c), 2)
    return torch.stack([contact_reach.cell_shift(table[k], c)
                        for k in (contact_reach.STRIKE, contact_reach.JOLT)], dim=-1)


def cell_table(states: ContactStates, table: torch.Tensor | None = None) -> pd.DataFrame:
    """Per cell of `states`: frames, the record's shares of strikes and jolts, the head's
    mean odds of each and (with `table`) the mean odds with its shifts."""
    head = contact_reach.kind_probabilities(states.logits, torch.zeros(len(states), 2))
    cols = {"cell": states.cell, "record": states.kind == 0, "record_jolt": states.kind == 1,
            "head": head[:, 0].numpy(), "head_jolt": head[:, 1].numpy()}
    if table is not None:
        shifted = contact_reach.kind_probabilities(states.logits,
                                                   _cell_shifts(table, states.cell))
        cols.update(shifted=shifted[:, 0].numpy(), shifted_jolt=shifted[:, 1].numpy())
    df = pd.DataFrame(cols)
    out = df.groupby("cell").agg(n=("head", "size"), **{c: (c, "mean") for c in df.columns
                                                        if c != "cell"})
    out.insert(0, "frames_cell", out.index // contact_reach.N_ASIDE_CELLS)
    out.insert(1, "aside_cell", out.index % contact_reach.N_ASIDE_CELLS)
    return out.reset_index()


def _match(logits: torch.Tensor, record: np.ndarray, prior_frames: float,
           rounds: int = 4) -> tuple[list[float], list[float], list[float]]:
    """A cell's (strike, jolt) shifts matching the record's shares (module doc) -> (shifts,
    the head's mean odds before, after)."""
    n = len(logits)
    zero = torch.zeros(n, 2)
    before = contact_reach.kind_probabilities(logits, zero).mean(0)
    targets = [pulled_toward(float(record[k]), float(before[k]), n, prior_frames)
               for k in range(2)]
    shift = [0.0, 0.0]
    for _ in range(rounds):
        for k in range(2):
            def odds(s: float, k: int = k) -> float:
                trial = list(shift)
                trial[k] = s
                return float(contact_reach.kind_probabilities(
                    logits, torch.tensor([trial]).expand(n, 2))[:, k].mean())
            shift[k] = bisect_shift(odds, targets[k], MAX_SHIFT)
    after = contact_reach.kind_probabilities(logits, torch.tensor([shift]).expand(n, 2)).mean(0)
    return shift, before[:2].tolist(), after[:2].tolist()


@torch.no_grad()
def fit_contact_reach(model: SportsNGEN, states: ContactStates, prior_frames: float = 20.0,
                      min_frames: int = 30) -> pd.DataFrame:
    """Fill `model.contact_reach` (in place) from the recorded frames `states` (module doc).
    -> per fitted cell: frames, the record's shares, the head's mean odds before and after,
    the shifts (strike, jolt)."""
    if model.contact_reach is None:
        raise ValueError("the model has no contact table (cfg.contact_reach): add it with "
                         "with_contact_reach")
    if prior_frames < 0 or min_frames < 1:
        raise ValueError("prior_frames must be >= 0 and min_frames >= 1")
    model.contact_reach.zero_()
    rows = []
    for cell in np.unique(states.cell):
        i = np.flatnonzero(states.cell == cell)
        if len(i) < min_frames:
            continue
        kind = states.kind[i]
        record = [(kind == 0).mean(), (kind == 1).mean()]
        shift, before, after = _match(states.logits[torch.as_tensor(i)], record, prior_frames)
        fi, ai = divmod(int(cell), contact_reach.N_ASIDE_CELLS)
        for k in (contact_reach.STRIKE, contact_reach.JOLT):
            model.contact_reach[k, fi, ai] = shift[k]
        rows.append({"cell": int(cell), "frames_cell": fi, "aside_cell": ai, "n": len(i),
                     "record": record[0], "head": before[0], "after": after[0],
                     "shift": shift[0], "record_jolt": record[1], "head_jolt": before[1],
                     "after_jolt": after[1], "shift_jolt": shift[1]})
    return pd.DataFrame(rows)
