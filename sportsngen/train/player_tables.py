"""A fine-tuned player's rows of the per-player tables, fitted on his own rallies.

A named player of the bundled file plays through his identity row and his rows of the tables
that correct what the heads draw for him (`SportsNGEN.PER_IDENTITY_TABLES`): the serve's faults
and speed (`model.serve_bias`; his short serves, `model.serve_short`, and where in the box his
serves go, `model.serve_lateral`, where the file has them), his
rally errors by role (`model.strike_bias`) and on his returns
(`model.strike_return`). The heads read a player only through the decoder's state, and fitted
on everyone they draw about the average player's serves and errors (docs/evaluation.md,
twenty-fourth and thirty-second parts); the tables are what brought the named players' faults
and rallies to their records. A player added by fine-tuning (`train.finetune.add_player`) got
zero rows, so he kept the average player's errors whatever his rallies showed. Here his rows
are fitted after his identity row is trained, on the same rallies and by the same matching as
the named players' (`train.serve_bias.fit_serve_bias`, `train.strike_bias.fit_strike_bias` and
`fit_strike_return`, each pulled toward the head's own odds by its prior, so a player with few
rallies moves little); every other row is left as it is. His row of the opponents' table
(`model.strike_pressure`: how hard his balls are to play) is not fitted: it is read on the
opponents' strikes, whose rows the fine-tune does not touch. Nor are his rows of the shape
tables (`model.strike_shape` and `strike_shape_opponent`, where the file has them): they stay
at zero, the head's own depth and height for him.

The rollout rules' tables keyed by name in the file's extra (his reach for the return and for
the rally balls, `sim.reach_table`, and his top speed, `sim.top_speed`) are carried from the
base file with his own row added where his rallies have enough of his balls or frames
(`player_rule_tables`): a fine-tune that copied the base's sampling defaults but not the tables
left its rollouts with the fixed reaches and no speed bound at all.
"""

from __future__ import annotations

import pandas as pd
import torch

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.reach import reach_rows
from sportsngen.model.decoder import SportsNGEN
from sportsngen.sim.reach_table import BALLS, MIN_BALLS, ReachTable, fit_logistic
from sportsngen.sim.top_speed import MIN_FRAMES, QUANTILE, TopSpeeds, player_speeds
from sportsngen.train.head_fit import collect_head_states
from sportsngen.train.serve_bias import fit_serve_bias, fit_serve_lateral, fit_serve_short
from sportsngen.train.strike_bias import fit_strike_bias, fit_strike_return


