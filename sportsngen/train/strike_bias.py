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

from sportsngen.model import strike, strike_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates, head_inputs
from sportsngen.train.serve_bias import (
    MAX_SHIFT,
    bisect_shift,
    matched_shift,
    mean_odds,
    pulled_toward,
    solve_shift,
)

KINDS = ("long", "wide", "net")
SHAPES = ("depth", "height")


def with_strike_bias(model: SportsNGEN) -> SportsNGEN:
    """`model` with the per-hitter table added (`cfg.strike_bias`), at zero: it draws as
    before until `fit_strike_bias` fills it. -> a new model (the same one if it has it)."""
    return with_flag(model, "strike_bias", ["strike_bias"])


@torch.no_grad()
def check_prior(prior_strikes: float, min_strikes: int) -> None:
    """A table fit's pseudo-strikes and smallest cell: `ValueError` where they make no
    sense."""
    if prior_strikes < 0 or min_strikes < 1:
        raise ValueError(f"prior_strikes must be >= 0 and min_strikes >= 1, got "
                         f"{prior_strikes} and {min_strikes}")


def fit_strike_bias(model: SportsNGEN, states: HeadStates, prior_strikes: float = 200.0,
                    min_strikes: int = 50) -> pd.DataFrame:
    """Fill `model.strike_bias` (in place) from the recorded rally strikes `states` (with the
    receivers' identities), per hitter and role with at least `min_strikes` strikes (others
    keep 0). -> per (hitter_id, receiver): n, and per kind the record's share, the head's
    before, the target, the head's after and the shift."""
    if model.strike_bias is None:
        raise ValueError("the model has no per-hitter table (cfg.strike_bias): add it with "
                         "with_strike_bias")
    check_prior(prior_strikes, min_strikes)
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


def head_draws(model: SportsNGEN, states: HeadStates, rows: np.ndarray, x: torch.Tensor,
               draws: int, seed: int = 0) -> tuple[np.ndarray, torch.Tensor, torch.Tensor]:
    """The strikes `rows` of `states` (head inputs `x`) each repeated `draws` times, with the
    head's own draw of every dimension's bin under the file's tables (what a rollout draws):
    a kind's odds read at the drawn earlier dimensions, not the record's. Matched at the
    record's depth and lateral, the head's errors equal the record's there; a rollout draws
    its net height after its own depth and lateral, and where the head's joint puts those
    where a net ball follows it errs more than matched (at clay truth strikes 0.129 matched,
    0.154 drawn: the fifty-second part). -> (rows repeated, x repeated, the drawn bins)."""
    if draws < 1:
        raise ValueError(f"draws must be >= 1, got {draws}")
    rep = np.repeat(np.arange(len(rows)), draws)
    rows = np.asarray(rows)[rep]
    x = x[torch.as_tensor(rep)]
    bias = states_strike_bias(model, states, rows, x.dtype)
    gen = torch.Generator().manual_seed(seed)
    return rows, x, model.strike_head.sample(x, 1.0, gen, dim_bias=bias)


def states_strike_bias(model: SportsNGEN, states: HeadStates, rows: np.ndarray,
                       dtype: torch.dtype) -> torch.Tensor | None:
    """(len(rows), 4, bins): every table of the file's shift of the strike head's odds at the
    recorded strikes `rows` of `states` (`SportsNGEN.strike_head_bias`: each strike's hitter,
    role, return or not, opponent, number, depth, serve and, where read, surface); None where
    the model has no table."""
    return model.strike_head_bias(
        torch.as_tensor(states.hitter_id()[rows]),
        torch.as_tensor(states.receiver[rows].astype(bool)),
        torch.as_tensor(states.returns()[rows]),
        torch.as_tensor(states.opponent_id()[rows]),
        torch.as_tensor(states.shot_numbers()[rows]),
        torch.as_tensor(states.contact_m[rows, 0], dtype=dtype),
        torch.as_tensor(states.serve[rows]),
        None if states.surface is None else torch.as_tensor(states.surface[rows]))


