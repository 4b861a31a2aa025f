"""Fit a model's per-hitter shifts of the strike head's odds of a rally ball long, wide or into
the net.

`ModelConfig.strike_bias` (`sportsngen.model.strike_bias`) adds to the strike head's logits,
per hitter and role (his own service point or his opponent's), one shift on the depth bins
beyond the baseline, one on the lateral bins outside the singles lines and one on the
net-height bins below the net. Each is found here as the serve's are (`train.serve_bias`): on
a hitter's recorded rally strikes (the decoder's states, `train.head_fit.collect_head_states`
with "strike"), the shift that makes the head's mean odds of the error equal his record's,
pulled toward the head's own by `prior_strikes` pseudo-strikes. The lateral odds are read at
the record's own depth bin and the net's at its depth and lateral bins, as the head's
teacher-forced loss reads them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.model import strike_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates, head_inputs
from sportsngen.train.serve_bias import matched_shift

KINDS = ("long", "wide", "net")


def with_strike_bias(model: SportsNGEN) -> SportsNGEN:
    """`model` with the per-hitter table added (`cfg.strike_bias`), at zero: it draws as
    before until `fit_strike_bias` fills it. -> a new model (the same one if it has it)."""
    return with_flag(model, "strike_bias", ["strike_bias"])


@torch.no_grad()
def fit_strike_bias(model: SportsNGEN, states: HeadStates, prior_strikes: float = 200.0,
                    min_strikes: int = 50) -> pd.DataFrame:
    """Fill `model.strike_bias` (in place) from the recorded rally strikes `states` (with the
    receivers' identities), per hitter and role with at least `min_strikes` strikes (others
    keep 0). -> per (hitter_id, receiver): n, and per kind the record's share, the head's
    before, the target, the head's after and the shift."""
    if model.strike_bias is None:
        raise ValueError("the model has no per-hitter table (cfg.strike_bias): add it with "
                         "with_strike_bias")
    if prior_strikes < 0 or min_strikes < 1:
        raise ValueError(f"prior_strikes must be >= 0 and min_strikes >= 1, got "
                         f"{prior_strikes} and {min_strikes}")
    head = model.strike_head
    masks = torch.as_tensor(strike_bias.error_bins())
    keys = pd.DataFrame({"hitter_id": states.hitter_id(), "receiver": states.receiver})
    rows = []
    for (hid, recv), g in keys.groupby(["hitter_id", "receiver"]):
        if len(g) < min_strikes:
            continue
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        x, bins = head_inputs(model, "strike", states, i), states.bins[i]
        n = len(i)
        row = {"hitter_id": int(hid), "receiver": bool(recv), "n": n}
        for kind, name in enumerate(KINDS):
            logits = head.dim_logits(x, bins, kind)
            mask = masks[kind].expand(n, -1)
            record = float(masks[kind][bins[:, kind]].float().mean())
            fit = matched_shift(logits, mask, mask.to(logits.dtype), record, prior_strikes)
            model.strike_bias[int(hid), int(recv), kind] = fit["shift"]
            row.update({f"{name}_{k}": v for k, v in fit.items()})
        rows.append(row)
    return pd.DataFrame(rows)


def error_shares(table: pd.DataFrame) -> pd.DataFrame:
    """`fit_strike_bias`'s table -> per row the share of strikes in error (long, or else wide,
    or else into the net) by the record, the head before and after, the kinds taken as
    independent (the head draws them one after another): a summary to print."""
    out = table[["hitter_id", "receiver", "n"]].copy()
    for when in ("record", "head", "after"):
        keep = np.ones(len(table))
        for name in KINDS:
            keep = keep * (1.0 - table[f"{name}_{when}"].to_numpy())
        out[f"error_{when}"] = 1.0 - keep
    return out
