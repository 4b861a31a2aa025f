"""Tests for sportsngen.tennis.scoring: exact scores, serve order, change of ends, errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sportsngen.tennis.scoring import SCORE_VECTOR_FIELDS, MatchFormat, MatchState


def play(state: MatchState, winners) -> MatchState:
    """Apply point winners given as a string like "0011" or any iterable of 0/1."""
    for w in winners:
        state = state.point_won(int(w))
    return state


def games(state: MatchState, game_winners) -> MatchState:
    """Each listed player wins a love game."""
    for w in game_winners:
        state = play(state, str(w) * 4)
    return state


def set_to(state: MatchState, a: int, b: int) -> MatchState:
    """Alternate games (love games) so the current set ends a-b, player 0 taking the last."""
    order = "01" * min(a, b) + ("0" * (a - b) if a > b else "1" * (b - a))
    return games(state, order)


# --- games ------------------------------------------------------------------------------


def test_love_game_scores_server_and_sides():
    s = MatchState.new()
    assert (s.score_str(), s.point_score_str(), s.serving_side) == ("0-0", "0-0", "deuce")
    seen = []
    for _ in range(3):
        s = s.point_won(0)
        seen.append((s.point_score_str(), s.serving_side, s.server))
    assert seen == [("15-0", "ad", 0), ("30-0", "deuce", 0), ("40-0", "ad", 0)]
    s = s.point_won(0)
    assert s.games == (1, 0) and s.points == (0, 0) and s.server == 1
    assert s.points_played == 4 and s.score_str() == "1-0"


def test_deuce_advantage_back_to_deuce_then_game():
    s = play(MatchState.new(), "000111")
    assert s.point_score_str() == "40-40" and s.serving_side == "deuce"
    s = s.point_won(0)
    assert s.point_score_str() == "AD-40" and s.serving_side == "ad"
    s = s.point_won(1)
    assert s.point_score_str() == "40-40" and s.games == (0, 0)
    s = s.point_won(1)
    assert s.point_score_str() == "40-AD" and s.is_break_point
    s = s.point_won(1)
    assert s.games == (0, 1) and s.points == (0, 0) and s.server == 1


def test_no_ad_deciding_point_goes_to_deuce_court_and_ends_game():
    fmt = MatchFormat(no_ad=True)
    s = play(MatchState.new(fmt), "010101")
    assert s.points == (3, 3) and s.serving_side == "deuce"
    assert s.is_break_point  # either player wins the game with the next point
    assert s.point_won(0).games == (1, 0)
    assert s.point_won(1).games == (0, 1)


# --- sets and tie-breaks ----------------------------------------------------------------


@pytest.mark.parametrize("a,b", [(6, 4), (7, 5), (6, 0)])
def test_set_won_without_tiebreak(a, b):
    s = set_to(MatchState.new(), a, b)
    assert s.sets == ((a, b),) and s.tiebreaks == (None,)
    assert s.games == (0, 0) and not s.in_tiebreak and s.set_no == 2
    assert s.server == (a + b) % 2  # alternation carries across the set boundary
    assert s.score_str() == f"{a}-{b} 0-0"


def test_six_five_is_not_a_set():
    s = games(MatchState.new(), "01" * 5 + "0")
    assert s.games == (6, 5) and s.sets == () and s.set_point_for is None  # 0-0: no set point
    s = play(s, "000")
    assert s.set_point_for == 0 and s.match_point_for is None and s.point_score_str() == "40-0"


def test_seven_point_tiebreak_serve_order_sides_and_ends():
    s = games(MatchState.new(), "01" * 6)
    assert s.games == (6, 6) and s.in_tiebreak and s.server == 0
    assert s.score_str() == "6-6 0-0" and s.ends == (-1, 1)
    # Player 0 wins the tie-break 7-5: points alternate in pairs after point 1.
    seq = "010101010100"
    servers, sides, ends = [], [], []
    for w in seq:
        servers.append(s.server)
        sides.append(s.serving_side)
        ends.append(s.ends[0])
        s = s.point_won(int(w))
    assert servers == [0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0]
    assert sides == ["deuce", "ad"] * 6
    # Change of ends after 6 points (ends[0] is player 0's baseline sign).
    assert ends == [-1] * 6 + [1] * 6
    assert s.sets == ((7, 6),) and s.tiebreaks == ((7, 5),)
    # The tie-break's first server (0) receives first in the next set; ends change again.
    assert s.server == 1 and s.ends == (-1, 1) and s.score_str() == "7-6(5) 0-0"


def test_tiebreak_ends_change_at_end_relative_to_current_ends():
    base = games(MatchState.new(), "01" * 6)
    s = play(base, "0000000")  # 7-0: one change after 6 points, one at the end
    assert s.tiebreaks == ((7, 0),) and s.ends == (-1, 1)
    s = play(base, "01" * 7 + "00")  # 9-7 (16 points): changes after 6 and 12, then the end
    assert s.tiebreaks == ((9, 7),) and s.sets == ((7, 6),) and s.ends == (1, -1)


def test_final_set_ten_point_tiebreak_to_ten_eight():
    fmt = MatchFormat(best_of=3, final_set="tiebreak10")
    s = set_to(set_to(MatchState.new(fmt), 6, 4), 4, 6)
    s = games(s, "01" * 6)
    assert s.in_tiebreak and s.is_final_set
    s = play(s, "01" * 8)
    assert s.points == (8, 8) and not s.is_over
    s = play(s, "0")
    assert s.match_point_for == 0
    s = play(s, "0")
    assert s.winner == 0 and s.sets[-1] == (7, 6) and s.tiebreaks[-1] == (10, 8)
    assert s.score_str() == "6-4 4-6 7-6(8)"
    with pytest.raises(ValueError, match="over"):
        s.point_won(1)


def test_advantage_final_set_reaches_70_68():
    fmt = MatchFormat(best_of=5, final_set="advantage")
    s = MatchState.new(fmt)
    for a, b in [(6, 4), (4, 6), (6, 4), (4, 6)]:
        s = set_to(s, a, b)
    s = games(s, "01" * 68)
    assert s.games == (68, 68) and not s.in_tiebreak and not s.is_over
    s = games(s, "0")
    assert s.games == (69, 68) and s.set_point_for is None  # no point won in this game yet
    s = play(s, "000")
    assert s.set_point_for == 0 and s.match_point_for == 0
    s = play(s, "0")
    assert s.winner == 0 and s.sets[-1] == (70, 68) and s.tiebreaks[-1] is None
    assert s.score_str() == "6-4 4-6 6-4 4-6 70-68"


def test_final_set_tiebreak7_at_12():
    fmt = MatchFormat(best_of=3, final_set="tiebreak7_at_12")
    s = set_to(set_to(MatchState.new(fmt), 6, 4), 4, 6)
    s = games(s, "01" * 6)
    assert s.games == (6, 6) and not s.in_tiebreak  # no tie-break at 6-6 in this final set
    s = games(s, "01" * 6)
    assert s.games == (12, 12) and s.in_tiebreak
    s = play(s, "11101111")
    assert s.winner == 1 and s.sets[-1] == (12, 13) and s.tiebreaks[-1] == (1, 7)
    assert s.score_str() == "6-4 4-6 12-13(1)"


def test_match_tiebreak_replaces_final_set():
    fmt = MatchFormat(best_of=3, match_tiebreak_points=10)
    s = set_to(set_to(MatchState.new(fmt), 6, 4), 4, 6)
    assert s.in_tiebreak and s.games == (0, 0) and s.score_str() == "6-4 4-6 [0-0]"
    assert s.server == 0  # 20 games played: the original order of service continues
    s = play(s, "00000111")
    assert s.score_str() == "6-4 4-6 [5-3]" and s.point_score_str() == "5-3"
    s = play(s, "111001")
    assert s.points == (7, 7) and not s.is_over and s.ends == (-1, 1)  # 14 points: 2 changes
    s = play(s, "0")
    assert s.points == (8, 7) and s.match_point_for is None  # a tie-break to 10
    s = play(s, "10")
    assert s.points == (9, 8) and s.match_point_for == 0 and s.set_point_for == 0
    s = play(s, "0")
    assert s.winner == 0 and s.sets[-1] == (1, 0) and s.tiebreaks[-1] == (10, 8)
    assert s.score_str() == "6-4 4-6 [10-8]"


def test_best_of_one_match_tiebreak_starts_in_tiebreak():
    s = MatchState.new(MatchFormat(best_of=1, match_tiebreak_points=7), first_server=1)
    assert s.in_tiebreak and s.server == 1 and s.is_final_set
    s = play(s, "0" * 7)
    assert s.winner == 0 and s.sets == ((1, 0),) and s.score_str() == "[7-0]"


# --- change of ends -----------------------------------------------------------------------


def test_ends_change_after_odd_games_of_each_set():
    s = MatchState.new()
    seen = [s.ends[0]]
    for _ in range(9):  # player 0 leads 6-3 after 9 games
        s = games(s, "000111000"[sum(s.games)])
        seen.append(s.ends[0])
    assert s.sets == ((6, 3),)
    # Changes after games 1, 3, 5, 7, 9 of set 1 (9 is also the end of the set) ...
    assert seen == [-1, 1, 1, -1, -1, 1, 1, -1, -1, 1]
    # ... and again after the first game of set 2 (ITF rule 10: odd games of EACH set).
    s = games(s, "0")
    assert s.ends == (-1, 1)
    s = games(s, "1")
    assert s.ends == (-1, 1)
    s = games(s, "1")
    assert s.ends == (1, -1)


def test_ends_even_set_changes_after_first_game_of_next_set():
    s = set_to(MatchState.new(), 6, 4)
    assert s.ends == (1, -1)  # 5 changes in set 1 (games 1..9), none at the end of the set
    s = games(s, "1")
    assert s.ends == (-1, 1)


# --- flags and strings --------------------------------------------------------------------


def test_break_set_match_point_flags_and_score_vector():
    s = MatchState.from_score(None, [(6, 4)], (5, 3), (3, 0), server=1)
    assert s.first_server == 1 and s.receiver == 0
    assert s.is_break_point and s.set_point_for == 0 and s.match_point_for == 0
    assert s.score_str() == "6-4 5-3 40-0"
    v = s.score_vector()  # server (player 1) first
    assert v.dtype == np.float32 and len(v) == len(SCORE_VECTOR_FIELDS) == 13
    assert v.tolist() == [0, 1, 3, 5, 0, 3, 0, 0, 1, 0, 1, 0, 1]
    # Server holds at 40-0 at 5-4 in the first set: set point, not match point, no break point.
    t = MatchState.from_score(None, [], (5, 4), (3, 0), server=0)
    assert (t.is_break_point, t.set_point_for, t.match_point_for) == (False, 0, None)
    assert dict(zip(SCORE_VECTOR_FIELDS, t.score_vector())) == dict(
        zip(SCORE_VECTOR_FIELDS, [0, 0, 5, 4, 3, 0, 0, 0, 0, 1, 0, 0, 0])
    )
    # In a tie-break: no break point; 6-5 is set point; not at 5-5.
    u = MatchState.from_score(None, [], (6, 6), (6, 5), server=1)
    assert u.in_tiebreak and not u.is_break_point and u.set_point_for == 0
    assert MatchState.from_score(None, [], (6, 6), (5, 5), server=0).set_point_for is None
    # Deep deuce maps onto the equivalent short score in the score vector.
    w = MatchState.from_score(None, [], (0, 0), (7, 6), server=0)
    assert w.score_vector()[4:6].tolist() == [4, 3] and w.point_score_str() == "AD-40"


def test_score_strings():
    assert play(MatchState.new(), "0").score_str() == "0-0 15-0"
    s = MatchState.from_score(None, [(6, 4)], (2, 3), (3, 4), server=0)
    assert s.score_str() == "6-4 2-3 40-AD" and s.point_score_str() == "40-AD"
    s = MatchState.from_score(None, [], (6, 6), (5, 3), server=0)
    assert s.score_str() == "6-6 5-3"
    s = MatchState.from_score(None, [(6, 4), (3, 6)], (6, 6), (0, 0), server=0)
    s = play(s, "1" * 5 + "0" * 5 + "11")  # player 1 wins the deciding tie-break 7-5
    assert s.winner == 1 and s.score_str() == "6-4 3-6 6-7(5)"
    m = MatchState.from_score(None, [(6, 4), (3, 6), (7, 6)], (0, 0), (0, 0), server=0)
    assert m.score_str() == "6-4 3-6 7-6" and m.is_over  # tie-break points unknown


# --- from_score ------------------------------------------------------------------------------


def test_from_score_round_trip_on_a_random_match():
    rng = np.random.default_rng(7)
    s = MatchState.new(MatchFormat(best_of=5), first_server=1)
    checked = 0
    while not s.is_over:
        s = s.point_won(int(rng.random() < 0.5))
        t = MatchState.from_score(s.fmt, s.sets, s.games, s.points, s.server, tiebreaks=s.tiebreaks)
        assert t == s and t.ends == s.ends and t.first_server == 1
        checked += 1
    assert checked == s.points_played > 100


def test_from_score_points_played_is_a_lower_bound():
    s = games(MatchState.new(), "0" * 6 + "01" * 6)  # 6-0, 6-6
    s = play(s, "0" * 7)
    t = MatchState.from_score(None, s.sets, s.games, s.points, s.server, tiebreaks=s.tiebreaks)
    assert s.points_played == t.points_played == 24 + 48 + 7
    u = MatchState.from_score(None, s.sets, s.games, s.points, s.server)
    assert u.tiebreaks == (None, None) and u.points_played == 79 and u != s


@pytest.mark.parametrize(
    "kwargs,msg",
    [
        (dict(sets=[(6, 5)]), "set 1 score"),
        (dict(sets=[(8, 6)]), "set 1 score"),
        (dict(sets=[(7, 6)], tiebreaks=[(7, 6)]), "tie-break"),
        (dict(sets=[(6, 4)], tiebreaks=[(7, 5)]), "no tie-break"),
        (dict(sets=[(6, 4), (6, 4), (6, 4)]), "already won"),
        (dict(games=(7, 3)), "games"),
        (dict(games=(6, 6), in_tiebreak=False), "in_tiebreak"),
        (dict(points=(5, 2)), "points"),
        (dict(points=(8, 2), games=(6, 6)), "points"),
        (dict(first_server=1), "first_server"),
        (dict(sets=[(6, 4), (6, 4)], points=(1, 0)), "over"),
        (dict(games=(-1, 0)), "non-negative"),
        (dict(server=2), "server"),
    ],
)
def test_from_score_rejects_impossible_scores(kwargs, msg):
    args = dict(fmt=None, sets=[], games=(0, 0), points=(0, 0), server=0, first_server=0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=msg):
        MatchState.from_score(**args)


def test_no_ad_rejects_deuce_points():
    with pytest.raises(ValueError, match="points"):
        MatchState.from_score(MatchFormat(no_ad=True), [], (0, 0), (4, 3), server=0)


# --- errors and formats ---------------------------------------------------------------------


def test_point_won_rejects_bad_player():
    s = MatchState.new()
    for bad in (2, -1, True, "0"):
        with pytest.raises(ValueError, match="by must be player 0 or 1"):
            s.point_won(bad)


@pytest.mark.parametrize(
    "kwargs,msg",
    [
        (dict(best_of=4), "best_of"),
        (dict(best_of=0), "best_of"),
        (dict(final_set="sudden_death"), "final_set"),
        (dict(tiebreak_points=0), "tiebreak_points"),
        (dict(games_per_set=6, tiebreak_at=4), "tiebreak_at"),
        (dict(match_tiebreak_points=10, final_set="advantage"), "match_tiebreak_points"),
        (dict(match_tiebreak_points=0), "match_tiebreak_points"),
    ],
)
def test_invalid_formats(kwargs, msg):
    with pytest.raises(ValueError, match=msg):
        MatchFormat(**kwargs)


@pytest.mark.parametrize(
    "slam,year,gender,best_of,final",
    [
        ("usopen", 2011, "men", 5, "tiebreak7"),
        ("usopen", 2021, "women", 3, "tiebreak7"),
        ("usopen", 2022, "women", 3, "tiebreak10"),
        ("wimbledon", 2011, "men", 5, "advantage"),
        ("wimbledon", 2018, "women", 3, "advantage"),
        ("wimbledon", 2019, "men", 5, "tiebreak7_at_12"),
        ("wimbledon", 2022, "men", 5, "tiebreak10"),
        ("ausopen", 2012, "men", 5, "advantage"),
        ("ausopen", 2019, "women", 3, "tiebreak10"),
        ("frenchopen", 2021, "men", 5, "advantage"),
        ("frenchopen", 2024, "women", 3, "tiebreak10"),
    ],
)
def test_for_slam(slam, year, gender, best_of, final):
    fmt = MatchFormat.for_slam(slam, year, gender)
    assert (fmt.best_of, fmt.final_set, fmt.tiebreak_at, fmt.tiebreak_points) == (
        best_of,
        final,
        6,
        7,
    )


@pytest.mark.parametrize(
    "args,msg",
    [(("rolandgarros", 2012, "men"), "ausopen"), (("usopen", 2010, "men"), "2011"),
     (("usopen", 2012, "mixed"), "women")],
)  # fmt: skip
def test_for_slam_rejects_unknown(args, msg):
    with pytest.raises(ValueError, match=msg):
        MatchFormat.for_slam(*args)


# --- property test --------------------------------------------------------------------------

FORMATS = [
    MatchFormat(),
    MatchFormat(best_of=5),
    MatchFormat(no_ad=True, match_tiebreak_points=10),
    MatchFormat(best_of=5, final_set="tiebreak10"),
    MatchFormat(best_of=3, final_set="tiebreak7_at_12"),
    MatchFormat(best_of=5, final_set="advantage"),
    MatchFormat(games_per_set=4, tiebreak_at=3, tiebreak_points=5),  # Fast4-like
]


def check_valid(s: MatchState) -> None:
    fmt = s.fmt
    assert s.server in (0, 1) and s.receiver == 1 - s.server
    assert s.ends in ((-1, 1), (1, -1))
    assert s.serving_side == ("deuce" if sum(s.points) % 2 == 0 else "ad")
    assert max(s.sets_won) <= fmt.sets_to_win
    assert (s.winner is not None) == (max(s.sets_won) == fmt.sets_to_win)
    tb_at, tb_points, match_tb = fmt.set_rule(s.set_no)
    if s.is_over:
        assert s.games == (0, 0) and s.points == (0, 0)
    elif s.in_tiebreak:
        assert match_tb or s.games == (tb_at, tb_at)
        assert max(s.points) < tb_points or abs(s.points[0] - s.points[1]) < 2
    else:
        assert tb_at is None or max(s.games) <= tb_at
        assert max(s.games) < fmt.games_per_set or abs(s.games[0] - s.games[1]) < 2
        assert max(s.points) < 4 or abs(s.points[0] - s.points[1]) < 2
        assert not fmt.no_ad or max(s.points) <= 3
    for (a, b), tb in zip(s.sets, s.tiebreaks):
        assert a != b and (tb is None or (tb[0] > tb[1]) == (a > b))
    # Every state reached by play is accepted by from_score and rebuilt identically.
    t = MatchState.from_score(fmt, s.sets, s.games, s.points, s.server, tiebreaks=s.tiebreaks)
    assert t == s and t.ends == s.ends


@settings(max_examples=150, deadline=None)
@given(
    fmt_index=st.integers(0, len(FORMATS) - 1),
    first_server=st.integers(0, 1),
    prefix=st.lists(st.integers(0, 1), max_size=400),
)
def test_random_points_keep_state_valid_and_matches_end(fmt_index, first_server, prefix):
    fmt = FORMATS[fmt_index]
    s = MatchState.new(fmt, first_server)
    for n, w in enumerate(prefix, start=1):
        if s.is_over:
            break
        s = s.point_won(w)
        assert s.points_played == n
        check_valid(s)
    # Games (a tie-break counting as one) are bounded in tie-break formats.
    if fmt.final_set != "advantage":
        most = max(fmt.tiebreak_at, 12 if fmt.final_set == "tiebreak7_at_12" else 0)
        assert sum(a + b for a, b in s.sets) + sum(s.games) <= fmt.best_of * (2 * most + 1)
    # A biased tail (player 1 wins every point) ends any match, advantage sets included.
    extra = 0
    while not s.is_over:
        s = s.point_won(1)
        extra += 1
        assert extra <= 5 * 14 * fmt.best_of + 12
    check_valid(s)


@settings(max_examples=40, deadline=None)
@given(
    fmt_index=st.integers(0, len(FORMATS) - 1),
    seed=st.integers(0, 2**32 - 1),
    p_player0=st.floats(0.3, 0.7),
)
def test_whole_random_matches_stay_valid_and_end(fmt_index, seed, p_player0):
    fmt = FORMATS[fmt_index]
    rng = np.random.default_rng(seed)
    s = MatchState.new(fmt, int(rng.integers(2)))
    games_seen = 0
    while not s.is_over:
        before = s
        s = s.point_won(int(rng.random() >= p_player0))
        check_valid(s)
        if s.server != before.server and not before.in_tiebreak:
            games_seen += 1  # outside tie-breaks the server changes exactly when a game ends
        assert s.points_played < 20_000
    total_games = sum(a + b for a, b in s.sets)
    assert games_seen <= total_games
    if fmt.final_set != "advantage":
        most = max(fmt.tiebreak_at, 12 if fmt.final_set == "tiebreak7_at_12" else 0)
        assert total_games <= fmt.best_of * (2 * most + 1)


def test_point_label():
    from sportsngen.tennis.scoring import point_label

    assert [point_label(m, 0) for m in range(4)] == ["0", "15", "30", "40"]
    assert (point_label(3, 3), point_label(4, 3), point_label(3, 4)) == ("40", "AD", "40")
    assert point_label(6, 5, in_tiebreak=True) == "6"
