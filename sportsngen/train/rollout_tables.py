"""The late strikes' error table, and the player's own rally rows, moved by the model's own
rollouts (closed loop).

`ModelConfig.strike_late` adds a shift per hitter and role on his strikes from the rally's fifth
on. Matched to the record's strikes (`train.strike_bias.fit_strike_pressure`) it moved the
wrong way: at the record's own late states the head errs less than the record for nearly every
named hitter, while in rollouts the same hitters' late balls err more than a large truth's, the
model's players arriving worse than the record's (docs/evaluation.md, forty-eighth part). Here
the table is moved by what the rollouts drew instead: per hitter and role, the log-odds gap
between a truth's share of his late strikes that ended the point as his error and his
rollouts' share (`eval.shot_profile.strike_endings`), pooled over matchups, shrunk toward zero
by `prior_strikes` pseudo-strikes and added to all three of his error kinds (for errors this
rare a shift of every error bin by d multiplies his odds of an error by about e^d). The same
gaps over every strike after the return move the player's own rows instead
(`add_rollout_rally_shift`, docs/evaluation.md, seventy-third part): in rollouts Federer's
and Nadal's rally balls erred more than a truth's, and more than the generator's players
from the same states. The same gaps over a second serve's rally strikes alone move the second
serves' table (`add_rollout_second_shift`, `ModelConfig.strike_second`; docs/evaluation.md,
seventy-fourth part): there the receivers' rally balls erred 0.04-0.05 more than a truth's,
after first serves as the truth's.
"""

from __future__ import annotations

import pandas as pd
import torch

from sportsngen.data.tokens import Vocab
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.serve_bias import MAX_SHIFT, share_logit

LATE_STAGE = "shots 5+"            # `eval.shot_profile.STRIKE_STAGES`' stage the table covers
RALLY_STAGES = ("shots 2-4", LATE_STAGE)   # every strike after the return
ROLES = ("server", "receiver")     # `strike_endings`' roles, in the table's order


def at_serve(endings: pd.DataFrame, serve_number: int) -> pd.DataFrame:
    """The rows of one serve (1 first, 2 second) of a `strike_endings(..., by_serve=True)`
    table, indexed as a table without the split."""
    if "serve_number" not in endings.index.names:
        raise ValueError("not a strike_endings table split by serve (by_serve=True)")
    return endings.xs(serve_number, level="serve_number")


def _at_stage(endings: pd.DataFrame, stage: str | tuple[str, ...]) -> pd.DataFrame:
    """A `strike_endings` table's `n` and `error` on `stage` (several: pooled), indexed by
    hitter and role."""
    stages = (stage,) if isinstance(stage, str) else tuple(stage)
    rows = endings[endings.index.get_level_values("stage").isin(stages)]
    rows = rows.assign(errors=rows["n"] * rows["error"]).groupby(["hitter", "role"])
    out = rows[["n", "errors"]].sum()
    return pd.DataFrame({"n": out["n"], "error": out["errors"] / out["n"]})


def rollout_error_gaps(pairs: list[tuple[pd.DataFrame, pd.DataFrame]],
                       stage: str | tuple[str, ...] = LATE_STAGE) -> pd.DataFrame:
    """`pairs` of (a matchup's rollouts' `strike_endings`, the same matchup's truth's) -> per
    hitter and role on `stage` (several stages: pooled): the rollouts' strikes `n`, their
    error share and the truth's (each pooled over the matchups, weighted by the rollouts'
    strikes) and `gap`, the truth's
    log-odds less the rollouts', averaged over the matchups with the same weights. A hitter
    with strikes on one side only is left out."""
    if not pairs:
        raise ValueError("no (rollouts, truth) pair given")
    rows = []
    for k, (sim, truth) in enumerate(pairs):
        for name, table in (("sim", sim), ("truth", truth)):
            if not {"n", "error"} <= set(table.columns):
                raise ValueError(f"pair {k}'s {name} is not a strike_endings table")
        both = _at_stage(sim, stage).join(_at_stage(truth, stage), lsuffix="_sim",
                                          rsuffix="_truth", how="inner")
        both["gap"] = share_logit(both["error_truth"].to_numpy(), both["n_truth"].to_numpy()) \
            - share_logit(both["error_sim"].to_numpy(), both["n_sim"].to_numpy())
        rows.append(both.reset_index())
    frame = pd.concat(rows, ignore_index=True)
    w = frame["n_sim"]
    frame = frame.assign(err_sim_w=frame["error_sim"] * w, err_truth_w=frame["error_truth"] * w,
                         gap_w=frame["gap"] * w)
    out = frame.groupby(["hitter", "role"]).agg(n=("n_sim", "sum"), es=("err_sim_w", "sum"),
                                                et=("err_truth_w", "sum"), g=("gap_w", "sum"))
    return pd.DataFrame({"n": out["n"], "error_sim": out["es"] / out["n"],
                         "error_truth": out["et"] / out["n"], "gap": out["g"] / out["n"]})


