"""Whole matches with the learned engine: points chained through `MatchState`, many matches
rolled forward together.

Every round, each unfinished match contributes the rally it needs next (a first serve, or the
second serve after a fault) and all of them go through one batched `Simulator.simulate_rallies`
call. A rally that breaks physics, or that the rules cannot decide, is set aside (kept in
`MatchResult.discarded`, counted) and the same serve is played again; after `max_retries` such
replays in a row, the point goes to the rules' verdict if there is one, else to a coin toss
(counted in `forced_decisions`; its rally's end_reason becomes "winner" with end_detail "none",
its shots keep the outcomes they were played with).

Every rally is played from a seed of its own, drawn from the match's seed and the rally's
context (`rally_seed`: match, point, serve, score, replays), so what happens in a rally depends
on where it stands in its match alone. That is what lets one match be played ahead along its
likely score paths in worker processes (`lookahead`, `sim.lookahead`) with the same result.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from sportsngen.data.points import score_row
from sportsngen.data.tracking import SURFACES, RallyData
from sportsngen.errors import ArgumentError, check_choice, check_int, check_players
from sportsngen.eval.stats import serve_stats
from sportsngen.sim.lookahead import Lookahead
from sportsngen.tennis.scoring import MatchFormat, MatchState


@dataclass
class MatchResult:
    players: tuple[str, str]
    surface: str
    state: MatchState
    points: pd.DataFrame          # the points table (`sportsngen.data.points`), one row a point
    rallies: RallyData            # the rallies that count (realistic, decided)
    discarded: RallyData | None   # rallies set aside (non-realistic or undecided)
    forced_decisions: int         # rallies (a fault is one) counted with no realistic replay

    @property
    def n_discarded(self) -> int:
        return 0 if self.discarded is None else len(self.discarded)

    @property
    def winner(self) -> str:
        return self.players[self.state.winner] if self.state.is_over else ""

    @property
    def score_line(self) -> str:
        """"Winner d. loser 7-6(5) 6-4", the score from the winner's side."""
        if not self.state.is_over:
            return f"{self.players[0]} v {self.players[1]} {self.state.score_str()} (unfinished)"
        w = self.state.winner
        return f"{self.players[w]} d. {self.players[1 - w]} {winner_view(self.state)}"

    def summary(self) -> pd.DataFrame:
        """Serving statistics per player (`serve_stats`) plus points won."""
        out = serve_stats(self.points)
        won = self.points["winner"].value_counts()
        out["points_won"] = [int(won.get(p, 0)) for p in out.index]
        return out


def winner_view(state: MatchState) -> str:
    """Score line from the winner's side, as tennis reports it ("7-6(5) 6-4")."""
    if state.winner == 0:
        return state.score_str()
    parts = []
    for (a, b), tb in zip(state.sets, state.tiebreaks):
        s = f"{b}-{a}"
        if tb is not None and max(a, b) - min(a, b) == 1 and min(a, b) >= 6:
            s += f"({min(tb)})"
        parts.append(s)
    return " ".join(parts)


def _plan_row(state: MatchState, names: tuple[str, str], match_id: str, point: int,
              serve_number: int, surface: str, tournament: str) -> dict:
    server = state.server
    return {"match_id": match_id, "point": point, "server": names[server],
            "receiver": names[1 - server], "serve_number": serve_number,
            "side": state.serving_side, "server_end": state.ends[server], "surface": surface,
            "tournament": tournament, **score_row(state, server)}


def rally_seed(match_seed: int, row: dict, attempt: int) -> int:
    """A rally's own random stream, from the match's seed, the rally's context (its plan row:
    match, point, serve, score, ends, surface) and how often it has been replayed: a rally's
    result then depends on where it stands in its match alone, not on what was played before
    or beside it, which makes look-ahead exact (`sim.lookahead`)."""
    text = json.dumps([int(match_seed), int(attempt), row], sort_keys=True, default=str)
    return int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "little") >> 2


def _round_seed(seeds: list[int]) -> int:
    """One batch's seed: the rally's own when it plays alone, else one drawn from all of them."""
    if len(seeds) == 1:
        return seeds[0]
    return int(np.random.default_rng(seeds).integers(2 ** 62))