def with_strike_width(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the error table) with the per-hitter width added (`cfg.strike_width`), at
    zero: it draws as before until `fit_strike_width` fills it. -> a new model."""
    return with_flag(model, "strike_width", ["strike_width"])


def _width_in_play(logits: torch.Tensor, tilt: torch.Tensor, inside: torch.Tensor,
                   offset_m: torch.Tensor, shift: float) -> float:
    """Mean over rows of the lateral draw's mean distance from the centre line among the bins
    in play, with the width's `shift`."""
    p = (logits + shift * tilt).softmax(-1) * inside
    return float(((p * offset_m).sum(-1) / p.sum(-1).clamp_min(1e-12)).mean())


@torch.no_grad()
def fit_strike_width(model: SportsNGEN, states: HeadStates, prior_strikes: float = 200.0,
                     min_strikes: int = 50, refit_wide: bool = True) -> pd.DataFrame:
    """Fill `model.strike_width` (in place) from the recorded rally strikes `states`, per
    hitter and role with at least `min_strikes` strikes in play sideways: the tilt whose mean
    distance from the centre line of the head's lateral draws in play (read at the record's
    depth bin) equals his record's, pulled toward the head's own by `prior_strikes`
    pseudo-strikes (it rises with the tilt, so a bisection finds it); then, the tilt moving
    a little of the lateral mass across the singles lines, with `refit_wide` his wide error's
    shift refitted on the tilted odds (`fit_strike_bias` must have run; a file with the returns'
    and opponents' tables refits them all instead, `fit_strike_pressure`, which reads the
    tilt). -> per (hitter_id, receiver): n, the record's, the head's before and after mean
    distances (m), the tilt and (with `refit_wide`) the wide error's shift after."""
    if model.strike_width is None or model.strike_bias is None:
        raise ValueError("the model has no per-hitter width (cfg.strike_width): add it with "
                         "with_strike_width after fit_strike_bias")
    head = model.strike_head
    wide = torch.as_tensor(strike_bias.error_bins()[strike_bias.WIDE])
    inside = (~wide).to(states.h.dtype)
    tilt = torch.as_tensor(strike_bias.width_tilt(), dtype=states.h.dtype)
    offset_m = torch.as_tensor(strike_bias.lateral_offsets_m(), dtype=states.h.dtype)
    keys = pd.DataFrame({"hitter_id": states.hitter_id(), "receiver": states.receiver})
    rows = []
    for (hid, recv), g in keys.groupby(["hitter_id", "receiver"]):
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        bins = states.bins[i]
        in_play = ~wide[bins[:, 1]]
        n = int(in_play.sum())
        if n < min_strikes:
            continue
        logits = head.dim_logits(head_inputs(model, "strike", states, i), bins, 1)
        play = logits[in_play]
        record = float(offset_m[bins[in_play, 1]].mean())
        before = _width_in_play(play, tilt, inside, offset_m, 0.0)
        target = pulled_toward(record, before, n, prior_strikes)
        shift = bisect_shift(lambda s, lg=play: _width_in_play(lg, tilt, inside, offset_m, s),
                             target, MAX_SHIFT)
        model.strike_width[int(hid), int(recv)] = shift
        row = {"hitter_id": int(hid), "receiver": bool(recv), "n": n,
               "width_record_m": record, "width_head_m": before,
               "width_after_m": _width_in_play(play, tilt, inside, offset_m, shift),
               "width_shift": shift}
        if refit_wide:
            # The wide error's shift again, on all his strikes' lateral odds with the tilt.
            tilted = logits + shift * tilt
            mask = wide.expand(len(i), -1)
            fit = matched_shift(tilted, mask, mask.to(tilted.dtype),
                                float(wide[bins[:, 1]].float().mean()), prior_strikes)
            model.strike_bias[int(hid), int(recv), strike_bias.WIDE] = fit["shift"]
            row.update({"wide_shift": fit["shift"], "wide_after": fit["after"]})
        rows.append(row)
    return pd.DataFrame(rows)


