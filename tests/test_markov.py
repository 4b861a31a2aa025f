"""The i.i.d.-point Markov model: closed forms, exact recursion, Monte Carlo."""

import functools
import math

import numpy as np
import pytest

from sportsngen.baselines.markov import (
    game_probability_from,
    hold_probability,
    live_win_probabilities,
    match_win_probability,
    monte_carlo_match_win,
    point_importance,
    set_probability,
    simulate_match,
    tiebreak_probability,
)
from sportsngen.tennis.scoring import MatchFormat, MatchState

BO3 = MatchFormat()
BO5_ADV = MatchFormat(best_of=5, final_set="advantage")
NO_AD = MatchFormat(no_ad=True)
MATCH_TB = MatchFormat(match_tiebreak_points=10)


def dp_match_probability(pa, pb, start, cap=70):
    """Independent exact answer by backward induction over every `MatchState` reachable from
    `start`, built only from `MatchState.point_won` (no closed forms). States with more than
    `cap` points in a game or games in a set count as a coin flip; reaching them is so
    unlikely (< 1e-10 here) that the answer is exact to the tolerances used. Best of 1 only.
    """
    def cut(s):
        return max(s.points) > cap or max(s.games) > cap

    seen, stack, kids = {start}, [start], {}
    while stack:
        s = stack.pop()
        kids[s] = [s.point_won(s.server), s.point_won(s.receiver)]
        for t in kids[s]:
            if not t.is_over and not cut(t) and t not in seen:
                seen.add(t)
                stack.append(t)
    # Every point raises (sets, games, points played in the game), so this is a valid order.
    order = sorted(seen, key=lambda s: (len(s.sets), sum(s.games), sum(s.points)), reverse=True)
    value = {}
    for s in order:
        p = pa if s.server == 0 else pb
        v = [float(t.winner == 0) if t.is_over else 0.5 if cut(t) else value[t] for t in kids[s]]
        value[s] = v[0] * p + v[1] * (1.0 - p)  # the server wins the point w.p. p
    return value[start]


# --- game -------------------------------------------------------------------------------

def test_hold_probability_known_value_and_symmetry():
    assert round(hold_probability(0.6), 4) == 0.7357
    assert hold_probability(0.5) == pytest.approx(0.5, abs=1e-15)
    for p in (0.1, 0.35, 0.62, 0.9):
        assert hold_probability(p) + hold_probability(1 - p) == pytest.approx(1.0, abs=1e-12)
    assert hold_probability(0.0) == 0.0 and hold_probability(1.0) == 1.0
    # No-ad: p^4 (1 + 4q + 10q^2 + 20q^3) = 0.1296 * 5.48
    assert hold_probability(0.6, no_ad=True) == pytest.approx(0.710208, abs=1e-12)


def test_game_probability_from_scores():
    p = 0.6
    deuce = p * p / (p * p + 0.16)
    assert game_probability_from(p, 0, 0) == pytest.approx(hold_probability(p))
    assert game_probability_from(p, 3, 3) == pytest.approx(deuce)
    assert game_probability_from(p, 9, 9) == pytest.approx(deuce)
    assert game_probability_from(p, 4, 3) == pytest.approx(p + (1 - p) * deuce)  # AD-40
    assert game_probability_from(p, 2, 3) == pytest.approx(p * deuce)  # 30-40
    assert game_probability_from(p, 3, 0) == pytest.approx(1 - 0.4**3 * (1 - deuce))
    assert game_probability_from(p, 3, 3, no_ad=True) == p
    assert game_probability_from(p, 4, 2) == 1.0 and game_probability_from(p, 5, 7) == 0.0
    for bad in ((5, 1), (6, 3), (-1, 0)):
        with pytest.raises(ValueError):
            game_probability_from(p, *bad)
    with pytest.raises(ValueError):
        game_probability_from(p, 4, 4, no_ad=True)
    with pytest.raises(ValueError, match="p must be"):
        game_probability_from(1.2, 0, 0)


# --- tie-break and set ----------------------------------------------------------------------