def _shrunk_steps(vocab: Vocab, gaps: pd.DataFrame, prior_strikes: float
                  ) -> list[tuple[int, int, float]]:
    """(identity, role index, step) per row of `gaps`: its `gap` shrunk by n / (n +
    `prior_strikes`). Every row is checked before any cell moves."""
    if prior_strikes < 0:
        raise ValueError(f"prior_strikes must be >= 0, got {prior_strikes}")
    out = []
    for (hitter, role), row in gaps.iterrows():
        if role not in ROLES:
            raise ValueError(f"role must be one of {ROLES}, got {role!r}")
        out.append((vocab.player_index(hitter, unknown="error"), ROLES.index(role),
                     float(row["gap"]) * row["n"] / (row["n"] + prior_strikes)))
    return out


def _add_steps(table: torch.Tensor, steps: list[tuple[int, int, float]],
               returns: torch.Tensor | None = None) -> list[float]:
    """Add each step to all three kinds of its (identity, role) cell of `table`, kept within
    `MAX_SHIFT`; with `returns`, what a receiver's cell moved is taken off his returns' row.
    -> each cell's mean after."""
    shifts = []
    for ident, r, step in steps:
        cell = table[ident, r]
        before = cell.clone()
        cell.add_(step).clamp_(-MAX_SHIFT, MAX_SHIFT)
        if returns is not None and ROLES[r] == "receiver":
            returns[ident].sub_(cell - before)
        shifts.append(float(cell.mean()))
    return shifts


def _moved(gaps: pd.DataFrame, vocab: Vocab, prior_strikes: float, table: torch.Tensor,
           returns: torch.Tensor | None = None) -> pd.DataFrame:
    """`_add_steps` of `gaps`' shrunk steps into `table` -> `gaps` with each `step` and the
    cell's mean `shift` after."""
    steps = _shrunk_steps(vocab, gaps, prior_strikes)
    return gaps.assign(step=[st for _, _, st in steps],
                       shift=_add_steps(table, steps, returns))


@torch.no_grad()
def add_rollout_late_shift(model: SportsNGEN, vocab: Vocab, gaps: pd.DataFrame,
                           prior_strikes: float = 200.0) -> pd.DataFrame:
    """Add to `model.strike_late` (in place) each hitter's and role's `gap`
    (`rollout_error_gaps`) shrunk by n / (n + `prior_strikes`), on all three error kinds,
    the sum kept within the matching's `MAX_SHIFT`. -> `gaps` with the `step` added and the
    cell's `shift` after."""
    if model.strike_late is None:
        raise ValueError("the model has no late table (cfg.strike_late): add it with "
                         "train.strike_bias.with_strike_late")
    return _moved(gaps, vocab, prior_strikes, model.strike_late)


@torch.no_grad()
def add_rollout_rally_shift(model: SportsNGEN, vocab: Vocab, gaps: pd.DataFrame,
                            prior_strikes: float = 200.0) -> pd.DataFrame:
    """Add to the player's table `model.strike_bias` (in place) each hitter's and role's `gap`
    over the rally strikes (`rollout_error_gaps(..., RALLY_STAGES)`) shrunk by n / (n +
    `prior_strikes`), on all three error kinds; a receiver's step is taken off his returns'
    row (`model.strike_return`), so his returns draw as before and only his strikes after
    the return move. The cell kept within `MAX_SHIFT` (the return's row moved by what the
    cell moved). -> `gaps` with the `step` taken and the cell's mean `shift` after."""
    if model.strike_bias is None or model.strike_return is None:
        raise ValueError("the rally shift needs the player's table and the returns' "
                         "(cfg.strike_bias and cfg.strike_return)")
    return _moved(gaps, vocab, prior_strikes, model.strike_bias, model.strike_return)


@torch.no_grad()
def add_rollout_second_shift(model: SportsNGEN, vocab: Vocab, gaps: pd.DataFrame,
                             prior_strikes: float = 200.0) -> pd.DataFrame:
    """Add to the second serves' table `model.strike_second` (in place) each hitter's and
    role's `gap` over the rally strikes of second-serve points (`rollout_error_gaps` of
    `at_serve(..., 2)` tables, `RALLY_STAGES`) shrunk by n / (n + `prior_strikes`), on all
    three error kinds, kept within `MAX_SHIFT`: first serves' rallies and every return draw as
    before. -> `gaps` with the `step` taken and the cell's mean `shift` after."""
    if model.strike_second is None:
        raise ValueError("the model has no second serves' table (cfg.strike_second): add it "
                         "with train.strike_bias.with_strike_second")
    return _moved(gaps, vocab, prior_strikes, model.strike_second)
