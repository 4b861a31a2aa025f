"""Live win probability of a match, point by point, with each point's importance.

The model is the serve-level Markov chain: each player wins a point on his serve with a fixed
probability, his own 2011 slam figures (`sportsngen.baselines.serve_model`, adjusted to the
opponent by Barnett & Clarke) where the bundled models know him, the pooled 2011 figures of his
gender otherwise. From the score before each point, `sportsngen.baselines.markov` gives
P(player 1 wins the match) exactly, and the same if he wins or loses that point; the difference
is the point's importance. The same code serves simulated and recorded matches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from sportsngen.baselines.markov import live_win_probabilities
from sportsngen.baselines.serve_model import serve_model_or_pooled
from sportsngen.tennis.scoring import MatchFormat, MatchState

TIMELINE_COLUMNS = (
    "point", "set_no", "games_p1", "games_p2", "score", "point_score", "server", "winner",
    "tag", "new_game", "new_set", "p_before", "p_if_won", "p_if_lost", "importance", "p_after",
    "swing",
)


@dataclass(frozen=True)
class ServeOdds:
    """P(player i wins a point on his own serve) for the two players of a match, and whether it
    comes from his own figures (True) or the pooled ones (False)."""

    p_serve: tuple[float, float]
    own_figures: tuple[bool, bool]

    def describe(self, players: tuple[str, str]) -> str:
        parts = [f"{name} {p:.1%} on serve ({'own 2011 slam figures' if own else 'pooled'})"
                 for name, p, own in zip(players, self.p_serve, self.own_figures)]
        return "; ".join(parts)


def serve_odds(player1: str, player2: str, gender: str = "men") -> ServeOdds:
    """Each player's point-win probability on serve against the other (see the module)."""
    (m1, own1), (m2, own2) = (serve_model_or_pooled(p, gender) for p in (player1, player2))
    pa = m1.adjusted_against(m2).serve_points_won
    pb = m2.adjusted_against(m1).serve_points_won
    return ServeOdds((float(pa), float(pb)), (own1, own2))


def replay_states(points: pd.DataFrame, fmt: MatchFormat,
                  players: tuple[str, str]) -> list[MatchState]:
    """The score before each point of a points table of one whole match (its first row's server
    served first), replayed through `MatchState`. ValueError naming the row where the table's
    server disagrees with the rules, or a point follows the end of the match."""
    if not len(points):
        raise ValueError("the points table is empty")
    first = str(points["server"].iat[0])
    if first not in players:
        raise ValueError(f"points row 0: server {first!r} is neither of {players}")
    state = MatchState.new(fmt, first_server=players.index(first))
    out = []
    for i, (server, winner) in enumerate(zip(points["server"], points["winner"])):
        if state.is_over:
            raise ValueError(f"points row {i}: the match was already over ({state.score_str()})")
        if players[state.server] != server:
            raise ValueError(f"points row {i}: server {server!r}, but the rules say "
                             f"{players[state.server]!r} serves at {state.score_str()}")
        if winner not in players:
            raise ValueError(f"points row {i}: winner {winner!r} is neither of {players}")
        out.append(state)
        state = state.point_won(players.index(winner))
    return out


def _tag(s: MatchState) -> str:
    if s.match_point_for is not None:
        return "match point"
    if s.set_point_for is not None:
        return "set point"
    if s.is_break_point:
        return "break point"
    return "tie-break" if s.in_tiebreak else ""


def timeline(states: list[MatchState], winners, odds: ServeOdds) -> pd.DataFrame:
    """One row a point (`TIMELINE_COLUMNS`): the score before it, who served and won it (0/1),
    P(player 1 wins the match) before it, if he wins it and if he loses it, its importance,
    the probability after it and the swing (after - before). `winners[i]` is 0 or 1."""
    winners = np.asarray(winners, dtype=int)
    if len(winners) != len(states):
        raise ValueError(f"{len(states)} states but {len(winners)} winners")
    if not np.isin(winners, (0, 1)).all():
        raise ValueError("winners must be 0 (player 1) or 1 (player 2)")
    live = live_win_probabilities(*odds.p_serve, states)
    after = np.where(winners == 0, live[:, 1], live[:, 2])
    games = [s.games for s in states]
    set_no = np.array([s.set_no for s in states])
    game_key = [(s.set_no, g) for s, g in zip(states, games)]
    new_game = np.r_[True, [a != b for a, b in zip(game_key[1:], game_key[:-1])]]
    tl = pd.DataFrame({
        "point": np.arange(1, len(states) + 1),
        "set_no": set_no,
        "games_p1": [g[0] for g in games], "games_p2": [g[1] for g in games],
        "score": [s.score_str() for s in states],
        "point_score": [s.point_score_str() for s in states],
        "server": [s.server for s in states],
        "winner": winners,
        "tag": [_tag(s) for s in states],
        "new_game": new_game,
        "new_set": np.r_[True, set_no[1:] != set_no[:-1]],
        "p_before": live[:, 0], "p_if_won": live[:, 1], "p_if_lost": live[:, 2],
        "importance": live[:, 1] - live[:, 2],
        "p_after": after,
        "swing": after - live[:, 0],
    })
    return tl.loc[:, list(TIMELINE_COLUMNS)]


def key_moments(tl: pd.DataFrame, k: int = 5) -> list[int]:
    """Row positions of the `k` points with the largest swings of the win probability, in
    match order (ties: the earlier point)."""
    if k < 0:
        raise ValueError(f"k must be >= 0, got {k}")
    order = np.argsort(-np.abs(tl["swing"].to_numpy()), kind="stable")[:k]
    return sorted(int(i) for i in order)


def describe_point(row: pd.Series, players: tuple[str, str]) -> str:
    """"Set 3, 4-5 30-40 (break point), Nadal serving: Federer wins it, 41% -> 63%"."""
    tag = f" ({row['tag']})" if row["tag"] and row["tag"] != "tie-break" else ""
    games = f"{row['games_p1']}-{row['games_p2']}"
    score = f"{games} {row['point_score']}" if row["point_score"] != "0-0" else games
    return (f"Set {row['set_no']}, {score}{tag}, {players[row['server']]} serving: "
            f"{players[row['winner']]} wins it, {row['p_before']:.0%} -> {row['p_after']:.0%}")