def test_tiebreak_probability_symmetry_and_tail():
    assert tiebreak_probability(0.5, 0.5) == pytest.approx(0.5, abs=1e-15)
    assert tiebreak_probability(0.7, 0.7, points_to_win=10) == pytest.approx(0.5, abs=1e-12)
    tail = 0.7 * 0.4 / (0.7 * 0.4 + 0.3 * 0.6)
    for score in ((6, 6), (20, 20), (9, 9)):
        assert tiebreak_probability(0.7, 0.6, 1, 7, score) == pytest.approx(tail)
    # Who serves first does not change a tie-break's odds from 0-0 (Newton & Keller).
    assert tiebreak_probability(0.7, 0.6, 0) == pytest.approx(tiebreak_probability(0.7, 0.6, 1))
    # Points 1, 4-5, 8-9, 12-13 go to the first server (player 0): he serves at 6-5.
    assert tiebreak_probability(0.7, 0.6, 0, 7, (6, 5)) == pytest.approx(0.7 + 0.3 * tail)
    assert tiebreak_probability(0.7, 0.6, 0, 7, (7, 5)) == 1.0
    with pytest.raises(ValueError):
        tiebreak_probability(0.7, 0.6, 0, 7, (9, 5))


@pytest.mark.parametrize("mode", ["tiebreak7", "tiebreak10", "advantage", "tiebreak7_at_12"])
def test_set_probability_equal_players_and_against_dp(mode):
    assert set_probability(0.62, 0.62, tiebreak=mode) == pytest.approx(0.5, abs=1e-12)
    fmt = MatchFormat(best_of=1, final_set=mode)
    exact = set_probability(0.66, 0.6, 0, tiebreak=mode)
    assert exact == pytest.approx(dp_match_probability(0.66, 0.6, MatchState.new(fmt)), abs=1e-9)
    # A mid-set state: 5-6, 30-40, player 1 serving.
    state = MatchState.from_score(fmt, (), (5, 6), (3, 2), server=1)
    mid = set_probability(0.66, 0.6, 1, (5, 6), mode, points=(3, 2))
    assert mid == pytest.approx(dp_match_probability(0.66, 0.6, state), abs=1e-9)
    assert mid == pytest.approx(match_win_probability(0.66, 0.6, state=state), abs=1e-12)


@pytest.mark.parametrize("fmt,games", [
    (MatchFormat(best_of=1), (6, 6)),
    (MatchFormat(best_of=1, final_set="tiebreak10"), (6, 6)),
    (MatchFormat(best_of=1, final_set="tiebreak7_at_12"), (12, 12)),
    (MatchFormat(best_of=1, match_tiebreak_points=10), (0, 0)),
])
@pytest.mark.parametrize("server", [0, 1])
def test_mid_tiebreak_against_dp(fmt, games, server):
    """Mid-tie-break odds depend on who serves the remaining points (see the tie-break test
    above for the serve order itself)."""
    state = MatchState.from_score(fmt, (), games, (4, 3), server=server)
    exact = match_win_probability(0.72, 0.6, state=state)
    assert exact == pytest.approx(dp_match_probability(0.72, 0.6, state), abs=1e-12)


def test_set_probability_no_ad_and_long_advantage_set():
    fmt = MatchFormat(best_of=1, no_ad=True)
    exact = set_probability(0.6, 0.64, 1, no_ad=True)
    assert exact == pytest.approx(dp_match_probability(0.6, 0.64, MatchState.new(fmt, 1)))
    # 68-68 in an advantage set is the same as 6-6 (only the lead and the server matter).
    long = set_probability(0.6, 0.64, 0, (68, 67), "advantage")
    assert long == pytest.approx(set_probability(0.6, 0.64, 0, (6, 5), "advantage"))
    h0, h1 = hold_probability(0.6), hold_probability(0.64)
    level = h0 * (1 - h1) / (h0 * (1 - h1) + (1 - h0) * h1)
    assert set_probability(0.6, 0.64, 1, (70, 70), "advantage") == pytest.approx(level)