@dataclass(frozen=True)
class _Context:
    """Where a match stands before a rally: the score, the point's number, the serve (1 or 2)
    and how many of its rallies were set aside (replays)."""

    state: MatchState
    point: int = 1
    serve: int = 1
    attempt: int = 0

    def after(self, outcome: str) -> _Context:
        """The next rally's context after this one's `outcome`: "replay" (set aside),
        "fault" (a first serve's), "server" or "receiver" (who won the point)."""
        if outcome == "replay":
            return replace(self, attempt=self.attempt + 1)
        if outcome == "fault":
            return _Context(self.state, self.point, 2, 0)
        server = self.state.server
        return _Context(self.state.point_won(server if outcome == "server" else 1 - server),
                        self.point + 1, 1, 0)


class _Odds:
    """Each serve's outcomes so far in a match, from priors of a few rallies' weight (a
    first serve: 38 % faults, 42 % the server's points; a second: 55 % the server's): what
    `likely_path` follows."""

    def __init__(self):
        self.counts = {1: {"fault": 1.9, "server": 2.1, "receiver": 1.0},
                       2: {"server": 2.75, "receiver": 2.25}}

    def add(self, serve: int, outcome: str) -> None:
        if outcome in self.counts[serve]:
            self.counts[serve][outcome] += 1.0

    def likeliest(self, serve: int) -> str:
        c = self.counts[serve]
        return max(c, key=c.get)


def likely_path(ctx: _Context, odds: _Odds, depth: int) -> list[_Context]:
    """`ctx` and the `depth` rallies after it, each the likeliest outcome's (`_Odds`), up to
    the match's end."""
    path = [ctx]
    while len(path) <= depth and not path[-1].state.is_over:
        path.append(path[-1].after(odds.likeliest(path[-1].serve)))
    return path


def _with_rally_id(data: RallyData, rally_id: int) -> RallyData:
    """A one-rally RallyData with its rally id set (rallies played alone are played as 0)."""
    return RallyData(*(t.assign(rally_id=rally_id) for t in (data.frames, data.rallies,
                                                               data.shots)),
                     data.fps, dict(data.meta))


