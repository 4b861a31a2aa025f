"""Fit the surfaces' table of the returns' error shifts, in turn with the receivers'.

The generator's return faces the serve's heaviness (the server's `serve_heaviness`), which a
surface passes on as a power (clay 0.7, `synth.behaviour.SURFACE_SERVE_WEIGHT`) and a second
serve as its square root. The head draws a receiver's returns erring about alike on every
surface and after either serve: at the round robins' returns, read as a rollout reads them
(`synthetic_named`, 14,757 returns), it drew first serves' returns on clay erring 0.184 where
the record's erred 0.134 and second serves' on hard 0.097 against 0.136, while the receivers'
returns table (`model.strike_return`, one row per receiver) matched each receiver over all of
them (docs/evaluation.md, fifty-fifth part). `ModelConfig.strike_return_surface` adds a row per
surface and serve (`model.strike_bias.strike_dim_bias`); here it and the receivers' rows are
matched in turn on the recorded returns, each cell (a receiver; a surface and serve) to the
record's share of each error, pulled toward the odds before by `prior_strikes` pseudo-returns,
as `train.strike_bias.fit_strike_pressure` fits the hitters' and opponents' rows.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from sportsngen.model import strike_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates, head_inputs
from sportsngen.train.strike_bias import head_draws, match_cell


def with_return_surface(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the returns' table) with the surfaces' returns table added
    (`cfg.strike_return_surface`), at zero: it draws as before until `fit_return_surface`
    fills it. -> a new model."""
    return with_flag(model, "strike_return_surface", ["strike_return_surface"])


@torch.no_grad()
def fit_return_surface(model: SportsNGEN, states: HeadStates, returns: np.ndarray,
                       rounds: int = 4, prior_strikes: float = 200.0, min_strikes: int = 50,
                       draws: int = 0) -> pd.DataFrame:
    """Fill the surfaces' returns table (`model.strike_return_surface`) and refit the
    receivers' (`model.strike_return`), in place, on the recorded returns among `states`
    (`returns` (N,) bool; `HeadStates.returns`; the states must hold their surfaces, as
    `collect_head_states` reads them). A return's odds of each error get the receiver's rally
    row (`model.strike_bias`, receiving), his width's tilt where the model has one, his
    returns' row and the row of the surface and serve; the last two are found in turn for
    `rounds` rounds, each cell with at least `min_strikes` returns matched to the record. With
    `draws`, each return's odds are read at that many of the head's own draws of the earlier
    dimensions (`train.strike_bias.head_draws`: as a rollout draws). -> per (table:
    "receiver" or "surface", id (the receiver's identity or the surface's index), serve (-1
    for the receivers' rows)) of the last round: n and per kind the record's share, the odds
    before and after, and the shift."""
    if model.strike_return is None or model.strike_return_surface is None:
        raise ValueError("the model has no surfaces' returns table "
                         "(cfg.strike_return_surface): add it with with_return_surface")
    if states.surface is None:
        raise ValueError("these states hold no surfaces: read them again with "
                         "collect_head_states")
    if len(returns) != len(states):
        raise ValueError(f"returns has {len(returns)} rows, the states {len(states)}")
    if rounds < 1 or prior_strikes < 0 or min_strikes < 1:
        raise ValueError(f"rounds and min_strikes must be >= 1 and prior_strikes >= 0, got "
                         f"{rounds}, {min_strikes} and {prior_strikes}")
    rows = np.flatnonzero(np.asarray(returns, dtype=bool) & states.receiver.astype(bool))
    if len(rows) == 0:
        raise ValueError("no recorded return among the states")
    head = model.strike_head
    masks = torch.as_tensor(strike_bias.error_bins())
    i = torch.as_tensor(rows)
    x, bins = head_inputs(model, "strike", states, i), states.bins[i]
    prev = bins
    if draws:
        rows, x, prev = head_draws(model, states, rows, x, draws)
        bins = states.bins[torch.as_tensor(rows)]
        # A return's draws together weigh as the return did.
        prior_strikes, min_strikes = prior_strikes * draws, min_strikes * draws
    receiver = torch.as_tensor(states.receiver_id[rows])
    surface = torch.as_tensor(states.surface[rows])
    serve = torch.as_tensor(states.serve[rows])
    logits = [head.dim_logits(x, prev, kind) for kind in range(strike_bias.N_KINDS)]
    if model.strike_width is not None:
        tilt = torch.as_tensor(strike_bias.width_tilt(), dtype=x.dtype)
        logits[strike_bias.WIDE] = logits[strike_bias.WIDE] + \
            model.strike_width[receiver, 1][:, None] * tilt
    record = [masks[k][bins[:, k]].to(x.dtype) for k in range(strike_bias.N_KINDS)]

    def shifts(name: str, kind: int) -> torch.Tensor:
        """(len(rows),) every table's shift of `kind` on each return but `name`'s."""
        total = model.strike_bias[receiver, 1, kind].clone()
        if name != "receiver":
            total += model.strike_return[receiver, kind]
        if name != "surface":
            total += model.strike_return_surface[surface, serve, kind]
        return total

    cells = {"receiver": pd.DataFrame({"id": receiver.numpy(), "serve": -1}),
             "surface": pd.DataFrame({"id": surface.numpy(), "serve": serve.numpy()})}
    out = []
    for r in range(rounds):
        for name, keys in cells.items():
            for (cid, sv), g in keys.groupby(["id", "serve"]):
                if len(g) < min_strikes:
                    continue
                j = torch.as_tensor(g.index.to_numpy(copy=True))
                fitted_shifts, fitted = match_cell(
                    logits, record, masks, j, lambda kind, j=j, name=name: shifts(name, kind)[j],
                    prior_strikes)
                cell = (model.strike_return[int(cid)] if name == "receiver"
                        else model.strike_return_surface[int(cid), int(sv)])
                cell[:] = torch.as_tensor(fitted_shifts, dtype=cell.dtype)
                row = {"table": name, "id": int(cid), "serve": int(sv),
                       "n": len(j) // max(draws, 1), **fitted}
                if r == rounds - 1:
                    out.append(row)
    return pd.DataFrame(out)