def test_set_probability_errors():
    with pytest.raises(ValueError, match="tiebreak must be"):
        set_probability(0.6, 0.6, tiebreak="super")
    with pytest.raises(ValueError, match="games"):
        set_probability(0.6, 0.6, games=(7, 5))
    with pytest.raises(ValueError, match="finished"):
        set_probability(0.6, 0.6, games=(3, 3), points=(4, 0))
    with pytest.raises(ValueError, match="never ends"):
        set_probability(1.0, 1.0, games=(5, 5), tiebreak="advantage")


# --- match ------------------------------------------------------------------------------

@pytest.mark.parametrize("fmt", [BO3, BO5_ADV, NO_AD, MATCH_TB])
def test_match_identical_players_is_half(fmt):
    assert match_win_probability(0.63, 0.63, fmt) == pytest.approx(0.5, abs=1e-12)


def test_match_probability_from_set_probability_identity():
    """Set odds do not depend on who serves first, so the match is a race of i.i.d. sets."""
    ps = set_probability(0.65, 0.62)
    assert match_win_probability(0.65, 0.62, BO3) == pytest.approx(ps**2 * (3 - 2 * ps))
    pf = set_probability(0.65, 0.62, tiebreak="advantage")
    want = ps**3 * (1 + 3 * (1 - ps)) + 6 * ps**2 * (1 - ps) ** 2 * pf
    assert match_win_probability(0.65, 0.62, BO5_ADV) == pytest.approx(want)
    pt = tiebreak_probability(0.65, 0.62, 0, 10)
    want_tb = ps**2 + 2 * ps * (1 - ps) * pt
    assert match_win_probability(0.65, 0.62, MATCH_TB) == pytest.approx(want_tb)


def test_match_probability_monotone_in_pa():
    pas = np.linspace(0.3, 0.9, 13)
    for fmt in (BO3, BO5_ADV):
        probs = [match_win_probability(pa, 0.6, fmt) for pa in pas]
        assert np.all(np.diff(probs) > 0)


def test_match_probability_finished_and_nearly_finished_states():
    over = MatchState.from_score(BO3, ((6, 4), (6, 3)), (0, 0), (0, 0), server=0)
    assert match_win_probability(0.3, 0.9, state=over) == 1.0
    lost = MatchState.from_score(BO3, ((4, 6), (3, 6)), (0, 0), (0, 0), server=0)
    assert match_win_probability(0.9, 0.3, state=lost) == 0.0
    # Match point on player 0's serve at 6-4 5-4 40-0: he loses only by losing the game
    # and then the set from 5-5.
    mp = MatchState.from_score(BO3, ((6, 4),), (5, 4), (3, 0), server=0)
    got = match_win_probability(0.6, 0.6, state=mp)
    assert 1 - got == pytest.approx((1 - game_probability_from(0.6, 3, 0))
                                    * (1 - set_probability(0.6, 0.6, 1, (5, 5)))
                                    * (1 - set_probability(0.6, 0.6)), abs=1e-12)
    with pytest.raises(ValueError, match="differs"):
        match_win_probability(0.6, 0.6, BO5_ADV, state=mp)


# One set all, 4-5, 30-40, player 0 serving.
MID = MatchState.from_score(BO3, ((6, 3), (4, 6)), (4, 5), (2, 3), server=0)
MC_CASES = [
    (0.65, 0.60, BO3, None),
    (0.62, 0.64, BO5_ADV, None),
    (0.60, 0.55, NO_AD, None),
    (0.58, 0.62, MATCH_TB, None),
    (0.66, 0.62, BO3, MID),
    (0.64, 0.66, BO5_ADV, MatchState.from_score(BO5_ADV, ((6, 4), (3, 6), (7, 6), (4, 6)),
                                                (8, 8), (1, 2), server=1)),
    (0.6, 0.6, MATCH_TB, MatchState.from_score(MATCH_TB, ((6, 4), (4, 6)), (0, 0), (6, 7),
                                               server=1)),
    (0.62, 0.6, BO3, MatchState.from_score(BO3, ((7, 6),), (6, 6), (5, 4), server=1)),
]


