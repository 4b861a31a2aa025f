"""Reports of simulated matches: the learned engine's (rallies and what-if shots) and the
Markov engine's (the score only).

What-if shots are chosen from the points with the largest swings of the win probability (the
key moments first): in the rally that decided the point, a forehand or backhand after the
serve, forced to go cross-court and down the line by `Simulator.counterfactual`: the last such
shot that stayed in play where there is one (where to put the ball to win the point), else the
last one. Each option's point-win probability for the hitter carries its 95 % Wilson interval;
through the point's importance it becomes the hitter's match-win probability
(P(win | lose the point) + p * importance), exact given that point probability.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from sportsngen.report.document import match_document, write_report
from sportsngen.report.live import ServeOdds, replay_states, serve_odds, timeline
from sportsngen.tennis.scoring import MatchFormat

log = logging.getLogger(__name__)
GROUNDSTROKES = ("forehand", "backhand")
WHATIF_OPTIONS = ("cross_court", "down_the_line")


def _format_text(fmt: MatchFormat) -> str:
    extra = ", no-ad" if fmt.no_ad else ""
    return f"best of {fmt.best_of}{extra}"


def _rallies_of_point(rallies: pd.DataFrame) -> dict[int, list[int]]:
    r = rallies.sort_values(["point", "serve_number", "rally_id"], kind="stable")
    return {int(p): [int(x) for x in g["rally_id"]] for p, g in r.groupby("point", sort=False)}


def choose_whatif_shots(rallies_of_point: dict[int, list[int]], shots: pd.DataFrame,
                        tl: pd.DataFrame, k: int) -> list[tuple[int, int, int]]:
    """Up to `k` (row of the timeline, rally_id, shot_index): see the module."""
    picked = []
    order = np.argsort(-np.abs(tl["swing"].to_numpy()), kind="stable")
    for i in order:
        if len(picked) >= k:
            break
        ids = rallies_of_point.get(int(tl["point"].iat[i]), [])
        if not ids:
            continue
        mine = shots[(shots["rally_id"] == ids[-1]) & shots["stroke"].isin(GROUNDSTROKES)
                     & (shots["shot_index"] > 0)]
        kept_in = mine[mine["outcome"] == "in_play"]
        if len(mine):
            pick = kept_in if len(kept_in) else mine
            picked.append((int(i), ids[-1], int(pick["shot_index"].max())))
    return picked


def whatif_entries(sim, rallies, tl: pd.DataFrame, players: tuple[str, str],
                   chosen: list[tuple[int, int, int]], n: int, seed: int = 0,
                   options=WHATIF_OPTIONS, progress: bool = True) -> list[dict]:
    """Run `Simulator.counterfactual` for each chosen shot -> the report's what-if records."""
    out = []
    shots = rallies.shots
    for j, (i, rid, shot_index) in enumerate(tqdm(chosen, desc="what-if shots",
                                                   disable=not progress)):
        shot = shots[(shots["rally_id"] == rid) & (shots["shot_index"] == shot_index)].iloc[0]
        hitter = players.index(str(shot["hitter"]))
        try:
            table = sim.counterfactual(rallies, rid, shot_index, options=options, n=n,
                                       seed=seed + 101 * j)
        except ValueError as exc:  # a shot that cannot be branched: the report goes on
            log.warning("what-if of rally %d shot %d skipped: %s", rid, shot_index, exc)
            continue
        row = tl.iloc[i]
        # The hitter's match-win probability if he wins / loses this point.
        win = row["p_if_won"] if hitter == 0 else 1.0 - row["p_if_lost"]
        lose = row["p_if_lost"] if hitter == 0 else 1.0 - row["p_if_won"]
        opts = []
        for o in table.itertuples(index=False):
            opts.append({"option": o.option, "p": o.win_probability, "lo": o.ci_low,
                         "hi": o.ci_high, "n": o.n, "n_sims": o.n_sims,
                         "n_unrealistic": o.n_unrealistic, "n_forced_failed": o.n_forced_failed,
                         "match_p": lose + o.win_probability * (win - lose),
                         "match_lo": lose + o.ci_low * (win - lose),
                         "match_hi": lose + o.ci_high * (win - lose)})
        out.append({"row": i, "point": int(row["point"]), "rally": rid, "shot": shot_index,
                    "hitter": hitter, "stroke": str(shot["stroke"]),
                    "played": str(shot["direction"]), "outcome": str(shot["outcome"]),
                    "rollouts": n, "match_if_won": win, "match_if_lost": lose,
                    "options": opts})
    return out


