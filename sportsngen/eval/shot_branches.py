"""Recorded rallies rolled out from a chosen frame: the branches every rollout diagnostic reads,
and the rally-ball counterpart of the branch return share.

`branch_rallies` keeps the first k frames of each chosen recorded rally (k its own) and lets the
model play on; rallies sharing k run as one batch. `serve_branches`
(`sportsngen.eval.diagnostics`) branches just after each serve; `shot_branches` just after any
later recorded contact, by default the return of serve. `shot_outcomes` reads from the rules
whether that shot stayed in play (struck again before it bounced, or its first bounce in the
opponent's singles court), where it first bounced, and whether it was struck back: over a
model's branches against the record, the **answer share** says how often the model's hitter
strikes a ball in play that the record's hitter struck (after the return, shot 1, that is the
server's third shot, which decides serve points won and rally length), and the **landing gap**
how far from the recorded bounce the model flew a ball whose first frames it was given
(docs/evaluation.md, issue 17, seventh part).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.sim.assemble import PLAN_COLUMNS
from sportsngen.sim.rollout import pad_tracks
from sportsngen.tennis.court import is_in_singles

RETURN_SHOT = 1            # contacts count from the serve (0)
SHOT_HORIZON_S = 2.5       # the shot's flight, the answer and its first frames


def branch_rallies(sim, truth: RallyData, keep_frames: pd.Series, seed: int,
                   horizon_s: float, forced_pos_m: dict[int, np.ndarray] | None = None,
                   copies: int = 1, label_events: bool = True
                   ) -> tuple[RallyData, pd.Series]:
    """Each recorded rally of `keep_frames` (rally id -> frames kept from its start) rolled
    out `copies` times from its own frame, `horizon_s` beyond it -> (the branches, a Series:
    branch rally id -> the recorded rally id). Rallies whose kept frames are not shorter than
    their track are left out. `forced_pos_m`: recorded rally id -> (T, 3, 3) players'
    positions from the rally's start, NaN where free, that replace the sampled ones
    (`rollout`'s). `label_events`: `Simulator.simulate_rallies`'."""
    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    rallies = truth.rallies.set_index("rally_id")
    idx, kept = [], []
    for ri, rid in enumerate(arr.rally_id):
        if rid in keep_frames.index:
            k = int(keep_frames[rid])
            if 0 < k < arr.length[ri]:
                idx.append(ri)
                kept.append(k)
    if not idx:
        raise ValueError("no recorded rally is longer than its branch point")
    # One rollout for every branch point: each rally keeps its own frames
    # (`init_frames`) and its own horizon beyond them.
    idx, kept = np.repeat(idx, copies), np.repeat(np.asarray(kept, dtype=np.int64), copies)
    rids = arr.rally_id[idx]
    plan = rallies.loc[rids].reset_index()[PLAN_COLUMNS].copy()
    plan["rally_id"] = np.arange(len(plan))
    plan["match_id"] = "branch"
    init = pad_tracks([arr.pos_m[arr.start[i]:arr.start[i] + k] for i, k in zip(idx, kept)])
    forced = None if forced_pos_m is None else pad_tracks(
        [forced_pos_m.get(int(r), np.full((0, 3, 3), np.nan)) for r in rids])
    out = sim.simulate_rallies(plan, seed=seed, init_pos_m=init, init_frames=kept,
                               max_duration_s=kept / sim.fps + horizon_s, forced_pos_m=forced,
                               label_events=label_events)
    return out, pd.Series(rids, index=plan["rally_id"].to_numpy())


def shot_outcomes(data: RallyData, shot: int = RETURN_SHOT,
                  rules: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per rally, from the rules (or `rules` already read from `data`): `struck` (the rally
    has contact number `shot`), `in_play` (that ball was struck again before it bounced, or
    its first bounce lies in the opponent's singles court), `answered` (struck again after
    it), `contact_frame` (from the rally's first frame; -1 where there is none) and
    `bounce_x_m`, `bounce_y_m`, where it bounced before anyone struck it again (NaN: not
    struck, volleyed or not yet bounced)."""
    if shot < 1:
        raise ValueError(f"shot counts contacts after the serve (>= 1), got {shot}")
    rules = analyse_rally_data(data) if rules is None else rules
    rows = []
    for rid, rule in rules.iterrows():
        contacts, bounces = list(rule["contact_frames"]), list(rule["bounce_frames"])
        struck = len(contacts) > shot
        answered = len(contacts) > shot + 1
        in_play = False
        first = None
        if struck:
            after = [i for i, b in enumerate(bounces) if b > contacts[shot]]
            first = after[0] if after else None
            if answered and (first is None or bounces[first] > contacts[shot + 1]):
                in_play, first = True, None   # volleyed: it never bounced as this shot
            elif first is not None:
                # The server (hitter 0) plays at `server_end`: an odd shot is the receiver's
                # and lands on the server's half.
                side = int(rule["server_end"]) * (1 if shot % 2 else -1)
                bx, by = rule["bounces_m"][first][:2]
                in_play = bool(is_in_singles(bx, by, side))
        bounce = rule["bounces_m"][first][:2] if first is not None else (np.nan, np.nan)
        rows.append({"rally_id": int(rid), "struck": struck, "in_play": in_play,
                     "answered": bool(in_play and answered),
                     "contact_frame": int(contacts[shot]) if struck else -1,
                     "bounce_x_m": float(bounce[0]), "bounce_y_m": float(bounce[1])})
    return pd.DataFrame(rows).set_index("rally_id")


def landing_gaps_m(branch_out: pd.DataFrame, truth_out: pd.DataFrame,
                   order: pd.Series) -> np.ndarray:
    """For each branch whose shot bounced, as its recorded rally's did, the distance (m)
    between the two first bounces after the shot: how far the model flew a ball it was given
    three frames of (`shot_outcomes`' bounce columns)."""
    b = branch_out.reindex(order.index)[["bounce_x_m", "bounce_y_m"]].to_numpy(float)
    r = truth_out.loc[order.to_numpy(), ["bounce_x_m", "bounce_y_m"]].to_numpy(float)
    gap = np.hypot(*(b - r).T)
    return gap[np.isfinite(gap)]


def shot_branches(sim, truth: RallyData, shot: int = RETURN_SHOT, after_frames: int = 3,
                  seed: int = 0, horizon_s: float = SHOT_HORIZON_S,
                  truth_out: pd.DataFrame | None = None) -> tuple[RallyData, pd.Series]:
    """The recorded rallies whose shot number `shot` stayed in play, each rolled out from
    `after_frames` frames after that contact (`branch_rallies`)."""
    out = shot_outcomes(truth, shot) if truth_out is None else truth_out
    keep = out.loc[out["in_play"], "contact_frame"] + after_frames + 1
    return branch_rallies(sim, truth, keep, seed, horizon_s)


def answer_share(branch_out: pd.DataFrame, truth_out: pd.DataFrame,
                 order: pd.Series) -> dict:
    """Of the branches whose shot stayed in play, the share answered, beside the same share of
    the recorded rallies they branched from (in play by construction) and the branches' share
    in play: -> {"model", "data", "n", "in_play"}."""
    b = branch_out.reindex(order.index)
    live = b["in_play"].fillna(False).to_numpy(bool)
    r = truth_out.loc[order.to_numpy()]
    return {"model": float(b.loc[live, "answered"].mean()) if live.any() else float("nan"),
            "data": float(r["answered"].mean()), "n": int(live.sum()),
            "in_play": float(live.mean())}


def strike_shares(sim, truth: RallyData, shots: tuple[int, ...] = (1, 2, 3, 4, 5),
                  after_frames: int = -1, seed: int = 0, horizon_s: float = SHOT_HORIZON_S,
                  rules: pd.DataFrame | None = None) -> pd.DataFrame:
    """Who keeps the ball in play, shot by shot: every recorded rally that reached contact
    number `shot` (1 the return) rolled out once from `after_frames` frames after that
    contact (-1: the frames before it only, so the model strikes the recorded approach) ->
    per shot its hitter (odd shots the receiver's), the recorded rallies `n`, the recorded
    shares of that shot in play and answered, and the model's shares struck, in play, in play
    of those struck, and answered; `recorded_side_m` and `model_side_m`, the median distance
    from the centre line of the shot's bounces in play (how wide the strikes are aimed).

    The generator's server keeps the initiative all rally (his balls multiply the receiver's
    aim noise), so the receiver's recorded shots stay in play less often than the server's; a
    model that does not play that gives both the same share (docs/evaluation.md, eleventh
    part). Teacher-forced up to the strike, one rollout a rally: a few minutes for 800 points."""
    rules = analyse_rally_data(truth) if rules is None else rules
    rows = []
    for shot in shots:
        rec = shot_outcomes(truth, shot, rules)
        rec = rec[rec["struck"]]
        if rec.empty:
            continue
        keep = rec["contact_frame"] + after_frames + 1
        branches, order = branch_rallies(sim, truth, keep, seed + shot, horizon_s)
        got = shot_outcomes(branches, shot).reindex(order.index)
        struck = got["struck"].fillna(False).to_numpy(bool)
        in_play = got["in_play"].fillna(False).to_numpy(bool)
        rows.append({"shot": shot, "hitter": "receiver" if shot % 2 else "server",
                     "n": len(rec), "recorded_in_play": float(rec["in_play"].mean()),
                     "recorded_answered": float(rec["answered"].mean()),
                     "model_struck": float(struck.mean()),
                     "model_in_play": float(in_play.mean()),
                     "model_in_play_if_struck": float(in_play[struck].mean())
                     if struck.any() else float("nan"),
                     "model_answered": float(got["answered"].fillna(False).astype(bool).mean()),
                     "recorded_side_m": _median_side_m(rec),
                     "model_side_m": _median_side_m(got)})
    return pd.DataFrame(rows)


def _median_side_m(out: pd.DataFrame) -> float:
    """Median distance (m) from the centre line of the balls that bounced in play: how
    much of the court's width the strikes use (NaN where none bounced in)."""
    side = out.loc[out["in_play"].fillna(False).astype(bool), "bounce_y_m"].abs().dropna()
    return float(side.median()) if len(side) else float("nan")