@pytest.mark.parametrize("pa,pb,fmt,state", MC_CASES)
def test_exact_against_monte_carlo(pa, pb, fmt, state):
    exact = match_win_probability(pa, pb, fmt, state)
    p_hat, se = monte_carlo_match_win(pa, pb, fmt, n=1500, seed=11, state=state)
    assert abs(p_hat - exact) < 3 * se, (exact, p_hat, se)


def test_simulate_match_plays_to_the_end():
    rng = np.random.default_rng(3)
    final = simulate_match(0.6, 0.6, BO5_ADV, rng)
    assert final.is_over and max(final.sets_won) == 3
    assert simulate_match(1.0, 0.0, BO3, rng).score_str() == "6-0 6-0"


# --- point importance -------------------------------------------------------------------

def _dp_key(s):
    """What decides the future of a match under i.i.d. points (not the score's history)."""
    return (s.sets_won, s.games, s.points, s.server, s.in_tiebreak)


@functools.lru_cache(maxsize=4)
def dp_values(pa, pb, fmt, cap=60):
    """Independent exact answers for any format (several sets too): backward induction like
    `dp_match_probability` over every state reachable from the start (either first server),
    built only from `MatchState.point_won`, but with states merged by `_dp_key`, so a best-of-3
    match has tens of thousands of states, not millions. Long deuces or tie-breaks past `cap`
    points count as a coin flip (reached with probability < 1e-9 here). -> key -> P(player 0
    wins the match)."""
    def cut(s):
        return max(s.points) > cap

    starts = [MatchState.new(fmt, 0), MatchState.new(fmt, 1)]
    rep, stack, kids = {_dp_key(s): s for s in starts}, list(starts), {}
    while stack:
        s = stack.pop()
        kids[_dp_key(s)] = [s.point_won(s.server), s.point_won(s.receiver)]
        for t in kids[_dp_key(s)]:
            if not t.is_over and not cut(t) and _dp_key(t) not in rep:
                rep[_dp_key(t)] = t
                stack.append(t)
    # Every point raises (sets won, games, points), so this is a valid order.
    order = sorted(rep, key=lambda k: (sum(k[0]), sum(k[1]), sum(k[2])), reverse=True)
    value = {}
    for k in order:
        p = pa if k[3] == 0 else pb
        v = [float(t.winner == 0) if t.is_over else 0.5 if cut(t) else value[_dp_key(t)]
             for t in kids[k]]
        value[k] = v[0] * p + v[1] * (1.0 - p)
    return value


def dp_importance(pa, pb, state):
    values = dp_values(pa, pb, state.fmt)

    def v(s):
        return float(s.winner == 0) if s.is_over else values[_dp_key(s)]

    return v(state.point_won(0)) - v(state.point_won(1))


BO5_US = MatchFormat(best_of=5)
# Deuce (40-40) at 3-3 in the first set of a best-of-3 match (a tie-break set).
DEUCE_TB_SET = MatchState.from_score(BO3, (), (3, 3), (3, 3), server=1)
# 30-40 on player 0's serve at 5-6 in the final set: match point for player 1.
FINAL_30_40 = MatchState.from_score(BO3, ((6, 4), (4, 6)), (5, 6), (2, 3), server=0)
# 6-6 in the final-set tie-break of a best-of-5 match (US Open 2011 rules).
FINAL_TB_6_6 = MatchState.from_score(BO5_US, ((6, 4), (4, 6), (6, 3), (3, 6)), (6, 6), (6, 6),
                                     server=0)


def test_importance_30_40_at_5_6_final_set_closed_form():
    """Losing the point loses the match; winning it leads to deuce, then (holding) a final-set
    tie-break that player 1 serves first: importance = P(hold from deuce) * P(tie-break)."""
    pa, pb = 0.65, 0.61
    deuce = pa * pa / (pa * pa + (1 - pa) ** 2)
    got = point_importance(pa, pb, FINAL_30_40)
    want = deuce * tiebreak_probability(pa, pb, first_server=1)
    assert got == pytest.approx(want, abs=1e-12)
    assert got == pytest.approx(dp_importance(pa, pb, FINAL_30_40), abs=1e-9)
    assert match_win_probability(pa, pb, state=FINAL_30_40.point_won(1)) == 0.0