def with_strike_return(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the error table) with the returns' table added (`cfg.strike_return`), at
    zero: it draws as before until `fit_strike_return` fills it. -> a new model."""
    return with_flag(model, "strike_return", ["strike_return"])


@torch.no_grad()
def fit_strike_return(model: SportsNGEN, states: HeadStates, returns: np.ndarray,
                      prior_strikes: float = 200.0, min_strikes: int = 50,
                      rally: bool = True, draws: int = 0) -> pd.DataFrame:
    """Split each receiver's error shifts (in place): his receiving role's shifts refitted on
    his recorded strikes that are not returns (with `rally`; without, they stay as they are),
    then the returns' table (`model.strike_return`) fitted on his returns (`returns` (N,) bool
    over `states`; `HeadStates.returns`) on top of them, each by matching as
    `fit_strike_bias` (the lateral odds with his width's tilt where the model has one). The
    servers' shifts are left alone. With `draws`, each strike's odds are read at that many of
    the head's own draws (`head_draws`). -> per (hitter_id, return): n, and per kind the record's
    share, the head's before, the target, after and the shift."""
    if model.strike_bias is None or model.strike_return is None:
        raise ValueError("the model has no returns' table (cfg.strike_return): add it with "
                         "with_strike_return after fit_strike_bias")
    if len(returns) != len(states):
        raise ValueError(f"returns has {len(returns)} rows, the states {len(states)}")
    if prior_strikes < 0 or min_strikes < 1:
        raise ValueError(f"prior_strikes must be >= 0 and min_strikes >= 1, got "
                         f"{prior_strikes} and {min_strikes}")
    head = model.strike_head
    masks = torch.as_tensor(strike_bias.error_bins())
    tilt = torch.as_tensor(strike_bias.width_tilt(), dtype=states.h.dtype)
    keys = pd.DataFrame({"hitter_id": states.hitter_id(), "receiver": states.receiver,
                         "is_return": np.asarray(returns, dtype=bool) & states.receiver})
    rows = []
    # Per hitter his other strikes come first (False sorts first), so a return's fit starts
    # from his refitted receiving shifts.
    for (hid, ret), g in keys[keys["receiver"]].groupby(["hitter_id", "is_return"]):
        if len(g) < min_strikes or not (ret or rally):
            continue
        hid, ret = int(hid), bool(ret)
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        x, bins = head_inputs(model, "strike", states, i), states.bins[i]
        prev, prior = bins, prior_strikes
        if draws:
            idx, x, prev = head_draws(model, states, i.numpy(), x, draws)
            bins, prior = states.bins[torch.as_tensor(idx)], prior_strikes * draws
        n = len(i)
        row = {"hitter_id": hid, "is_return": ret, "n": n}
        for kind, name in enumerate(KINDS):
            logits = head.dim_logits(x, prev, kind)
            if kind == strike_bias.WIDE and model.strike_width is not None:
                logits = logits + model.strike_width[hid, 1] * tilt
            mask = masks[kind].expand(len(x), -1)
            weight = mask.to(logits.dtype)
            if ret:
                logits = logits + model.strike_bias[hid, 1, kind] * weight
            record = float(masks[kind][bins[:, kind]].float().mean())
            fit = matched_shift(logits, mask, weight, record, prior)
            if ret:
                model.strike_return[hid, kind] = fit["shift"]
            else:
                model.strike_bias[hid, 1, kind] = fit["shift"]
            row.update({f"{name}_{k}": v for k, v in fit.items()})
        rows.append(row)
    return pd.DataFrame(rows)


def with_strike_pressure(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the returns' table) with the opponents' table added
    (`cfg.strike_pressure`), at zero: it draws as before until `fit_strike_pressure` fills it.
    -> a new model."""
    return with_flag(model, "strike_pressure", ["strike_pressure"])


def _check_rounds(states: HeadStates, returns: np.ndarray, rounds: int, prior_strikes: float,
                  min_strikes: int) -> None:
    """The arguments of a fit of two tables in turn over the strikes that are not returns."""
    if len(returns) != len(states):
        raise ValueError(f"returns has {len(returns)} rows, the states {len(states)}")
    if rounds < 1 or prior_strikes < 0 or min_strikes < 1:
        raise ValueError(f"rounds and min_strikes must be >= 1 and prior_strikes >= 0, got "
                         f"{rounds}, {min_strikes} and {prior_strikes}")


def match_cell(logits: list[torch.Tensor], record: list[torch.Tensor], masks: torch.Tensor,
               j: torch.Tensor, offset, prior_strikes: float) -> tuple[list[float], dict]:
    """One cell's rows `j` of an in-turn table fit: per kind (`KINDS`) the shift that matches
    their odds (`logits[kind][j]`, with `offset(kind)` (len(j),) the other tables' shifts on
    the kind's bins) to the record's share there (`matched_shift`). -> (the shifts, the row's
    record / head / after / shift columns)."""
    shifts, row = [], {}
    for kind, kname in enumerate(KINDS):
        mask = masks[kind].expand(len(j), -1)
        weight = mask.to(logits[kind].dtype)
        base = logits[kind][j] + offset(kind)[:, None] * weight
        fit = matched_shift(base, mask, weight, float(record[kind][j].mean()), prior_strikes)
        shifts.append(fit["shift"])
        row.update({f"{kname}_{k}": fit[k] for k in ("record", "head", "after", "shift")})
    return shifts, row


@torch.no_grad()
def fit_strike_pressure(model: SportsNGEN, states: HeadStates, returns: np.ndarray,
                        rounds: int = 4, prior_strikes: float = 200.0,
                        min_strikes: int = 50, late_only: bool = False,
                        depth_only: bool = False, draws: int = 0) -> pd.DataFrame:
    """Fill the opponents' table (`model.strike_pressure`) and refit the hitters' rows
    (`model.strike_bias`), in place, on the recorded rally strikes `states` that are not
    returns (`returns` (N,) bool; `HeadStates.returns`), then the returns' table on top of the
    hitters' rows. A strike's odds of each error get his row (by role) plus his opponent's;
    the two are found in turn for `rounds` rounds, each cell (an identity and the hitter's
    role, with at least `min_strikes` strikes) by matching its strikes' mean odds to the
    record's, pulled toward the odds before by `prior_strikes` pseudo-strikes, as
    `fit_strike_bias` does. A constant moved from every hitter's row to every opponent's
    reads the same; the prior keeps each table near where the head's own odds were. A model
    with the late table (`cfg.strike_late`) gets it fitted in the same turns, each hitter's
    cell by role on his strikes numbered `strike_bias.LATE_SHOT` or more, on top of his row,
    which is then matched on his other strikes; with `late_only` the late table alone, on top
    of the others as they are (one round; the returns' table kept). A model with the depth
    table (`cfg.strike_depth`) gets it fitted in the same turns, a cell per band of the
    contact's depth (`strike_bias.depth_band` of `HeadStates.contact_m`) and role; with
    `depth_only` the depth table alone on top of the others as they are (one round), then
    centred: per role and kind one constant taken from its fitted cells keeps the role's mean
    odds of that error what they were without it, so it tilts the errors by depth and leaves
    their level to the other tables. With `draws`, each strike's odds are read at that many
    of the head's own draws of the earlier dimensions (`head_draws`: as a rollout draws),
    not at the record's, and the returns' table likewise. -> per (table: "opponent",
    "hitter", "late" or "depth", id (the band for "depth"), receiver) of the last round: n and
    per kind the record's share, the odds before and after, and the shift (before centring)."""
    if model.strike_pressure is None:
        raise ValueError("the model has no opponents' table (cfg.strike_pressure): add it with "
                         "with_strike_pressure")
    _check_rounds(states, returns, rounds, prior_strikes, min_strikes)
    head = model.strike_head
    masks = torch.as_tensor(strike_bias.error_bins())
    rows = np.flatnonzero(~np.asarray(returns, dtype=bool))
    i = torch.as_tensor(rows)
    x, bins = head_inputs(model, "strike", states, i), states.bins[i]
    prev, given = bins, (prior_strikes, min_strikes)
    if draws:
        rows, x, prev = head_draws(model, states, rows, x, draws)
        bins = states.bins[torch.as_tensor(rows)]
        # A strike's draws together weigh as the strike did (the returns' fit repeats its own).
        prior_strikes, min_strikes = prior_strikes * draws, min_strikes * draws
    recv = torch.as_tensor(states.receiver[rows].astype(bool))
    hitter = torch.as_tensor(states.hitter_id()[rows])
    opponent = torch.as_tensor(states.opponent_id()[rows])
    logits = [head.dim_logits(x, prev, kind) for kind in range(strike_bias.N_KINDS)]
    if model.strike_width is not None:
        tilt = torch.as_tensor(strike_bias.width_tilt(), dtype=x.dtype)
        w = model.strike_width[hitter, recv.long()]
        logits[strike_bias.WIDE] = logits[strike_bias.WIDE] + w[:, None] * tilt
    if model.strike_shape is not None:
        # The shapes' tilts move a little mass across the baseline and the net: the errors'
        # odds are matched with them.
        tilted = strike_bias.shape_bias(model.strike_shape, model.strike_shape_opponent,
                                        hitter, recv, opponent_id=opponent)
        for kind, dim in ((strike_bias.LONG, 0), (strike_bias.NET, 2)):
            logits[kind] = logits[kind] + tilted[:, dim]
    record = [masks[k][bins[:, k]].to(x.dtype) for k in range(strike_bias.N_KINDS)]
    if late_only and depth_only:
        raise ValueError("late_only and depth_only each fit one table alone: give one")
    if late_only and model.strike_late is None:
        raise ValueError("late_only fits the late table (cfg.strike_late): add it with "
                         "with_strike_late")
    if depth_only and model.strike_depth is None:
        raise ValueError("depth_only fits the depth table (cfg.strike_depth): add it with "
                         "with_strike_depth")
    every = torch.ones(len(rows), dtype=torch.bool)
    # Each table: its tensor, the identity that picks a strike's row, the strikes it is added
    # on, the strikes it is matched on.
    tables = {"opponent": (model.strike_pressure, opponent, every, every),
              "hitter": (model.strike_bias, hitter, every, every)}
    if model.strike_late is not None:
        # A hitter's row is matched on his early strikes and his late row on his late ones on
        # top of it, so the two do not pull each other round by round (matched both on all,
        # the early strikes' error closed by a fifth a round). Where a role has too few late
        # strikes for a cell, they stay with the early ones.
        late = states.shot_numbers()[rows] >= strike_bias.LATE_SHOT
        cells = pd.DataFrame({"id": hitter.numpy(), "receiver": recv.numpy(), "late": late})
        size = cells.groupby(["id", "receiver", "late"])["late"].transform("size").to_numpy()
        apart = torch.as_tensor(late & (size >= min_strikes))
        tables["hitter"] = (model.strike_bias, hitter, every, ~apart)
        tables["late"] = (model.strike_late, hitter, torch.as_tensor(late), apart)
    band = None
    if model.strike_depth is not None:
        band = strike_bias.depth_band(torch.as_tensor(states.contact_m[rows, 0]))
        tables["depth"] = (model.strike_depth, band, every, every)
    alone = "late" if late_only else "depth" if depth_only else None
    if alone is not None:
        # The other tables still add on their strikes, but none is matched; nothing else moves.
        tables = {k: (t, ids, on, matched if k == alone else ~every)
                  for k, (t, ids, on, matched) in tables.items()}
        rounds = 1

    def others(name: str, j: torch.Tensor, rcv: int, kind: int) -> torch.Tensor:
        """The strikes `j`'s shifts of `kind` from every table but `name`."""
        return sum(t[ids[j], rcv, kind] * on[j].to(x.dtype)
                   for other, (t, ids, on, _) in tables.items() if other != name)

    out = []
    for r in range(rounds):
        for name, (table, ids, _, matched) in tables.items():
            keys = pd.DataFrame({"id": ids.numpy(), "receiver": recv.numpy()})[matched.numpy()]
            for (cid, rcv), g in keys.groupby(["id", "receiver"]):
                if len(g) < min_strikes:
                    continue
                j = torch.as_tensor(g.index.to_numpy(copy=True))
                shifts, fitted = match_cell(
                    logits, record, masks, j,
                    lambda kind, j=j, rcv=int(rcv), name=name: others(name, j, rcv, kind),
                    prior_strikes)
                table[int(cid), int(rcv)] = torch.as_tensor(shifts, dtype=table.dtype)
                row = {"table": name, "id": int(cid), "receiver": bool(rcv),
                       "n": len(j) // max(draws, 1), **fitted}
                if r == rounds - 1:
                    out.append(row)
    if depth_only:
        _centre_depth(model.strike_depth, band, recv, logits,
                      lambda j, rcv, kind: others("depth", j, rcv, kind), min_strikes)
    if alone is None:
        fit_strike_return(model, states, returns, *given, rally=False, draws=draws)
    return pd.DataFrame(out)


def _centre_depth(table: torch.Tensor, band: torch.Tensor, receiver: torch.Tensor,
                  logits: list[torch.Tensor], others, min_strikes: int) -> None:
    """Centre the fitted depth `table` (in place) where the errors are drawn: per role and kind
    one constant taken from its cells with at least `min_strikes` strikes makes the role's mean
    odds of that error (over its strikes `band` (N,), `receiver` (N,) bool, head `logits` per
    kind plus `others(j, role, kind)`, the other tables' shifts) those without the table. A
    zero mean in logits raised them: the odds are convex in the shift."""
    masks = torch.as_tensor(strike_bias.error_bins())
    for rcv in (0, 1):
        j = torch.as_tensor(np.flatnonzero(receiver.numpy() == rcv))
        fitted = torch.bincount(band[j], minlength=table.shape[0]) >= min_strikes
        if not bool(fitted.any()):
            continue
        for kind in range(strike_bias.N_KINDS):
            weight = masks[kind].expand(len(j), -1).to(logits[kind].dtype)
            base = logits[kind][j] + others(j, rcv, kind)[:, None] * weight
            level = float(mean_odds(base, weight, weight, torch.zeros(1))[0])
            tilted = base + table[band[j], rcv, kind][:, None] * weight
            movable = weight * fitted[band[j]].to(weight.dtype)[:, None]
            table[fitted, rcv, kind] += solve_shift(tilted, movable, weight, level)


def with_strike_depth(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the opponents' table) with the depth table added (`cfg.strike_depth`), at
    zero: it draws as before until `fit_strike_pressure` fills it. -> a new model."""
    return with_flag(model, "strike_depth", ["strike_depth"])


def with_strike_late(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the opponents' table) with the late strikes' table added
    (`cfg.strike_late`), at zero: it draws as before until `fit_strike_pressure` fills it.
    -> a new model."""
    return with_flag(model, "strike_late", ["strike_late"])


def with_strike_second(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the player's table) with the second serves' rally table added
    (`cfg.strike_second`), at zero: it draws as before until its own rollouts move it
    (`train.rollout_tables.add_rollout_second_shift`). -> a new model."""
    return with_flag(model, "strike_second", ["strike_second"])


def error_shares(table: pd.DataFrame) -> pd.DataFrame:
    """`fit_strike_bias`'s (or `fit_strike_return`'s) table -> per row the share of strikes in
    error (long, or else wide, or else into the net) by the record, the head before and after,
    the kinds taken as independent (the head draws them one after another): a summary to
    print."""
    out = table[[c for c in ("hitter_id", "receiver", "is_return", "n") if c in table]].copy()
    for when in ("record", "head", "after"):
        keep = np.ones(len(table))
        for name in KINDS:
            keep = keep * (1.0 - table[f"{name}_{when}"].to_numpy())
        out[f"error_{when}"] = 1.0 - keep
    return out


def with_strike_shape(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the opponents' table) with the hitters' and opponents' shape tables added
    (`cfg.strike_shape`), at zero: it draws as before until `fit_strike_shape` fills them.
    -> a new model."""
    return with_flag(model, "strike_shape", ["strike_shape", "strike_shape_opponent"])


def _mean_kept(logits: torch.Tensor, tilt: torch.Tensor, keep: torch.Tensor,
               value: torch.Tensor, shift: float) -> float:
    """Mean over rows of the draw's mean `value` among the bins `keep`, with `shift` units of
    `tilt` added to `logits`."""
    p = (logits + shift * tilt).softmax(-1) * keep
    return float(((p * value).sum(-1) / p.sum(-1).clamp_min(1e-12)).mean())


@torch.no_grad()
def fit_strike_shape(model: SportsNGEN, states: HeadStates, returns: np.ndarray,
                     rounds: int = 4, prior_strikes: float = 200.0,
                     min_strikes: int = 50) -> pd.DataFrame:
    """Fill the shape tables (`model.strike_shape`, per hitter, and
    `model.strike_shape_opponent`, per opponent, by the hitter's role), in place, on the
    recorded rally strikes `states` that are not returns (`returns` (N,) bool), then refit
    the error tables with the tilts (`fit_strike_pressure`). Per shape (the depth of the
    balls in play, the height over the net of the balls not in it) a cell's tilt makes the
    head's mean on its strikes whose record is in play (over the net) equal the record's,
    pulled toward the head's before by `prior_strikes` pseudo-strikes (it rises with the
    tilt: a bisection); the hitters' and the opponents' cells are found in turn for `rounds`
    rounds, each on top of the other's. -> per (table, id, receiver, shape) of the last
    round: n, the record's, the head's before and after means (m) and the tilt."""
    if model.strike_shape is None:
        raise ValueError("the model has no shape tables (cfg.strike_shape): add them with "
                         "with_strike_shape")
    _check_rounds(states, returns, rounds, prior_strikes, min_strikes)
    head = model.strike_head
    rows = np.flatnonzero(~np.asarray(returns, dtype=bool))
    i = torch.as_tensor(rows)
    x, bins = head_inputs(model, "strike", states, i), states.bins[i]
    recv = torch.as_tensor(states.receiver[rows].astype(bool))
    ids = {"hitter": torch.as_tensor(states.hitter_id()[rows]),
           "opponent": torch.as_tensor(states.opponent_id()[rows])}
    tables = {"hitter": model.strike_shape, "opponent": model.strike_shape_opponent}
    edges = strike.strike_edges()
    errors = strike_bias.error_bins()
    tilts = (strike_bias.depth_tilt(), strike_bias.height_tilt())
    shapes = []
    for k, (dim, kind) in enumerate(((0, strike_bias.LONG), (2, strike_bias.NET))):
        keep = torch.as_tensor(~errors[kind])
        value = torch.as_tensor(0.5 * (edges[dim, 1:] + edges[dim, :-1]), dtype=x.dtype)
        kept = keep[bins[:, dim]]
        shapes.append({"dim": dim, "logits": head.dim_logits(x, bins, dim), "kept": kept,
                       "keep": keep.to(x.dtype), "value": value,
                       "tilt": torch.as_tensor(tilts[k], dtype=x.dtype),
                       "record": value[bins[:, dim]]})
    out = []
    for r in range(rounds):
        for name, table in tables.items():
            other = "opponent" if name == "hitter" else "hitter"
            keys = pd.DataFrame({"id": ids[name].numpy(), "receiver": recv.numpy()})
            for (cid, rcv), g in keys.groupby(["id", "receiver"]):
                j = torch.as_tensor(g.index.to_numpy(copy=True))
                for k, sh in enumerate(shapes):
                    jj = j[sh["kept"][j]]
                    n = len(jj)
                    if n < min_strikes:
                        continue
                    base = sh["logits"][jj] + \
                        tables[other][ids[other][jj], int(rcv), k][:, None] * sh["tilt"]

                    def mean(s: float, lg=base, sh=sh) -> float:
                        return _mean_kept(lg, sh["tilt"], sh["keep"], sh["value"], s)

                    record = float(sh["record"][jj].mean())
                    before = mean(0.0)
                    shift = bisect_shift(mean, pulled_toward(record, before, n, prior_strikes),
                                         MAX_SHIFT)
                    table[int(cid), int(rcv), k] = shift
                    if r == rounds - 1:
                        out.append({"table": name, "id": int(cid), "receiver": bool(rcv),
                                    "shape": SHAPES[k], "n": n, "record_m": record,
                                    "head_m": before, "after_m": mean(shift), "tilt": shift})
    fit_strike_pressure(model, states, returns, prior_strikes=prior_strikes,
                        min_strikes=min_strikes)
    return pd.DataFrame(out)
