"""Whole matches with the learned engine: points chained through `MatchState`, many matches
rolled forward together.

Every round, each unfinished match contributes the rally it needs next (a first serve, or the
second serve after a fault) and all of them go through one batched `Simulator.simulate_rallies`
call. A rally that breaks physics, or that the rules cannot decide, is set aside (kept in
`MatchResult.discarded`, counted) and the same serve is played again; after `max_retries` such
replays in a row, the point goes to the rules' verdict if there is one, else to a coin toss
(counted in `forced_decisions`; its rally's end_reason becomes "winner" with end_detail "none",
its shots keep the outcomes they were played with).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from sportsngen.data.tracking import SURFACES, RallyData
from sportsngen.errors import ArgumentError, check_choice, check_int, check_players
from sportsngen.eval.stats import serve_stats
from sportsngen.synth.generate import score_row
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


def simulate_matches(sim, matchups, surface: str, fmt: MatchFormat | None = None,
                     seed: int = 0, first_server: int | None = None, progress: bool = True,
                     tournament: str = "synthetic") -> list[MatchResult]:
    """Play each (player1, player2) of `matchups` to the end with `sim` (a `Simulator`)."""
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
    rng = np.random.default_rng(seed)
    n = len(matchups)
    states = [MatchState.new(fmt, first_server=int(rng.integers(2)) if first_server is None
                             else first_server) for _ in range(n)]
    point_no = [1] * n
    serve_no = [1] * n
    retries = [0] * n
    forced = [0] * n
    rounds: list[RallyData] = []
    counted: set[int] = set()
    overrides: dict[int, str] = {}      # rally_id -> winner, for points decided by fiat
    next_id = 0
    bar = tqdm(desc="points", unit="pt", disable=not progress)
    while True:
        live = [i for i in range(n) if not states[i].is_over]
        if not live:
            break
        rows = [_plan_row(states[i], matchups[i], f"sim-{seed}-{i:04d}", point_no[i],
                          serve_no[i], surface, tournament) for i in live]
        plan = pd.DataFrame(rows)
        plan.insert(0, "rally_id", np.arange(next_id, next_id + len(live)))
        next_id += len(live)
        data = sim.simulate_rallies(plan, seed=int(rng.integers(2 ** 62)))
        rounds.append(data)
        r = data.rallies
        for i, rid, real, reason, winner, server_name in zip(
                live, r["rally_id"], r["realistic"], r["end_reason"], r["winner"], r["server"]):
            decided = reason != "none"
            if not (bool(real) and decided):
                retries[i] += 1
                if retries[i] <= sim.max_retries:
                    continue                  # set aside; the same serve is played again
                forced[i] += 1                # give up: the rules' verdict, else a coin toss
                if not decided:
                    pair = matchups[i]
                    winner = overrides[int(rid)] = pair[int(rng.integers(2))]
            counted.add(int(rid))
            retries[i] = 0
            if reason == "fault":
                serve_no[i] = 2
                continue
            server = states[i].server
            states[i] = states[i].point_won(server if winner == server_name else 1 - server)
            point_no[i] += 1
            serve_no[i] = 1
            bar.update(1)
        bar.set_postfix(live=len(live))
    bar.close()
    ids = [f"sim-{seed}-{i:04d}" for i in range(n)]
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
