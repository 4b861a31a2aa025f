"""Tennis scoring: match formats and an immutable match state.

`MatchFormat` says how a match is scored (sets, tie-breaks, final-set rule, no-ad, match
tie-break). `MatchState` is the score at one moment; `state.point_won(p)` returns the next
state. Everything else (server, receiver, serving side, which end each player is at, break /
set / match point, score strings) is derived from the score, so a state built mid-match with
`MatchState.from_score` behaves exactly like one reached point by point.

Players are indexed 0 and 1. Points inside a game or tie-break are raw counts (0, 1, 2, ...),
never 15/30/40; the strings are produced only for display.

Rules implemented (ITF Rules of Tennis):

- Game: first to 4 points with a 2-point lead. With `no_ad`, at 3-3 the next point decides
  the game. Its serving side follows the point count (6 points played -> "deuce" court); in
  real no-ad play the receiver chooses the court, here it is always the deuce court.
- Set: first to `games_per_set` games with a 2-game lead; at `tiebreak_at`-all a tie-break is
  played and its winner takes the set `tiebreak_at + 1` to `tiebreak_at` (7-6, or 13-12 for
  the "tiebreak7_at_12" final set). The final set follows `final_set`; with
  `match_tiebreak_points` it is replaced by a match tie-break, recorded as a set 1-0.
- Tie-break: first to N points with a 2-point lead (no-ad never applies). The player due to
  serve serves point 1, then the players alternate every two points. The tie-break counts as
  one game for the order of service, so its first server receives first in the next set.
- Change of ends (ITF rule 10): after the 1st, 3rd, 5th ... game of EACH set, so also at the
  end of a set with an odd number of games and after the first game of the next set; inside a
  tie-break after every 6 points, and once more when the tie-break (and so the set) ends.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import numpy as np

from sportsngen.errors import ArgumentError

FINAL_SET_RULES = ("tiebreak7", "tiebreak10", "advantage", "tiebreak7_at_12")
SLAMS = ("ausopen", "frenchopen", "wimbledon", "usopen")
SLAM_YEARS = range(2011, 2025)
GENDERS = ("men", "women")

# Order of the numbers in `MatchState.score_vector()`: everything from the SERVER's view.
SCORE_VECTOR_FIELDS = (
    "sets_won_server",
    "sets_won_receiver",
    "games_server",
    "games_receiver",
    "points_server",  # deuce-reduced: (5, 5) -> (3, 3), (6, 5) -> (4, 3); tie-break likewise
    "points_receiver",
    "in_tiebreak",
    "is_final_set",
    "is_break_point",
    "set_point_server",
    "set_point_receiver",
    "match_point_server",
    "match_point_receiver",
)

_POINT_NAMES = ("0", "15", "30", "40")


@dataclass(frozen=True)
class MatchFormat:
    """How a match is scored. Invalid values or combinations raise ValueError.

    `final_set`: "tiebreak7" plays the final set like the others (a `tiebreak_points`
    tie-break at `tiebreak_at`-all); "tiebreak10" a 10-point tie-break at `tiebreak_at`-all;
    "advantage" no tie-break (won by two games); "tiebreak7_at_12" a `tiebreak_points`
    tie-break at 12-12. `match_tiebreak_points` (e.g. 10) replaces the whole final set by one
    tie-break to that many points; `final_set` must then stay at its default.
    """

    best_of: int = 3
    games_per_set: int = 6
    tiebreak_at: int = 6
    tiebreak_points: int = 7
    final_set: str = "tiebreak7"
    no_ad: bool = False
    match_tiebreak_points: int | None = None

    def __post_init__(self) -> None:
        # Integers of any kind (numpy's included) are stored as int. Bools are not numbers here
        # (best_of=True passed as 1), and no_ad must be a bool (the string "no" is truthy).
        for name in ("best_of", "games_per_set", "tiebreak_at", "tiebreak_points",
                     "match_tiebreak_points"):
            value = getattr(self, name)
            if isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_)):
                object.__setattr__(self, name, int(value))
        if isinstance(self.no_ad, np.bool_):
            object.__setattr__(self, "no_ad", bool(self.no_ad))
        if not _is_int(self.best_of) or self.best_of < 1 or self.best_of % 2 == 0:
            raise ArgumentError(f"best_of must be a positive odd int (3 or 5), "
                                f"got {self.best_of!r}")
        if not _is_int(self.games_per_set) or self.games_per_set < 1:
            raise ArgumentError(f"games_per_set must be an int >= 1, got {self.games_per_set!r}")
        if not _is_int(self.tiebreak_at) or self.tiebreak_at < self.games_per_set - 1:
            raise ArgumentError(
                f"tiebreak_at must be an int >= games_per_set - 1 = {self.games_per_set - 1}, "
                f"got {self.tiebreak_at!r}"
            )
        if not _is_int(self.tiebreak_points) or self.tiebreak_points < 1:
            raise ArgumentError(f"tiebreak_points must be an int >= 1, "
                                f"got {self.tiebreak_points!r}")
        if not isinstance(self.no_ad, bool):
            raise ArgumentError(f"no_ad must be True or False, got {self.no_ad!r}")
        if self.final_set not in FINAL_SET_RULES:
            raise ArgumentError(f"final_set must be one of {FINAL_SET_RULES}, "
                                f"got {self.final_set!r}")
        if self.final_set == "tiebreak7_at_12" and self.games_per_set > 13:
            raise ArgumentError("final_set 'tiebreak7_at_12' needs games_per_set <= 13")
        if self.match_tiebreak_points is not None:
            if not _is_int(self.match_tiebreak_points) or self.match_tiebreak_points < 1:
                raise ArgumentError(
                    "match_tiebreak_points must be None or an int >= 1, "
                    f"got {self.match_tiebreak_points!r}"
                )
            if self.final_set != "tiebreak7":
                raise ArgumentError(
                    "match_tiebreak_points replaces the final set, so final_set must stay at "
                    f"its default 'tiebreak7', got final_set={self.final_set!r}"
                )

    @property
    def sets_to_win(self) -> int:
        return self.best_of // 2 + 1

    def set_rule(self, set_no: int) -> tuple[int | None, int, bool]:
        """Rule of set `set_no` (1-based): (tie-break at this many games-all or None,
        tie-break points, whether the set is a match tie-break)."""
        if set_no < self.best_of:
            return self.tiebreak_at, self.tiebreak_points, False
        if self.match_tiebreak_points is not None:
            return 0, self.match_tiebreak_points, True
        if self.final_set == "tiebreak7":
            return self.tiebreak_at, self.tiebreak_points, False
        if self.final_set == "tiebreak10":
            return self.tiebreak_at, 10, False
        if self.final_set == "tiebreak7_at_12":
            return 12, self.tiebreak_points, False
        return None, self.tiebreak_points, False  # advantage

    @classmethod
    def for_slam(cls, slam: str, year: int, gender: str) -> MatchFormat:
        """Singles format of a Grand Slam: men best of 5 sets, women best of 3.

        All non-final sets: 7-point tie-break at 6-6. Final set (same for men and women):
        - usopen: 7-point tie-break at 6-6 in 2011-2021, 10-point tie-break from 2022;
        - wimbledon: advantage until 2018, 7-point tie-break at 12-12 in 2019-2021 (the 2020
          event was cancelled; the rule in force is still returned), 10-point from 2022;
        - ausopen: advantage until 2018, 10-point tie-break at 6-6 from 2019;
        - frenchopen: advantage until 2021, 10-point tie-break at 6-6 from 2022.
        The 2022 change is the slams' joint rule (10-point tie-break at 6-6 in the final set).
        """
        if slam not in SLAMS:
            raise ValueError(f"unknown slam {slam!r}; valid: {SLAMS}")
        if year not in SLAM_YEARS:
            raise ValueError(
                f"year {year!r} not covered; valid: {SLAM_YEARS.start}..{SLAM_YEARS.stop - 1}"
            )
        if gender not in GENDERS:
            raise ValueError(f"unknown gender {gender!r}; valid: {GENDERS}")
        if year >= 2022:
            final = "tiebreak10"
        elif slam == "usopen":
            final = "tiebreak7"
        elif slam == "wimbledon":
            final = "tiebreak7_at_12" if year >= 2019 else "advantage"
        elif slam == "ausopen":
            final = "tiebreak10" if year >= 2019 else "advantage"
        else:
            final = "advantage"
        return cls(best_of=5 if gender == "men" else 3, final_set=final)


# --- small pure helpers ------------------------------------------------------------------


def point_label(mine: int, theirs: int, in_tiebreak: bool = False) -> str:
    """One player's point score from raw counts: "0", "15", "30", "40" or "AD" in a game (deuce
    is "40" for both), the count as digits in a tie-break."""
    if in_tiebreak:
        return str(int(mine))
    if mine >= 3 and theirs >= 3:
        return "AD" if mine > theirs else "40"
    return _POINT_NAMES[min(int(mine), 3)]


def _game_won(points: tuple[int, int] | list[int], p: int, no_ad: bool) -> bool:
    """Has player p won a regular game at this point count?"""
    mine, theirs = points[p], points[1 - p]
    return mine >= 4 and (mine - theirs >= 2 or (no_ad and mine > theirs))


def _race_won(points: tuple[int, int] | list[int], p: int, target: int) -> bool:
    """Has player p won a first-to-`target`, win-by-2 race (tie-break or set)?"""
    return points[p] >= target and points[p] - points[1 - p] >= 2


def _winner_of(pair: tuple[int, int]) -> int:
    return 0 if pair[0] > pair[1] else 1


def _server_at(
    first_server: int, games_played: int, in_tiebreak: bool, tb_points_played: int
) -> int:
    """Who serves, from the first server and the games played in the whole match (a tie-break
    counts as one game). In a tie-break: point 1 by the game's server, then pairs alternate."""
    server = first_server if games_played % 2 == 0 else 1 - first_server
    if in_tiebreak and ((tb_points_played + 1) // 2) % 2 == 1:
        server = 1 - server
    return server


@dataclass(frozen=True)
class MatchState:
    """The score of a match at one moment (immutable). See the module docstring for rules.

    `points_played` is a running count kept for convenience; it is not part of the score, so
    it is ignored by == and hash (a state built by `from_score` only knows a lower bound).
    """

    fmt: MatchFormat
    first_server: int
    server: int
    sets: tuple[tuple[int, int], ...]
    tiebreaks: tuple[tuple[int, int] | None, ...]
    games: tuple[int, int]
    points: tuple[int, int]
    in_tiebreak: bool
    winner: int | None
    points_played: int = field(default=0, compare=False)

    # --- construction ------------------------------------------------------------------

    @classmethod
    def new(cls, fmt: MatchFormat | None = None, first_server: int = 0) -> MatchState:
        """The score before the first point."""
        fmt = MatchFormat() if fmt is None else fmt
        if not isinstance(fmt, MatchFormat):
            raise ArgumentError(f"fmt must be a MatchFormat (or None for best of 3), got {fmt!r}")
        _check_player(first_server, "first_server")
        match_tb = fmt.set_rule(1)[2]  # best_of=1 with a match tie-break: the match IS one
        return cls(fmt, first_server, first_server, (), (), (0, 0), (0, 0), match_tb, None, 0)

    @classmethod
    def from_score(
        cls,
        fmt: MatchFormat | None,
        sets: tuple[tuple[int, int], ...] | list,
        games: tuple[int, int],
        points: tuple[int, int],
        server: int,
        in_tiebreak: bool | None = None,
        first_server: int | None = None,
        tiebreaks: tuple[tuple[int, int] | None, ...] | list | None = None,
        points_played: int | None = None,
    ) -> MatchState:
        """Build a mid-match state from a score; impossible scores raise ValueError.

        `sets`: games of each completed set (a match tie-break as (1, 0) or (0, 1)).
        `tiebreaks`: points of each completed set's tie-break (None where none was played);
        when omitted every entry is None, which for a 7-6 set means "points unknown" (the
        change of ends then counts that tie-break as exactly one change).
        `in_tiebreak` is inferred from the games when None. `first_server` is inferred from
        `server` when None, else checked against it. `points_played` defaults to the least
        number of points that can produce this score.
        """
        fmt = MatchFormat() if fmt is None else fmt
        if not isinstance(fmt, MatchFormat):
            raise ArgumentError(f"fmt must be a MatchFormat (or None for best of 3), got {fmt!r}")
        _check_player(server, "server")
        sets_t = tuple(_pair(s, f"sets[{i}]") for i, s in enumerate(sets))
        games_t = _pair(games, "games")
        points_t = _pair(points, "points")
        if tiebreaks is None:
            tbs: tuple[tuple[int, int] | None, ...] = (None,) * len(sets_t)
        else:
            tbs = tuple(
                None if t is None else _pair(t, f"tiebreaks[{i}]") for i, t in enumerate(tiebreaks)
            )
            if len(tbs) != len(sets_t):
                raise ValueError(f"tiebreaks has {len(tbs)} entries but sets has {len(sets_t)}")

        won = [0, 0]
        winner = None
        for i, (s, tb) in enumerate(zip(sets_t, tbs)):
            if winner is not None:
                raise ValueError(f"sets[{i}]={s} played after the match was already won")
            _check_completed_set(fmt, i + 1, s, tb)
            won[_winner_of(s)] += 1
            if won[_winner_of(s)] == fmt.sets_to_win:
                winner = _winner_of(s)

        set_no = len(sets_t) + 1
        if winner is not None:
            if games_t != (0, 0) or points_t != (0, 0) or in_tiebreak:
                raise ValueError(
                    f"match is over (sets {sets_t}) but games={games_t}, points={points_t}, "
                    f"in_tiebreak={in_tiebreak}"
                )
            tb_now = False
        else:
            tb_now = _check_current_set(fmt, set_no, games_t, points_t)
            if in_tiebreak is not None and bool(in_tiebreak) != tb_now:
                raise ValueError(
                    f"in_tiebreak={in_tiebreak} contradicts games {games_t} in set {set_no}"
                )

        games_played = sum(a + b for a, b in sets_t) + sum(games_t)
        derived0 = _server_at(0, games_played, tb_now, sum(points_t))
        inferred_first = 0 if derived0 == server else 1
        if first_server is None:
            first_server = inferred_first
        else:
            _check_player(first_server, "first_server")
            if first_server != inferred_first:
                raise ValueError(
                    f"server={server} is impossible with first_server={first_server} at sets "
                    f"{sets_t}, games {games_t}, points {points_t}"
                )
        if points_played is None:
            points_played = _min_points(fmt, sets_t, tbs, games_t, points_t)
        return cls(
            fmt, first_server, server, sets_t, tbs, games_t, points_t, tb_now, winner,
            int(points_played),
        )  # fmt: skip

    # --- the one state transition ---------------------------------------------------------

    def point_won(self, by: int) -> MatchState:
        """The state after player `by` wins the next point."""
        _check_player(by, "by")
        if self.winner is not None:
            raise ValueError(f"match is over (won by player {self.winner}); no more points")
        fmt = self.fmt
        pts = [self.points[0], self.points[1]]
        pts[by] += 1
        n = self.points_played + 1
        sets, tbs = self.sets, self.tiebreaks
        # Most points end no game: they need neither the set's rule nor the games played.
        if not self.in_tiebreak and not _game_won(pts, by, fmt.no_ad):
            return MatchState(
                fmt, self.first_server, self.server, sets, tbs, self.games, (pts[0], pts[1]),
                False, None, n,
            )  # fmt: skip
        tb_at, tb_target, match_tb = fmt.set_rule(len(sets) + 1)
        games = [self.games[0], self.games[1]]
        games_before = sum(a + b for a, b in sets) + games[0] + games[1]

        if self.in_tiebreak:
            if not _race_won(pts, by, tb_target):
                server = _server_at(self.first_server, games_before, True, pts[0] + pts[1])
                return MatchState(
                    fmt, self.first_server, server, sets, tbs, self.games, (pts[0], pts[1]),
                    True, None, n,
                )  # fmt: skip
            if match_tb:
                games = [0, 0]
            games[by] += 1
            return self._set_over(games, (pts[0], pts[1]), by, n)

        games[by] += 1
        if _race_won(games, by, fmt.games_per_set):
            return self._set_over(games, None, by, n)
        tb_now = tb_at is not None and games[0] == tb_at and games[1] == tb_at
        server = _server_at(self.first_server, games_before + 1, tb_now, 0)
        return MatchState(
            fmt, self.first_server, server, sets, tbs, (games[0], games[1]), (0, 0), tb_now,
            None, n,
        )  # fmt: skip

    def _set_over(
        self, games: list[int], tb: tuple[int, int] | None, by: int, n: int
    ) -> MatchState:
        sets = self.sets + ((games[0], games[1]),)
        tbs = self.tiebreaks + (tb,)
        games_played = sum(a + b for a, b in sets)
        server = _server_at(self.first_server, games_played, False, 0)
        won_by = sum(1 for s in sets if _winner_of(s) == by)
        winner = by if won_by == self.fmt.sets_to_win else None
        next_is_match_tb = winner is None and self.fmt.set_rule(len(sets) + 1)[2]
        return MatchState(
            self.fmt, self.first_server, server, sets, tbs, (0, 0), (0, 0), next_is_match_tb,
            winner, n,
        )  # fmt: skip

    # --- derived properties -------------------------------------------------------------

    @property
    def receiver(self) -> int:
        return 1 - self.server

    @property
    def serving_side(self) -> str:
        """The "deuce" court after an even number of points in the game or tie-break, else "ad"."""
        return "deuce" if (self.points[0] + self.points[1]) % 2 == 0 else "ad"

    @property
    def ends(self) -> tuple[int, int]:
        """ends[i]: sign of x of player i's baseline. Player 0 starts at -1 (ITF rule 10)."""
        changes = 0
        for (a, b), tb in zip(self.sets, self.tiebreaks):
            changes += (a + b + 1) // 2  # after each odd game of the set (tie-break included)
            if tb is not None and tb[0] + tb[1] > 0:
                changes += (tb[0] + tb[1] - 1) // 6  # inside the tie-break, before its end
        changes += (self.games[0] + self.games[1] + 1) // 2
        if self.in_tiebreak:
            changes += (self.points[0] + self.points[1]) // 6
        return (-1, 1) if changes % 2 == 0 else (1, -1)

    @property
    def is_over(self) -> bool:
        return self.winner is not None

    @property
    def sets_won(self) -> tuple[int, int]:
        w1 = sum(1 for s in self.sets if s[1] > s[0])
        return (len(self.sets) - w1, w1)

    @property
    def set_no(self) -> int:
        """1-based number of the current set (of the last set once the match is over)."""
        return len(self.sets) if self.winner is not None else len(self.sets) + 1

    @property
    def is_final_set(self) -> bool:
        return self.set_no == self.fmt.best_of

    def _wins_game_next(self, p: int) -> bool:
        """Would player p end the current game or tie-break by winning the next point?"""
        pts = [self.points[0], self.points[1]]
        pts[p] += 1
        if self.in_tiebreak:
            return _race_won(pts, p, self.fmt.set_rule(self.set_no)[1])
        return _game_won(pts, p, self.fmt.no_ad)

    def _wins_set_next(self, p: int) -> bool:
        if self.winner is not None or not self._wins_game_next(p):
            return False
        if self.in_tiebreak:
            return True
        games = [self.games[0], self.games[1]]
        games[p] += 1
        return _race_won(games, p, self.fmt.games_per_set)

    @property
    def is_break_point(self) -> bool:
        """The receiver would win the game (not a tie-break) by winning the next point."""
        return self.winner is None and not self.in_tiebreak and self._wins_game_next(self.receiver)

    @property
    def set_point_for(self) -> int | None:
        for p in (0, 1):
            if self._wins_set_next(p):
                return p
        return None

    @property
    def match_point_for(self) -> int | None:
        p = self.set_point_for
        if p is not None and self.sets_won[p] + 1 == self.fmt.sets_to_win:
            return p
        return None

    # --- display and model features ----------------------------------------------------

    def point_score_str(self) -> str:
        """Current game score, player 0 first: "0-15", "40-40", "AD-40"; tie-break "5-3"."""
        a, b = self.points
        return f"{point_label(a, b, self.in_tiebreak)}-{point_label(b, a, self.in_tiebreak)}"

    def score_str(self) -> str:
        """Score from player 0's view, space separated.

        Completed sets as "6-4"; a tie-break set as "7-6(5)" / "6-7(5)" with the tie-break
        loser's points (plain "7-6" when unknown); a match tie-break as "[10-8]". Then, while
        the match is on, the current set's games ("2-3"), followed by the point score when a
        point of the current game has been played or a tie-break is on ("2-3 40-AD",
        "6-6 5-3"); a match tie-break in progress shows as "[5-3]" alone. Start: "0-0".
        """
        parts = []
        for i, ((a, b), tb) in enumerate(zip(self.sets, self.tiebreaks)):
            if self.fmt.set_rule(i + 1)[2]:
                parts.append(f"[{tb[0]}-{tb[1]}]" if tb is not None else f"[{a}-{b}]")
            elif tb is not None:
                parts.append(f"{a}-{b}({min(tb)})")
            else:
                parts.append(f"{a}-{b}")
        if self.winner is None:
            if self.fmt.set_rule(self.set_no)[2]:
                parts.append(f"[{self.points[0]}-{self.points[1]}]")
            else:
                parts.append(f"{self.games[0]}-{self.games[1]}")
                if self.in_tiebreak or self.points != (0, 0):
                    parts.append(self.point_score_str())
        return " ".join(parts)

    def score_vector(self) -> np.ndarray:
        """float32 summary from the server's view, ordered as SCORE_VECTOR_FIELDS.

        Points are deuce-reduced (a long deuce game or tie-break maps onto the equivalent
        smaller score) so the numbers stay bounded; flags are 0.0 / 1.0.
        """
        s, r = self.server, self.receiver
        pts = list(self.points)
        cap = self.fmt.set_rule(self.set_no)[1] - 1 if self.in_tiebreak else 3
        excess = min(pts) - cap
        if excess > 0:
            pts = [pts[0] - excess, pts[1] - excess]
        sw = self.sets_won
        sp, mp = self.set_point_for, self.match_point_for
        return np.array(
            [
                sw[s], sw[r], self.games[s], self.games[r], pts[s], pts[r],
                self.in_tiebreak, self.is_final_set, self.is_break_point,
                sp == s, sp == r, mp == s, mp == r,
            ],
            dtype=np.float32,
        )  # fmt: skip


# --- validation helpers ----------------------------------------------------------------


def _is_int(x: object) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _check_player(p: object, name: str) -> None:
    if p not in (0, 1) or isinstance(p, bool):
        raise ArgumentError(f"{name} must be player 0 or 1, got {p!r}")


def _pair(x: object, name: str) -> tuple[int, int]:
    try:
        a, b = x  # type: ignore[misc]
        a_i, b_i = int(a), int(b)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair of ints, got {x!r}") from None
    if a_i != a or b_i != b or a_i < 0 or b_i < 0:
        raise ValueError(f"{name} must be a pair of non-negative ints, got {x!r}")
    return (a_i, b_i)


def _game_state_ok(fmt: MatchFormat, set_no: int, g: tuple[int, int]) -> bool:
    """Is games `g` a reachable, unfinished state of set `set_no` (tie-break score allowed)?"""
    tb_at = fmt.set_rule(set_no)[0]
    if _race_won(g, 0, fmt.games_per_set) or _race_won(g, 1, fmt.games_per_set):
        return False
    return tb_at is None or max(g) <= tb_at


def _check_completed_set(
    fmt: MatchFormat, set_no: int, s: tuple[int, int], tb: tuple[int, int] | None
) -> None:
    tb_at, tb_target, match_tb = fmt.set_rule(set_no)
    w = _winner_of(s)
    if match_tb:
        ok_games = s in ((1, 0), (0, 1))
        by_tb = True
    else:
        by_tb = tb_at is not None and s[w] == tb_at + 1 and s[1 - w] == tb_at
        before = (s[0] - (w == 0), s[1] - (w == 1))
        ok_games = by_tb or (
            _race_won(s, w, fmt.games_per_set)
            and _game_state_ok(fmt, set_no, before)
            and before != (tb_at, tb_at)
        )
    if not ok_games:
        raise ValueError(f"set {set_no} score {s} is impossible in {fmt}")
    if tb is None:
        return
    if not by_tb:
        raise ValueError(f"set {set_no} score {s} had no tie-break, but tiebreaks gives {tb}")
    tb_w = _winner_of(tb)
    before_tb = (tb[0] - (tb_w == 0), tb[1] - (tb_w == 1))
    if tb_w != w or not _race_won(tb, w, tb_target) or _race_won(before_tb, w, tb_target):
        raise ValueError(f"tie-break {tb} is impossible for set {set_no} score {s}")


def _check_current_set(
    fmt: MatchFormat, set_no: int, games: tuple[int, int], points: tuple[int, int]
) -> bool:
    """Validate the unfinished set's games and points; return whether a tie-break is on."""
    tb_at, tb_target, match_tb = fmt.set_rule(set_no)
    if match_tb:
        if games != (0, 0):
            raise ValueError(f"set {set_no} is a match tie-break; games must be (0, 0): {games}")
        in_tb = True
    else:
        if not _game_state_ok(fmt, set_no, games):
            raise ValueError(f"games {games} impossible in unfinished set {set_no} of {fmt}")
        in_tb = tb_at is not None and games == (tb_at, tb_at)
    if in_tb:
        bad = _race_won(points, 0, tb_target) or _race_won(points, 1, tb_target)
    else:
        bad = _game_won(points, 0, fmt.no_ad) or _game_won(points, 1, fmt.no_ad)
        bad = bad or (fmt.no_ad and max(points) > 3)
    if bad:
        kind = "tie-break" if in_tb else "game"
        raise ValueError(f"points {points} impossible in an unfinished {kind} of {fmt}")
    return in_tb


def _min_points(
    fmt: MatchFormat,
    sets: tuple[tuple[int, int], ...],
    tbs: tuple[tuple[int, int] | None, ...],
    games: tuple[int, int],
    points: tuple[int, int],
) -> int:
    """Fewest points that produce this score (love games, shortest tie-breaks)."""
    total = points[0] + points[1] + 4 * (games[0] + games[1])
    for i, ((a, b), tb) in enumerate(zip(sets, tbs)):
        tb_at, tb_target, match_tb = fmt.set_rule(i + 1)
        by_tb = match_tb or (tb_at is not None and max(a, b) == tb_at + 1 and min(a, b) == tb_at)
        if by_tb:
            total += tb[0] + tb[1] if tb is not None else tb_target
            total += 0 if match_tb else 4 * (a + b - 1)
        else:
            total += 4 * (a + b)
    return total