@torch.no_grad()
def fit_player_tables(model: SportsNGEN, vocab: Vocab, data: RallyData, player: str,
                      prior_serves: float = 100.0, prior_strikes: float = 200.0,
                      progress: bool = False) -> pd.DataFrame:
    """Fit `player`'s rows of the tables `model` has (in place) on his serves and strikes in
    `data` (the decoder's states read as the named players' fits read them, windows also
    turned); other rows keep their values. -> one row per fitted cell: table, role ("first" /
    "second" serve, "server" / "receiver" / "return"), n and each kind's record, head's odds
    before, after and shift (serve speeds in m/s). Empty where the model has none of the
    tables or the player too few serves and strikes for any cell (`fit_serve_bias`'s and
    `fit_strike_bias`'s minimums)."""
    if not vocab.players or player not in vocab.players:
        raise ValueError(f"{player!r} has no identity row of his own in the model's vocabulary: "
                         "add him first (train.finetune.add_player)")
    rallies = data.rallies
    if not ((rallies["server"] == player) | (rallies["receiver"] == player)).any():
        raise ValueError(f"{player!r} plays no rally in the data given")
    row = vocab.player_index(player)
    arrays = rally_arrays(data, vocab, unknown="generic")
    parts = []
    if model.serve_bias is not None and model.serve_head is not None:
        states = collect_head_states(model, arrays, "serve", flip=True, progress=progress)
        mine = states.server_id == row
        if mine.any():
            own = states.take(mine)
            t = fit_serve_bias(model, own, prior_serves=prior_serves)
            parts.append(_labelled(t, "serve_bias", "serve", {0: "first", 1: "second"},
                                   "server_id"))
            if model.serve_short is not None:
                t = fit_serve_short(model, own, prior_serves=prior_serves)
                parts.append(_labelled(t, "serve_short", "serve", {0: "first", 1: "second"},
                                       "server_id"))
            if model.serve_lateral is not None:
                t = fit_serve_lateral(model, own, prior_serves=prior_serves)
                parts.append(_labelled(t, "serve_lateral", "serve", {0: "first", 1: "second"},
                                       "server_id"))
    if model.strike_bias is not None and model.strike_head is not None:
        states = collect_head_states(model, arrays, "strike", flip=True, progress=progress)
        returns = states.returns()
        mine = states.hitter_id() == row
        if mine.any():
            own = states.take(mine)
            t = _labelled(fit_strike_bias(model, own, prior_strikes=prior_strikes),
                          "strike_bias", "receiver", {False: "server", True: "receiver"},
                          "hitter_id")
            parts.append(t)
            if model.strike_return is not None:
                # As the named players' recipe: his receiving row refitted on the strikes that
                # are not returns, then the returns' row on top of it.
                r = _labelled(fit_strike_return(model, own, returns[mine],
                                                prior_strikes=prior_strikes),
                              "strike_bias", "is_return", {False: "receiver", True: "return"},
                              "hitter_id")
                r.loc[r["role"] == "return", "table"] = "strike_return"
                if (r["role"] == "receiver").any():     # the first fit's, superseded
                    parts[-1] = t[t["role"] != "receiver"]
                parts.append(r)
    parts = [p for p in parts if not p.empty]
    if not parts:
        return pd.DataFrame(columns=["table", "role", "n"])
    out = pd.concat(parts, ignore_index=True)
    first = ["table", "role", "n"]
    return out[first + [c for c in out.columns if c not in first]]


def _labelled(fit: pd.DataFrame, table: str, key: str, roles: dict, id_column: str
              ) -> pd.DataFrame:
    """A fit's cells named by `table` and role (`roles` of its `key` column), without the
    identity and key columns (every cell is the player's)."""
    if fit.empty:
        return pd.DataFrame(columns=["table", "role", "n"])
    return fit.assign(table=table, role=fit[key].map(roles)).drop(columns=[id_column, key])


# The rule tables of a file's extra keyed by player name, and which balls each reach reads.
REACH_TABLES = {"return_reach": "serve", "rally_reach": "rally"}


def player_rule_tables(base_extra: dict, data: RallyData, player: str,
                       min_balls: int = MIN_BALLS, min_frames: int = MIN_FRAMES) -> dict:
    """The base file's rule tables (`base_extra`'s `return_reach`, `rally_reach`, `top_speed`,
    those it has) with `player`'s own row fitted on `data` where he has at least `min_balls`
    good balls to answer (some answered, some not) or `min_frames` frames; else he plays the
    pooled row. -> {extra key: the table's dict}."""
    out = {}
    rows = None
    for key, kind in REACH_TABLES.items():
        if base_extra.get(key) is None:
            continue
        table = ReachTable.from_dict(base_extra[key])
        if rows is None:
            rows = reach_rows(data)
        balls = BALLS[kind](rows, data.rallies) if len(rows) else rows
        mine = balls[balls["player"] == player] if len(balls) else balls
        if len(mine) >= min_balls and mine["answered"].any() and not mine["answered"].all():
            table.players[player] = fit_logistic(mine["gap_m"], mine["answered"])
        out[key] = table.to_dict()
    if base_extra.get("top_speed") is not None:
        table = TopSpeeds.from_dict(base_extra["top_speed"])
        speeds = player_speeds(data.frames[data.frames["object"] == player], data.fps)
        if len(speeds) >= min_frames:
            table.players_mps[player] = float(speeds["speed_mps"].quantile(QUANTILE))
        out["top_speed"] = table.to_dict()
    return out


__all__ = ["fit_player_tables", "player_rule_tables"]
