"""The i.i.d.-point Markov model of a tennis match: exact win probabilities and Monte Carlo.

Baseline for everything the learned model does: each player wins a point on his own serve
with a fixed probability, independently of everything else (`pa` for player 0, `pb` for
player 1). Under that assumption the chance of winning a game, tie-break, set or match from
any score has an exact answer (O'Malley 2008, "Probability formulas and statistical analysis
in tennis"; Newton & Keller 2005). Here it is computed by memoised recursion over the score,
with closed forms for the three infinite tails: deuce in a game, "level at 6-6 or later" in a
tie-break, and "level at 5-5 or later" in an advantage set. `simulate_match` /
`monte_carlo_match_win` play the same model point by point through `MatchState` and exist to
check the exact numbers. `point_importance` and `live_win_probabilities` give, before each
point, the match-win probability and how much that point moves it (the match report's
timeline).

The serve-level refinement of the point (first / second serve, ace, double fault, speed,
rally length) is `sportsngen.baselines.serve_model`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sportsngen.tennis.scoring import MatchFormat, MatchState

TIEBREAK_MODES = ("tiebreak7", "tiebreak10", "advantage", "tiebreak7_at_12")
_CACHE = 1 << 16


def _check_p(p: float, name: str) -> float:
    p = float(p)
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"{name} must be a probability in [0, 1], got {p}")
    return p


def _check_player(p: object, name: str) -> None:
    if p not in (0, 1) or isinstance(p, bool):
        raise ValueError(f"{name} must be player 0 or 1, got {p!r}")


def _level_tail(p_win_pair: float, p_lose_pair: float, what: str) -> float:
    """P(win) from a level score where two consecutive wins decide (a geometric series)."""
    total = p_win_pair + p_lose_pair
    if total == 0.0:
        raise ValueError(f"{what} never ends with these probabilities (every pair is split)")
    return p_win_pair / total


def _race_finished(a: int, b: int, target: int, lead: int = 2) -> int | None:
    """0/1 when the first-to-`target`, win-by-`lead` race is won by that side, else None.
    Raises ValueError for scores the race cannot reach (it would have stopped earlier)."""
    if a < 0 or b < 0:
        raise ValueError(f"score ({a}, {b}) has a negative count")
    for w, (x, y) in enumerate(((a, b), (b, a))):
        if x >= target and x - y >= lead:
            if x != max(target, y + lead):
                raise ValueError(f"score ({a}, {b}) is unreachable: the race ends earlier")
            return w
    return None


# --- game -------------------------------------------------------------------------------


def hold_probability(p: float, no_ad: bool = False) -> float:
    """P(the server wins a game from 0-0) when he wins each point with probability `p`.

    Closed form: p^4 (1 + 4q + 10q^2) + 20 p^3 q^3 * p^2 / (1 - 2pq), q = 1 - p (reach 3-3
    with 20 p^3 q^3, then win from deuce, a geometric series). No-ad: 3-3 is decided by one
    point, so the last term is 20 p^4 q^3.
    """
    p = _check_p(p, "p")
    q = 1.0 - p
    head = p**4 * (1.0 + 4.0 * q + 10.0 * q * q)
    if no_ad:
        return head + 20.0 * p**4 * q**3
    return head + 20.0 * p**3 * q**3 * _level_tail(p * p, q * q, "game")


def game_probability_from(p: float, points_server: int, points_receiver: int,
                          no_ad: bool = False) -> float:
    """P(the server wins the game) from raw point counts (e.g. 30-40 is (2, 3)).

    A finished game returns 1.0 or 0.0; a score the game cannot reach (5-1) raises ValueError.
    """
    p = _check_p(p, "p")
    a, b = int(points_server), int(points_receiver)
    if no_ad:
        if max(a, b) > 4 or (a == 4 and b == 4) or min(a, b) < 0:
            raise ValueError(f"no-ad game score ({a}, {b}) is unreachable")
        if a == 4 or b == 4:
            return 1.0 if a == 4 else 0.0
    else:
        done = _race_finished(a, b, 4)
        if done is not None:
            return 1.0 if done == 0 else 0.0
        if min(a, b) >= 3:  # deuce-like: only the difference matters
            a, b = 3 + (a - min(a, b)), 3 + (b - min(a, b))
    return _game_from(p, a, b, no_ad)


@lru_cache(maxsize=_CACHE)
def _game_from(p: float, a: int, b: int, no_ad: bool) -> float:
    if a == 4 and (b <= 2 or no_ad):
        return 1.0
    if b == 4 and (a <= 2 or no_ad):
        return 0.0
    if a == 3 and b == 3:
        return p if no_ad else _level_tail(p * p, (1 - p) ** 2, "game")
    if a == 4:  # advantage server (4-3 after deuce reduction)
        return p + (1 - p) * _game_from(p, 3, 3, no_ad)
    if b == 4:
        return p * _game_from(p, 3, 3, no_ad)
    return p * _game_from(p, a + 1, b, no_ad) + (1 - p) * _game_from(p, a, b + 1, no_ad)


# --- tie-break --------------------------------------------------------------------------


def _tiebreak_server(first_server: int, points_played: int) -> int:
    """Point 1 by the first server, then pairs alternate (points 2-3 the other, 4-5 ...)."""
    return first_server if ((points_played + 1) // 2) % 2 == 0 else 1 - first_server


def tiebreak_probability(pa: float, pb: float, first_server: int = 0, points_to_win: int = 7,
                         score: tuple[int, int] = (0, 0)) -> float:
    """P(player 0 wins a tie-break to `points_to_win` (win by 2), exact, from `score`.

    `first_server` served the tie-break's first point; `score` is (player 0, player 1)
    points. From any level score at or past (N-1)-all the next two points are one serve each,
    so P = pa(1-pb) / (pa(1-pb) + (1-pa)pb) whoever serves first.
    """
    pa, pb = _check_p(pa, "pa"), _check_p(pb, "pb")
    _check_player(first_server, "first_server")
    if points_to_win < 1:
        raise ValueError(f"points_to_win must be >= 1, got {points_to_win}")
    a, b = (int(x) for x in score)
    done = _race_finished(a, b, points_to_win)
    if done is not None:
        return 1.0 if done == 0 else 0.0
    # Remove whole pairs of points past (N-1)-all: an even shift keeps the serve order.
    excess = min(a, b) - (points_to_win - 1)
    if excess > 0:
        a, b = a - 2 * (excess // 2), b - 2 * (excess // 2)
    return _tiebreak_from(pa, pb, first_server, points_to_win, a, b)


@lru_cache(maxsize=_CACHE)
def _tiebreak_from(pa: float, pb: float, f: int, n: int, a: int, b: int) -> float:
    if a >= n and a - b >= 2:
        return 1.0
    if b >= n and b - a >= 2:
        return 0.0
    if a == b and a >= n - 1:
        return _level_tail(pa * (1 - pb), (1 - pa) * pb, "tie-break")
    server = _tiebreak_server(f, a + b)
    p0 = pa if server == 0 else 1.0 - pb  # P(player 0 wins this point)
    return p0 * _tiebreak_from(pa, pb, f, n, a + 1, b) + (1 - p0) * _tiebreak_from(
        pa, pb, f, n, a, b + 1)


# --- set --------------------------------------------------------------------------------


@dataclass(frozen=True)
class _SetRule:
    games_per_set: int
    tiebreak_at: int | None  # None: advantage set
    tiebreak_points: int
    no_ad: bool
    match_tiebreak: bool = False


def _set_outcomes(pa: float, pb: float, rule: _SetRule, server: int, games: tuple[int, int],
                  points: tuple[int, int], in_tiebreak: bool) -> np.ndarray:
    """out[w, t] = P(player w wins the set and player t serves first in the next set).

    `server` serves the next point. The next set's first server is the player due to serve
    the game after the set's last one (a tie-break counts as a game). Carrying it makes the
    match recursion exact by construction; under i.i.d. points a set's odds from 0-0 do not in
    fact depend on who serves first (Newton & Keller 2005; tests check this), so it never
    changes the answer, but nothing here relies on that theorem.
    """
    if in_tiebreak:
        k = points[0] + points[1]
        f = server if _tiebreak_server(0, k) == 0 else 1 - server  # who served point 1
        p0 = tiebreak_probability(pa, pb, f, rule.tiebreak_points, points)
        out = np.zeros((2, 2))
        out[0, 1 - f], out[1, 1 - f] = p0, 1.0 - p0
        return out
    p_srv = pa if server == 0 else pb
    hold = game_probability_from(p_srv, points[server], points[1 - server], rule.no_ad)
    out = np.zeros((2, 2))
    for game_winner, prob in ((server, hold), (1 - server, 1.0 - hold)):
        if prob == 0.0:
            continue
        g = [games[0], games[1]]
        g[game_winner] += 1
        out += prob * np.array(_fresh_game(pa, pb, rule, g[0], g[1], 1 - server)).reshape(2, 2)
    return out


@lru_cache(maxsize=_CACHE)
def _fresh_game(pa: float, pb: float, rule: _SetRule, a: int, b: int,
                server: int) -> tuple[float, ...]:
    """`_set_outcomes` at games (a, b) before the first point of a game, flattened."""
    for w, (x, y) in enumerate(((a, b), (b, a))):
        if x >= rule.games_per_set and x - y >= 2:
            out = np.zeros((2, 2))
            out[w, 1 - server] = 1.0  # `server` would serve the next game: the next set's first
            return tuple(out.ravel())
    if rule.tiebreak_at is not None and a == b == rule.tiebreak_at:
        return tuple(_set_outcomes(pa, pb, rule, server, (a, b), (0, 0), True).ravel())
    if rule.tiebreak_at is None and a == b and a >= rule.games_per_set - 1:
        # Level in an advantage set: each pair of games is one service game each, so the
        # set ends after an even number of games and `server` opens the next set.
        h0, h1 = hold_probability(pa, rule.no_ad), hold_probability(pb, rule.no_ad)
        p0 = _level_tail(h0 * (1 - h1), (1 - h0) * h1, "advantage set")
        out = np.zeros((2, 2))
        out[0, server], out[1, server] = p0, 1.0 - p0
        return tuple(out.ravel())
    return tuple(_set_outcomes(pa, pb, rule, server, (a, b), (0, 0), False).ravel())


def _normalise_games(rule: _SetRule, games: tuple[int, int]) -> tuple[int, int]:
    """Validate an unfinished set's games; shorten long advantage sets (68-68 -> 5-5)."""
    a, b = (int(x) for x in games)
    gps, tb = rule.games_per_set, rule.tiebreak_at
    won = (a >= gps and a - b >= 2) or (b >= gps and b - a >= 2)
    if min(a, b) < 0 or won or (tb is not None and max(a, b) > tb):
        raise ValueError(f"games {games} are not an unfinished set (games_per_set={gps}, "
                         f"tie-break at {tb})")
    excess = min(a, b) - (gps - 1)
    if tb is None and excess > 0:
        a, b = a - 2 * (excess // 2), b - 2 * (excess // 2)  # even shift keeps the server
    return a, b


def set_probability(pa: float, pb: float, first_server: int = 0,
                    games: tuple[int, int] = (0, 0), tiebreak: str = "tiebreak7", *,
                    points: tuple[int, int] = (0, 0), games_per_set: int = 6,
                    tiebreak_at: int = 6, tiebreak_points: int = 7,
                    no_ad: bool = False) -> float:
    """P(player 0 wins the set) from `games` (player 0, player 1), exact.

    `first_server` serves the current game (at (0, 0): the set's first game; in a tie-break in
    progress: the tie-break's first point). `points` are the raw points of the current game or
    tie-break. `tiebreak` names the rule as `MatchFormat.final_set` does: "tiebreak7" (a
    `tiebreak_points` tie-break at `tiebreak_at`-all), "tiebreak10", "advantage" (no
    tie-break; exact through the closed form once level at 5-5 or later), "tiebreak7_at_12".
    """
    pa, pb = _check_p(pa, "pa"), _check_p(pb, "pb")
    _check_player(first_server, "first_server")
    rules = {"tiebreak7": (tiebreak_at, tiebreak_points), "tiebreak10": (tiebreak_at, 10),
             "advantage": (None, tiebreak_points), "tiebreak7_at_12": (12, tiebreak_points)}
    if tiebreak not in rules:
        raise ValueError(f"tiebreak must be one of {TIEBREAK_MODES}, got {tiebreak!r}")
    rule = _SetRule(games_per_set, rules[tiebreak][0], rules[tiebreak][1], bool(no_ad))
    a, b = _normalise_games(rule, games)
    in_tb = rule.tiebreak_at is not None and a == b == rule.tiebreak_at
    pts = (int(points[0]), int(points[1]))
    if in_tb:
        server = _tiebreak_server(first_server, sum(pts))
        finished = _race_finished(*pts, rule.tiebreak_points) is not None
    else:
        server = first_server
        finished = game_probability_from(0.5, *pts, no_ad) in (0.0, 1.0)  # also validates
    if finished:
        raise ValueError(f"points {points} are a finished game or tie-break, not a set state")
    return float(_set_outcomes(pa, pb, rule, server, (a, b), pts, in_tb)[0].sum())


# --- match ------------------------------------------------------------------------------


def _rule_for(fmt: MatchFormat, set_no: int) -> _SetRule:
    tb_at, tb_points, match_tb = fmt.set_rule(set_no)
    return _SetRule(fmt.games_per_set, tb_at, tb_points, fmt.no_ad, match_tb)


@lru_cache(maxsize=_CACHE)
def _match_from_set_start(pa: float, pb: float, fmt: MatchFormat, won0: int, won1: int,
                          server: int) -> float:
    if won0 == fmt.sets_to_win:
        return 1.0
    if won1 == fmt.sets_to_win:
        return 0.0
    rule = _rule_for(fmt, won0 + won1 + 1)
    out = _set_outcomes(pa, pb, rule, server, (0, 0), (0, 0), rule.match_tiebreak)
    return _combine(pa, pb, fmt, won0, won1, out)


def _combine(pa: float, pb: float, fmt: MatchFormat, won0: int, won1: int,
             out: np.ndarray) -> float:
    total = 0.0
    for w in (0, 1):
        for t in (0, 1):
            if out[w, t] > 0.0:
                total += out[w, t] * _match_from_set_start(
                    pa, pb, fmt, won0 + (w == 0), won1 + (w == 1), t)
    return total


def match_win_probability(pa: float, pb: float, fmt: MatchFormat | None = None,
                          state: MatchState | None = None) -> float:
    """P(player 0 wins the match), exact, from `state` (default: the start, player 0 serving).

    Works from any score `MatchState` can hold: mid-game, mid-tie-break, long advantage final
    sets, no-ad games and match tie-breaks. `fmt` defaults to `state.fmt` (or `MatchFormat()`);
    when both are given they must agree.
    """
    pa, pb = _check_p(pa, "pa"), _check_p(pb, "pb")
    if state is None:
        state = MatchState.new(MatchFormat() if fmt is None else fmt)
    elif fmt is not None and fmt != state.fmt:
        raise ValueError(f"fmt {fmt} differs from state.fmt {state.fmt}")
    if state.is_over:
        return 1.0 if state.winner == 0 else 0.0
    fmt = state.fmt
    rule = _rule_for(fmt, state.set_no)
    games = state.games if state.in_tiebreak else _normalise_games(rule, state.games)
    out = _set_outcomes(pa, pb, rule, state.server, games, state.points, state.in_tiebreak)
    won0, won1 = state.sets_won
    return float(min(1.0, max(0.0, _combine(pa, pb, fmt, won0, won1, out))))


# --- Monte Carlo check ------------------------------------------------------------------


def simulate_match(pa: float, pb: float, fmt: MatchFormat | None,
                   rng: np.random.Generator, state: MatchState | None = None) -> MatchState:
    """Play the i.i.d.-point model through `MatchState` to the end; return the final state."""
    pa, pb = _check_p(pa, "pa"), _check_p(pb, "pb")
    if state is None:
        state = MatchState.new(MatchFormat() if fmt is None else fmt)
    while not state.is_over:
        p_srv = pa if state.server == 0 else pb
        state = state.point_won(state.server if rng.random() < p_srv else state.receiver)
    return state


def monte_carlo_match_win(pa: float, pb: float, fmt: MatchFormat | None, n: int, seed: int,
                          state: MatchState | None = None) -> tuple[float, float]:
    """(share of `n` simulated matches won by player 0, its binomial standard error)."""
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    wins = sum(simulate_match(pa, pb, fmt, rng, state).winner == 0 for _ in range(n))
    p_hat = wins / n
    return p_hat, math.sqrt(p_hat * (1.0 - p_hat) / n)


# --- live win probability and point importance ------------------------------------------


def point_importance(pa: float, pb: float, state: MatchState) -> float:
    """Importance of the next point (Morris 1977): P(player 0 wins the match | he wins it) -
    P(player 0 wins the match | he loses it), exact. The same number for both players, so
    it needs no side; in [0, 1]. A finished match has no next point: ValueError."""
    if state.is_over:
        raise ValueError(f"the match is over ({state.score_str()}); no next point")
    return float(match_win_probability(pa, pb, state=state.point_won(0))
                 - match_win_probability(pa, pb, state=state.point_won(1)))


def live_win_probabilities(pa: float, pb: float, states) -> np.ndarray:
    """For each unfinished `MatchState` of `states` (the score before each point of a match):
    (P(player 0 wins the match), the same if he wins that point, the same if he loses it), as
    an (n, 3) array. Column 1 minus column 2 is the point's importance; before a point on
    player 0's serve, column 0 = pa * column 1 + (1 - pa) * column 2.

    Cheap: the recursions are memoised per (pa, pb), so a whole match costs milliseconds."""
    out = np.empty((len(states), 3))
    for i, s in enumerate(states):
        if s.is_over:
            raise ValueError(f"states[{i}] is a finished match ({s.score_str()})")
        out[i] = (match_win_probability(pa, pb, state=s),
                  match_win_probability(pa, pb, state=s.point_won(0)),
                  match_win_probability(pa, pb, state=s.point_won(1)))
    return out