def test_importance_at_6_6_in_final_set_tiebreak_closed_form():
    """At 6-6 in a tie-break the next two points are one serve each. Player 0 serves point 13
    (the state's server), player 1 point 14, so with T the level-score tail,
    I = [q + (1 - q) T] - [q T] = q + T (1 - 2 q), q = P(player 0 wins point 14) = 1 - pb."""
    pa, pb = 0.66, 0.70
    assert FINAL_TB_6_6.server == 0 and FINAL_TB_6_6.point_won(0).server == 1
    tail = pa * (1 - pb) / (pa * (1 - pb) + (1 - pa) * pb)
    q = 1 - pb
    assert point_importance(pa, pb, FINAL_TB_6_6) == pytest.approx(q + tail * (1 - 2 * q),
                                                                   abs=1e-12)


@pytest.mark.parametrize("state", [MatchState.new(BO3), DEUCE_TB_SET],
                         ids=["first point", "deuce in a tie-break set"])
def test_importance_against_independent_dp(state):
    pa, pb = 0.65, 0.61
    got = point_importance(pa, pb, state)
    assert got == pytest.approx(dp_importance(pa, pb, state), abs=1e-9)
    assert 0.0 < got < 1.0


def test_importance_known_values():
    # Values of this implementation, pinned; each is checked above against the dynamic
    # programme or a closed form, so a change here is a change of the model.
    assert point_importance(0.65, 0.61, MatchState.new(BO3)) == pytest.approx(0.03038, abs=5e-6)
    assert point_importance(0.65, 0.61, DEUCE_TB_SET) == pytest.approx(0.07928, abs=5e-6)
    assert point_importance(0.65, 0.61, FINAL_30_40) == pytest.approx(0.43852, abs=5e-6)
    # Equal players, first point: symmetric, so P(before) is 1/2 and the point moves it by
    # equal amounts up and down when it is won on serve with probability 1/2.
    live = live_win_probabilities(0.5, 0.5, [MatchState.new(BO3)])[0]
    assert live[0] == pytest.approx(0.5, abs=1e-12)
    assert live[1] - 0.5 == pytest.approx(0.5 - live[2], abs=1e-12)


def test_live_win_probabilities_consistent_with_the_point_model():
    pa, pb = 0.63, 0.6
    rng = np.random.default_rng(5)
    state, states = MatchState.new(BO3), []
    while not state.is_over:
        states.append(state)
        state = state.point_won(int(rng.random() < 0.5))
    live = live_win_probabilities(pa, pb, states)
    p0 = np.array([pa if s.server == 0 else 1 - pb for s in states])
    assert np.allclose(live[:, 0], p0 * live[:, 1] + (1 - p0) * live[:, 2], atol=1e-12)
    assert (live[:, 1] >= live[:, 2]).all()
    # The probability after point i is the probability before point i + 1.
    won0 = np.array([t.point_won(0) == u for t, u in zip(states[:-1], states[1:])])
    after = np.where(won0, live[:-1, 1], live[:-1, 2])
    assert np.allclose(after, live[1:, 0], atol=1e-12)
    with pytest.raises(ValueError, match="over"):
        point_importance(pa, pb, state)


def test_importance_against_monte_carlo():
    pa, pb, n = 0.65, 0.61, 2000
    exact = point_importance(pa, pb, DEUCE_TB_SET)
    won, se_w = monte_carlo_match_win(pa, pb, None, n, seed=21, state=DEUCE_TB_SET.point_won(0))
    lost, se_l = monte_carlo_match_win(pa, pb, None, n, seed=22, state=DEUCE_TB_SET.point_won(1))
    assert abs((won - lost) - exact) < 3 * math.hypot(se_w, se_l), (exact, won - lost)