def simulated_timeline(points: pd.DataFrame, players: tuple[str, str],
                       fmt: MatchFormat) -> tuple[ServeOdds, pd.DataFrame]:
    """The serve odds and the timeline (`sportsngen.report.live.timeline`) of a simulated
    match's points table."""
    odds = serve_odds(*players)
    winners = [players.index(w) for w in points["winner"]]
    return odds, timeline(replay_states(points, fmt, players), winners, odds)


def learned_match_document(result, odds: ServeOdds, tl: pd.DataFrame,
                           whatif: list[dict] | None = None, model_name: str = "") -> dict:
    """The report document of a `MatchResult` of the learned engine (see `match_document`)."""
    from sportsngen.report.rallies import rally_payload

    players = tuple(result.players)
    notes = [f"Simulated by the learned engine{f' ({model_name})' if model_name else ''}; "
             f"{result.n_discarded} rallies set aside as non-realistic or undecided and "
             f"replayed; {result.forced_decisions} rallies counted without a realistic "
             "replay (the rules' verdict, else a coin toss).",
             "Rallies: the simulated tracks; bounces and contacts as the rally-end rules found "
             "them; shot labels from the event classifier."]
    return match_document(
        players=players, title=f"{players[0]} v {players[1]}",
        subtitle=f"simulated match, {result.surface}, {_format_text(result.state.fmt)}",
        score_line=result.score_line, points=result.points, tl=tl, odds=odds,
        kind="simulated", surface=result.surface, notes=notes,
        rallies=rally_payload(result.rallies, players),
        rallies_of_point=_rallies_of_point(result.rallies.rallies), fps=result.rallies.fps,
        whatif=whatif)


def learned_match_report(result, path: str | Path, sim=None, whatif_shots: int = 2,
                         whatif_rollouts: int = 24, seed: int = 0, model_name: str = "",
                         progress: bool = True) -> Path:
    """The report of a `MatchResult` of the learned engine, written to `path`. With `sim` (the
    `Simulator` that played it) and `whatif_shots` > 0, what-if shots are computed."""
    if whatif_shots < 0 or (whatif_shots > 0 and whatif_rollouts < 1):
        raise ValueError(f"whatif_shots must be >= 0 and whatif_rollouts >= 1, got "
                         f"{whatif_shots} and {whatif_rollouts}")
    players = tuple(result.players)
    odds, tl = simulated_timeline(result.points, players, result.state.fmt)
    whatif = []
    if sim is not None and whatif_shots > 0:
        chosen = choose_whatif_shots(_rallies_of_point(result.rallies.rallies),
                                     result.rallies.shots, tl, whatif_shots)
        whatif = whatif_entries(sim, result.rallies, tl, players, chosen, whatif_rollouts,
                                seed, progress=progress)
    return write_report(learned_match_document(result, odds, tl, whatif, model_name), path)


def markov_match_report(points: pd.DataFrame, players: tuple[str, str], fmt: MatchFormat,
                        score_line: str, surface: str, path: str | Path) -> Path:
    """The report of a Markov-engine match (its points table): the score, statistics, win
    probability and key moments; no rallies."""
    odds, tl = simulated_timeline(points, players, fmt)
    doc = match_document(
        players=players, title=f"{players[0]} v {players[1]}",
        subtitle=f"simulated match (Markov engine), {surface}, {_format_text(fmt)}",
        score_line=score_line, points=points, tl=tl, odds=odds, kind="simulated",
        surface=surface, notes=["The Markov engine plays points, not rallies: no rally views."])
    return write_report(doc, path)
