"""Fit the hitters' surfaces table: each player's error shifts by surface, rally balls and
returns apart, on top of every other table of the strike head.

From generator version 6.3 a named player may play one surface his own way
(`synth.profiles.PlayerProfile.surface_overrides`: Nadal's return position and composure on
hard and clay, Federer's rally noise, pace and spin on hard and clay in version 6.4). The
strike head reads the surface only through the decoder's context, and its tables have one row
per player, fitted on his strikes of every surface pooled: in the bundled file's rollouts on
version 6.4's hard court Nadal's returns erred 0.146 of the time, the truth's 0.318
(docs/evaluation.md, seventy-second part). `ModelConfig.strike_surface` adds a row per hitter,
surface and stroke (`model.strike_bias.STROKE_RALLY` / `STROKE_RETURN`); here each cell with
enough strikes is matched to the record's share of each error, on top of the file's other
tables as they are, pulled toward the odds before by `prior_strikes` pseudo-strikes, as
`train.strike_bias.fit_strike_pressure` fits its cells.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.model import strike_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates, head_inputs
from sportsngen.train.strike_bias import (
    check_prior,
    head_draws,
    match_cell,
    states_strike_bias,
)


def with_strike_surface(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the hitters' table) with the hitters' surfaces table added
    (`cfg.strike_surface`), at zero: it draws as before until `fit_strike_surface` fills it.
    -> a new model."""
    return with_flag(model, "strike_surface", ["strike_surface"])


@torch.no_grad()
def fit_strike_surface(model: SportsNGEN, states: HeadStates, prior_strikes: float = 200.0,
                       min_strikes: int = 50, draws: int = 0) -> pd.DataFrame:
    """Fill the hitters' surfaces table (`model.strike_surface`), in place, from zero, on the
    recorded strikes `states` (rally balls and returns; the states must hold their surfaces,
    as `collect_head_states` reads them). A strike's odds of each error get every other table's
    shift as the file has them (`SportsNGEN.strike_head_bias`); each cell (a hitter, a surface
    and a stroke) with at least `min_strikes` strikes is matched to the record's share, the
    others stay at zero. With `draws`, each strike's odds are read at that many of the head's
    own draws of the earlier dimensions (`train.strike_bias.head_draws`: as a rollout draws).
    -> per cell (id, surface, stroke: "rally" or "return"): n and per kind the record's share,
    the odds before and after, and the shift."""
    if model.strike_surface is None:
        raise ValueError("the model has no hitters' surfaces table (cfg.strike_surface): add "
                         "it with with_strike_surface")
    if states.surface is None:
        raise ValueError("these states hold no surfaces: read them again with "
                         "collect_head_states")
    check_prior(prior_strikes, min_strikes)
    if len(states) == 0:
        raise ValueError("no recorded strike among the states")
    model.strike_surface.zero_()
    head = model.strike_head
    masks = torch.as_tensor(strike_bias.error_bins())
    rows = np.arange(len(states))
    x = head_inputs(model, "strike", states, torch.as_tensor(rows))
    prev = bins = states.bins
    if draws:
        rows, x, prev = head_draws(model, states, rows, x, draws)
        bins = states.bins[torch.as_tensor(rows)]
        # A strike's draws together weigh as the strike did.
        prior_strikes, min_strikes = prior_strikes * draws, min_strikes * draws
    bias = states_strike_bias(model, states, rows, x.dtype)
    # Each kind of error is read on the dimension of its index (depth, lateral, net height).
    logits = [head.dim_logits(x, prev, kind) + bias[:, kind]
              for kind in range(strike_bias.N_KINDS)]
    record = [masks[k][bins[:, k]].to(x.dtype) for k in range(strike_bias.N_KINDS)]
    stroke = np.where(states.returns()[rows], strike_bias.STROKE_RETURN,
                      strike_bias.STROKE_RALLY)
    keys = pd.DataFrame({"id": states.hitter_id()[rows], "surface": states.surface[rows],
                         "stroke": stroke})
    out = []
    for (cid, surface, row), g in keys.groupby(["id", "surface", "stroke"]):
        if len(g) < min_strikes:
            continue
        j = torch.as_tensor(g.index.to_numpy(copy=True))
        # Every other table's shift is already in the logits.
        zero = torch.zeros(len(j), dtype=x.dtype)
        shifts, fitted = match_cell(logits, record, masks, j, lambda kind, zero=zero: zero,
                                    prior_strikes)
        model.strike_surface[int(cid), int(surface), int(row)] = torch.as_tensor(
            shifts, dtype=model.strike_surface.dtype)
        out.append({"id": int(cid), "surface": int(surface),
                    "stroke": "return" if row == strike_bias.STROKE_RETURN else "rally",
                    "n": len(j) // max(draws, 1), **fitted})
    return pd.DataFrame(out)
