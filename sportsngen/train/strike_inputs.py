"""Fit the strike head's learned input shifts: by the strike's number in the rally
(`ModelConfig.strike_shots`) and by the hitter and his opponent (`ModelConfig.strike_players`).

The decoder's ball state does not say how many shots a rally has had: read at recorded rally
strikes, the head placed the receiver's second rally ball (shot 3) 0.2 m short of the record and
his third (shot 5) 0.45 m deep after first serves, and its spin was 0.085 nats a strike worse
than with the number (docs/evaluation.md, forty-fourth part). The rollout's tracker counts the
contacts, so the number is known where the head draws; here one learned vector per
`strike_heads.shot_bucket` row is added to the head's input and fitted on the decoder's states
at recorded strikes (`train.head_fit.collect_head_states`), with the head and everything else
frozen and the file's per-player tables applied as a rollout draws with them, kept at its best
likelihood on held-out rallies. The tables were fitted on the head without it: refit them after
(`fit_strike_pressure`, as `scripts/fit_strike_bias.py --shots` does).

The players' shifts are fitted the same way: the head reads who strikes and whom he answers only
through the ball's state, and the per-player tables (`model.strike_bias`) correct the means of
one or two of its dimensions each, where a vector per (player, role) moves all four together
(held out 0.26 nats a strike more, most of it the players' spin). Both raise the likelihood and
halve the head's teacher-forced depth and height gaps by shot; in the rollouts' checks neither
did better than the file without them (87 and 89 of 96 against 89): both are off in the bundled
file (docs/evaluation.md, forty-fourth part).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import torch
from tqdm.auto import tqdm

from sportsngen.model import strike, strike_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.strike_heads import shot_bucket
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates, head_inputs

HELD_OUT_EVERY = 5     # rallies whose id is a multiple of this are held out


PARTS = ("shot", "players")     # what `fit_strike_inputs` may fit


def with_strike_shots(model: SportsNGEN) -> SportsNGEN:
    """`model` (with a strike head) with the shot shift added (`cfg.strike_shots`), at zero: it
    draws as before until `fit_strike_inputs` fills it (a model without a strike head is
    refused by its config). -> a new model (the same one if it has it)."""
    return with_flag(model, "strike_shots", ["strike_shot.weight"])


def with_strike_players(model: SportsNGEN) -> SportsNGEN:
    """`model` (with a strike head and its role shift) with the players' shifts added
    (`cfg.strike_players`), at zero (a model without the role shift is refused by its config).
    -> a new model (the same one if it has them)."""
    return with_flag(model, "strike_players", ["strike_player", "strike_opponent"])


def _parameters(model: SportsNGEN, parts: tuple[str, ...]) -> list[torch.nn.Parameter]:
    bad = [p for p in parts if p not in PARTS]
    if bad or not parts:
        raise ValueError(f"parts must be a non-empty subset of {PARTS}, got {parts}")
    out = []
    if "shot" in parts:
        if model.strike_shot is None:
            raise ValueError("the model has no shot shift (cfg.strike_shots): add it with "
                             "with_strike_shots")
        out.append(model.strike_shot.weight)
    if "players" in parts:
        if model.strike_player is None:
            raise ValueError("the model has no players' shifts (cfg.strike_players): add them "
                             "with with_strike_players")
        out += [model.strike_player, model.strike_opponent]
    return out


@torch.no_grad()
def table_bias(model: SportsNGEN, states: HeadStates) -> torch.Tensor | None:
    """The file's per-player shifts of the strike head's logits at `states` (N, 4, bins), as a
    rollout draws them (hitter, role, returns, opponent, the strike's number, the serve, the
    surface); None where the model has none."""
    if states.receiver_id is None:
        return None
    return model.strike_head_bias(torch.as_tensor(states.hitter_id()),
                                  torch.as_tensor(states.receiver),
                                  torch.as_tensor(states.returns()),
                                  torch.as_tensor(states.opponent_id()),
                                  torch.as_tensor(states.shot_numbers()),
                                  torch.as_tensor(states.contact_m[:, 0]),
                                  torch.as_tensor(states.serve),
                                  None if states.surface is None
                                  else torch.as_tensor(states.surface))


def held_out(states: HeadStates, every: int = HELD_OUT_EVERY) -> np.ndarray:
    """(N,) bool: the strikes of the held-out rallies (whole rallies: id a multiple of
    `every`)."""
    if every < 2:
        raise ValueError(f"every must be >= 2, got {every}")
    return states.rally_id % every == 0


def _nll(model: SportsNGEN, states: HeadStates, rows: torch.Tensor,
         bias: torch.Tensor | None) -> torch.Tensor:
    return model.strike_head.nll(head_inputs(model, "strike", states, rows), states.bins[rows],
                                 None if bias is None else bias[rows])


def fit_strike_inputs(model: SportsNGEN, states: HeadStates, parts: tuple[str, ...] = ("shot",),
                      steps: int = 3000, lr: float = 3e-3, weight_decay: float = 0.0,
                      batch_size: int = 512, eval_every: int = 250,
                      every: int = HELD_OUT_EVERY, seed: int = 0,
                      progress: bool = True) -> list[dict]:
    """Fit the strike head's input shifts named in `parts` ("shot": `model.strike_shot`,
    "players": `model.strike_player` and `strike_opponent`) in place, nothing else moving, on
    the strikes `states` outside the held-out rallies (`held_out`) with AdamW, keeping them at
    their best held-out NLL. -> the history [{"step", "val_nll"}], step 0 the model as it
    came."""
    params = _parameters(model, tuple(parts))
    if steps < 1 or batch_size < 1 or eval_every < 1:
        raise ValueError("steps, batch_size and eval_every must be positive")
    val = held_out(states, every)
    train_rows = torch.as_tensor(np.flatnonzero(~val))
    val_rows = torch.as_tensor(np.flatnonzero(val))
    if len(train_rows) == 0 or len(val_rows) == 0:
        raise ValueError("the fit needs strikes in and out of the held-out rallies")
    # The shot numbers counted once, not at every step's `head_inputs`.
    states = dataclasses.replace(states, shot=states.shot_numbers())
    bias = table_bias(model, states)
    was_training = model.training
    model.eval()        # the head's dropout off: only the shifts are fitted
    grads = {id(p): p.requires_grad for p in model.parameters()}
    for p in model.parameters():
        p.requires_grad_(False)
    for p in params:
        p.requires_grad_(True)
    opt = torch.optim.AdamW(params, lr=lr, weight_decay=weight_decay)
    g = torch.Generator().manual_seed(seed)

    def val_nll() -> float:
        with torch.no_grad():
            return float(_nll(model, states, val_rows, bias).mean())

    def snapshot() -> list[torch.Tensor]:
        return [p.detach().clone() for p in params]

    history = [{"step": 0, "val_nll": val_nll()}]
    best = (history[0]["val_nll"], snapshot())
    bar = tqdm(range(steps), desc=f"fit {'+'.join(parts)} shifts", disable=not progress)
    for step in bar:
        rows = train_rows[torch.randint(len(train_rows), (batch_size,), generator=g)]
        loss = _nll(model, states, rows, bias).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if (step + 1) % eval_every == 0 or step + 1 == steps:
            v = val_nll()
            history.append({"step": step + 1, "val_nll": v})
            if v < best[0]:
                best = (v, snapshot())
            bar.set_postfix(val_nll=f"{v:.4f}", best=f"{best[0]:.4f}")
    with torch.no_grad():
        for p, kept in zip(params, best[1]):
            p.copy_(kept)
    for p in model.parameters():
        p.requires_grad_(grads[id(p)])
    model.train(was_training)
    return history


@torch.no_grad()
def shot_profile(model: SportsNGEN, states: HeadStates,
                 keep: np.ndarray | None = None) -> pd.DataFrame:
    """The head teacher-forced at the strikes `states` (rows `keep`, default all), by shot
    bucket (`strike_heads.shot_bucket`) and serve: n, over the strikes whose record is in
    play the record's and the head's mean depth beyond the net of the balls in play, over
    those whose record clears the net their mean height over the net of the balls above it
    (the head's means over those bins, each dimension given the record's earlier ones, with
    the file's tables), and the head's NLL per dimension (nats)."""
    keep = np.ones(len(states), dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    rows = torch.as_tensor(np.flatnonzero(keep))
    x, bins = head_inputs(model, "strike", states, rows), states.bins[rows]
    bias = table_bias(model, states)
    bias = None if bias is None else bias[rows]
    edges = strike.strike_edges()
    centre = torch.as_tensor(0.5 * (edges[:, 1:] + edges[:, :-1]))
    errors = torch.as_tensor(strike_bias.error_bins())
    cols = {}
    for k, name in ((0, "depth"), (2, "height")):
        logits = model.strike_head.dim_logits(x, bins, k, bias)
        ok = ~errors[k]                     # in play (depth) or above the net (height)
        p = logits.softmax(-1) * ok
        head = (p * centre[k]).sum(-1) / p.sum(-1).clamp_min(1e-12)
        # Both over the strikes whose record is in play (above the net).
        mine = ok[bins[:, k]]
        cols[f"{name}_record_m"] = torch.where(mine, centre[k][bins[:, k]].double(),
                                               float("nan")).numpy()
        cols[f"{name}_head_m"] = torch.where(mine, head.double(), float("nan")).numpy()
    for k, name in enumerate(strike.STRIKE_DIMS):
        lp = model.strike_head.dim_logits(x, bins, k, bias).log_softmax(-1)
        cols[f"nll_{name}"] = -lp.gather(-1, bins[:, k:k + 1])[:, 0].double().numpy()
    shot = states.shot_numbers()[keep]
    t = pd.DataFrame({"shot_row": shot_bucket(torch.as_tensor(shot)).numpy(),
                      "serve": states.serve[keep] + 1, **cols})
    out = t.groupby(["shot_row", "serve"]).agg(n=("serve", "size"),
                                               **{c: (c, "mean") for c in cols})
    return out.reset_index()


__all__ = ["PARTS", "fit_strike_inputs", "held_out", "shot_profile", "table_bias",
           "with_strike_players", "with_strike_shots"]