def simulate_matches(sim, matchups, surface: str, fmt: MatchFormat | None = None,
                     seed: int = 0, first_server: int | None = None, progress: bool = True,
                     tournament: str = "synthetic", lookahead: int = 0,
                     lookahead_depth: int = 2) -> list[MatchResult]:
    """Play each (player1, player2) of `matchups` to the end with `sim` (a `Simulator`).
    Every rally is played from its own seed (`rally_seed`); several matches play their
    rallies together, a round's rallies in one batch. `lookahead` (one match only): worker
    processes that play the match's likely next `lookahead_depth` rallies ahead
    (`sim.lookahead`); the match is the same with it on or off."""
    fmt = MatchFormat() if fmt is None else fmt
    if not isinstance(fmt, MatchFormat):
        raise ArgumentError(f"fmt must be a MatchFormat (or None for best of 3), got {fmt!r}")
    check_choice("surface", surface, SURFACES)
    seed = check_int("seed", seed, 0)
    if isinstance(matchups, (str, bytes)) or not hasattr(matchups, "__iter__"):
        raise ArgumentError(f"matchups must be a list of (player1, player2) pairs, got "
                            f"{matchups!r}")
    if any(isinstance(m, str) for m in matchups):
        raise ArgumentError(f"matchups must be (player1, player2) pairs, not names: {matchups!r}")
    matchups = [tuple(m) for m in matchups]
    if not matchups or any(len(m) != 2 or m[0] == m[1] for m in matchups):
        raise ArgumentError("matchups must be a non-empty list of (player1, player2) pairs of "
                            "different players")
    for a, b in matchups:
        check_players(a, b, ("player1", "player2"))
    if first_server not in (None, 0, 1) or isinstance(first_server, bool):
        raise ArgumentError(f"first_server must be None, 0 or 1, got {first_server!r}")
    lookahead = check_int("lookahead", lookahead, 0, 64)
    lookahead_depth = check_int("lookahead_depth", lookahead_depth, 1, 64)
    if lookahead and len(matchups) > 1:
        raise ArgumentError("lookahead plays one match ahead; several matches already play "
                            "their rallies together")
    rng = np.random.default_rng(seed)
    n = len(matchups)
    ids = [f"sim-{seed}-{i:04d}" for i in range(n)]
    ctx = [_Context(MatchState.new(fmt, first_server=int(rng.integers(2))
                                   if first_server is None else first_server))
           for _ in range(n)]
    odds = [_Odds() for _ in range(n)]
    forced = [0] * n
    rounds: list[RallyData] = []
    counted: set[int] = set()
    overrides: dict[int, str] = {}      # rally_id -> winner, for points decided by fiat
    next_id = 0

    def row_of(i: int, c: _Context) -> tuple[int, dict]:
        row = _plan_row(c.state, matchups[i], ids[i], c.point, c.serve, surface, tournament)
        return rally_seed(seed, row, c.attempt), row

    ahead = Lookahead(sim, lookahead) if lookahead else None
    bar = tqdm(desc="points", unit="pt", disable=not progress)
    try:
        while True:
            live = [i for i in range(n) if not ctx[i].state.is_over]
            if not live:
                break
            if ahead is not None:
                path = [row_of(live[0], c) for c in likely_path(ctx[live[0]], odds[live[0]],
                                                                lookahead_depth)]
                data = _with_rally_id(ahead.play(path), next_id)
            else:
                items = [row_of(i, ctx[i]) for i in live]
                plan = pd.DataFrame([row for _, row in items])
                plan.insert(0, "rally_id", np.arange(next_id, next_id + len(live)))
                data = sim.simulate_rallies(plan, seed=_round_seed([s for s, _ in items]))
            next_id += len(live)
            rounds.append(data)
            r = data.rallies
            for i, rid, real, reason, winner, server_name in zip(
                    live, r["rally_id"], r["realistic"], r["end_reason"], r["winner"],
                    r["server"]):
                c = ctx[i]
                decided = reason != "none"
                if not (bool(real) and decided):
                    if c.attempt < sim.max_retries:
                        ctx[i] = c.after("replay")   # set aside; the same serve again
                        continue
                    forced[i] += 1                # give up: the rules' verdict, else a coin
                    if not decided:
                        coin = np.random.default_rng(row_of(i, c)[0]).integers(2)
                        winner = overrides[int(rid)] = matchups[i][int(coin)]
                counted.add(int(rid))
                outcome = "fault" if reason == "fault" else \
                    "server" if winner == server_name else "receiver"
                odds[i].add(c.serve, outcome)
                ctx[i] = c.after(outcome)
                if outcome != "fault":
                    bar.update(1)
            bar.set_postfix(live=len(live))
    finally:
        bar.close()
        if ahead is not None:
            ahead.close()
    states = [c.state for c in ctx]
    return _results(matchups, ids, surface, states, rounds, counted, overrides, forced)


def _results(matchups, ids, surface, states, rounds, counted, overrides,
             forced) -> list[MatchResult]:
    """Split the rounds' rallies by match into counted and discarded ones."""
    allr = RallyData.concat(rounds)
    r = allr.rallies
    for rid, winner in overrides.items():
        sel = r["rally_id"] == rid
        r.loc[sel, "winner"] = winner
        r.loc[sel, "end_reason"] = "winner"
    match_of = dict(zip(r["rally_id"], r["match_id"]))

    def split(df: pd.DataFrame) -> dict:
        key = df["rally_id"].map(match_of).to_numpy() + np.where(
            df["rally_id"].isin(counted).to_numpy(), "|1", "|0")
        return {k: g.reset_index(drop=True) for k, g in df.groupby(key, sort=False)}

    frames, shots, rallies = split(allr.frames), split(allr.shots), split(r)
    empty = {"frames": allr.frames.iloc[:0], "shots": allr.shots.iloc[:0]}
    out = []
    for i, players in enumerate(matchups):
        parts = {}
        for flag in ("1", "0"):
            key = f"{ids[i]}|{flag}"
            if key not in rallies:
                parts[flag] = None
                continue
            parts[flag] = RallyData(frames.get(key, empty["frames"]), rallies[key],
                                    shots.get(key, empty["shots"]), allr.fps, dict(allr.meta))
        kept = parts["1"]
        out.append(MatchResult(players, surface, states[i], kept.points(), kept, parts["0"],
                               forced[i]))
    return out
