"""Rally outcome prediction, counterfactual "what if" shots and match win probabilities.

- `rally_win_probability`: branch a real rally at one of its frames, roll n continuations and
  count how often the rally's server wins the point (a first serve that ends in a fault goes on
  with one simulated second serve).
- `counterfactual`: branch just before a shot's contact and force where the shot goes: at the
  first sampled frame where the ball leaves the hitter, only samples whose flight lands in the
  chosen direction (or target box) are accepted; the others are drawn again from the same
  distribution, so the shot is sampled from the model's distribution restricted to that option
  and renormalised. The landing point is the ballistic extrapolation of that frame's velocity
  (gravity, no drag or spin: enough to tell the direction, which depends on y only).
- `match_win_probability`: point-win rates on serve from simulated service points, then the
  exact Markov chain of the scoring from any `MatchState`.

Probabilities count realistic, decided rallies only; the rest are reported, not hidden.
Confidence intervals are Wilson score intervals (95 %).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import torch

from sportsngen.baselines.markov import match_win_probability as markov_match_win
from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import DIRECTIONS, RallyData
from sportsngen.errors import ArgumentError, check_int, check_players
from sportsngen.model.inputs import BALL
from sportsngen.sim.assemble import PLAN_COLUMNS, realistic_points
from sportsngen.sim.rollout import pad_tracks
from sportsngen.tennis import court
from sportsngen.tennis.scoring import MatchFormat, MatchState

G_MPS2 = 9.81
LEAVE_WINDOW_FRAMES = 12     # the constraint waits this long for the ball to leave the hitter
MAX_TRIES = 200
MAX_BRANCHES = 100_000       # rollouts a call (all held in memory)
SERVE_OPTIONS = ("wide", "body", "T")
SHOT_OPTIONS = ("cross_court", "down_the_line", "middle", "inside_out", "inside_in")


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n ((nan, nan) for n = 0)."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def _rally(data: RallyData, rally_id: int) -> tuple[pd.Series, np.ndarray, int]:
    """The rally's row, its positions (T, 3, 3) [server, receiver, ball], its first frame."""
    if not isinstance(data, RallyData):
        raise ArgumentError(f"rally_data must be a RallyData, got {type(data).__name__}")
    rally_id = check_int("rally_id", rally_id)
    r = data.rallies
    if rally_id not in set(r["rally_id"].tolist()):
        raise ArgumentError(f"rally_id {rally_id} is not in the data")
    sub = data.subset([rally_id])
    arr = rally_arrays(sub, Vocab.from_data(sub), unknown="generic")
    first = int(sub.frames["frame"].min())
    return r[r["rally_id"] == rally_id].iloc[0], arr.pos_m[:int(arr.length[0])], first


def _plan(row: pd.Series, n: int, serve_number: int | None = None) -> pd.DataFrame:
    plan = pd.DataFrame([row[PLAN_COLUMNS].to_dict()] * n)
    plan["rally_id"] = np.arange(n)
    plan["match_id"] = "branch"
    if serve_number is not None:
        plan["serve_number"] = serve_number
    return plan


def _branch_outcomes(sim, rows: pd.DataFrame, out: RallyData, seed: int) -> np.ndarray:
    """Per branch (one rally of `out` per row of `rows`, same order): 1.0 if the server won
    the point, 0.0 if he lost it, NaN if the branch (or its second serve) was not realistic or
    undecided. A first serve that ends in a fault goes on with one simulated second serve."""
    r = out.rallies.reset_index(drop=True)
    ok = r["realistic"].to_numpy(bool) & (r["end_reason"] != "none").to_numpy()
    res = np.where(r["winner"].to_numpy(dtype=object) == rows["server"].to_numpy(dtype=object),
                   1.0, 0.0)
    res[~ok] = np.nan
    fault = ok & (r["end_reason"] == "fault").to_numpy()
    if fault.any():
        plan = rows[fault].copy()
        plan["serve_number"] = 2
        plan["rally_id"] = np.arange(len(plan))
        second = sim.simulate_rallies(plan.reset_index(drop=True), seed=seed + 1)
        s2 = second.rallies.reset_index(drop=True)
        ok2 = s2["realistic"].to_numpy(bool) & (s2["end_reason"] != "none").to_numpy()
        won2 = s2["winner"].to_numpy(dtype=object) == plan["server"].to_numpy(dtype=object)
        res[fault] = np.where(ok2, won2.astype(float), np.nan)
    return res


def _summary(outcomes: np.ndarray) -> dict:
    done = ~np.isnan(outcomes)
    n_ok = int(done.sum())
    return {"p": float(outcomes[done].mean()) if n_ok else math.nan, "n": n_ok,
            "n_sims": len(outcomes), "n_unrealistic": int((~done).sum())}


def rally_win_probabilities(sim, data: RallyData, items, n: int = 100,
                            seed: int = 0) -> pd.DataFrame:
    """`rally_win_probability` for many (rally_id, frame) pairs at once, all in one set of
    batches (each branch keeps its own prefix). -> one row a pair: rally_id, frame, p, n,
    n_sims, n_unrealistic."""
    n = check_int("n", n, 1, MAX_BRANCHES)
    seed = check_int("seed", seed, 0)
    prefixes = []
    for rid, frame in items:
        row, pos, first = _rally(data, rid)
        k = check_int("frame", frame) - first
        if not 0 <= k < len(pos):
            raise ArgumentError(f"frame {frame} is outside rally {rid} (frames {first}.."
                                f"{first + len(pos) - 1})")
        prefixes.append((row, pos[:k + 1]))
    # One rollout for all the pairs, shortest prefix first (a batch starts at its shortest
    # and replays the others' recorded frames: `RolloutInputs.init_frames`).
    idx = sorted(range(len(prefixes)), key=lambda i: len(prefixes[i][1]))
    kept = np.repeat([len(prefixes[i][1]) for i in idx], n)
    plan = pd.concat([_plan(prefixes[i][0], n) for i in idx], ignore_index=True)
    plan["rally_id"] = np.arange(len(plan))
    init = pad_tracks([prefixes[i][1] for i in idx for _ in range(n)])
    out = sim.simulate_rallies(plan, seed=seed, init_pos_m=init, init_frames=kept)
    outcomes = _branch_outcomes(sim, plan, out, seed)
    results = {i: _summary(outcomes[j * n:(j + 1) * n]) for j, i in enumerate(idx)}
    return pd.DataFrame([{"rally_id": int(rid), "frame": int(f), **results[i]}
                         for i, (rid, f) in enumerate(items)])


def rally_win_probability(sim, data: RallyData, rally_id: int, frame: int, n: int = 100,
                          seed: int = 0, details: bool = False):
    """P(the rally's server wins the point), from `n` continuations of the rally after its
    frame number `frame` (a `frame` value of `data.frames`). With `details`, a dict with the
    counts behind it (n realistic decided branches, n_sims, n_unrealistic)."""
    res = rally_win_probabilities(sim, data, [(rally_id, frame)], n, seed).iloc[0]
    d = {k: res[k] for k in ("p", "n", "n_sims", "n_unrealistic")}
    return d if details else float(d["p"])


@dataclass
class ShotConstraint:
    """Accept a sampled frame only if the shot leaving the hitter lands as `option` says.

    `by_head`: the model's strike (or serve) head places the shot, after the frame is drawn
    (`SportsNGEN.place_strikes`), so the head's landing point is judged (`judge_strikes`) and
    the drawn frame is not. Judging the drawn frame there judged a ball the head then replaced:
    on the bundled file none of 100 "down the line" branches of a rally's third shot went down
    the line (docs/evaluation.md, session s104)."""

    option: str | tuple[float, float, float, float]
    hitter: int                   # 0 server, 1 receiver
    hitter_end: int               # sign of x of the hitter's baseline
    handedness: str
    stroke: str
    serve_side: str
    start_frame: int
    fps: float = 25.0
    max_tries: int = MAX_TRIES
    offset: int = 0
    by_head: bool = False
    done: set = field(default_factory=set)
    failed: set = field(default_factory=set)
    head_tries: dict = field(default_factory=dict)    # row -> the head's draws rejected

    @property
    def judges_strikes(self) -> bool:
        return self.by_head

    def accept(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
               next_pos_m: torch.Tensor, vel_mps: torch.Tensor | None = None) -> torch.Tensor:
        if self.by_head:
            return torch.ones(len(rows), dtype=torch.bool, device=next_pos_m.device)
        rows = np.asarray(rows) + self.offset
        p = next_pos_m[:, 2].double().cpu().numpy()
        v = (p - pos_m[:, 2].double().cpu().numpy()) * self.fps
        leaving = np.sign(v[:, 0]) == -self.hitter_end
        waiting = np.array([r not in self.done for r in rows]) & \
            (frame < self.start_frame + LEAVE_WINDOW_FRAMES)
        judge = waiting & leaving
        ok = np.ones(len(rows), dtype=bool)
        if judge.any():
            ok[judge] = self._lands_as_asked(p[judge], v[judge],
                                             pos_m[judge][:, self.hitter].cpu().numpy())
            for r in rows[judge & ok]:
                self.done.add(int(r))
        return torch.as_tensor(ok, device=next_pos_m.device)

    def give_up(self, rows: np.ndarray) -> None:
        for r in np.asarray(rows) + self.offset:
            self.failed.add(int(r))
            self.done.add(int(r))

    def judge_strikes(self, rows: np.ndarray, frame: int, pos_m: torch.Tensor,
                      land_xy: np.ndarray, serve: bool) -> np.ndarray:
        """(R,) bool: each head's launch from the frames `pos_m` (R, 3, 3) of rows `rows`,
        landing at `land_xy` (R, 2), may stand: not the hitter's shot in the window, or it lands
        as asked, or its row has had `max_tries` draws rejected (then it stands, and the row
        counts as failed)."""
        rows = np.asarray(rows) + self.offset
        ok = np.ones(len(rows), dtype=bool)
        if serve != (self.stroke == "serve") or frame >= self.start_frame + LEAVE_WINDOW_FRAMES:
            return ok
        contact = pos_m[:, BALL].double().cpu().numpy()
        judge = (np.sign(contact[:, 0]) == self.hitter_end) & \
            np.array([int(r) not in self.done for r in rows], dtype=bool)
        if not judge.any():
            return ok
        hitter_xy = pos_m[:, self.hitter, :2].double().cpu().numpy()[judge]
        ok[judge] = self._landing_as_asked(land_xy[judge, 0], land_xy[judge, 1], hitter_xy)
        for i in np.flatnonzero(judge):
            r = int(rows[i])
            if not ok[i]:
                self.head_tries[r] = self.head_tries.get(r, 0) + 1
                if self.head_tries[r] < self.max_tries:
                    continue
                ok[i] = True
                self.failed.add(r)
            self.done.add(r)
        return ok

    def _lands_as_asked(self, p: np.ndarray, v: np.ndarray, hitter_xy: np.ndarray) -> np.ndarray:
        disc = v[:, 2] ** 2 + 2 * G_MPS2 * np.maximum(p[:, 2], 0.0)
        t = (v[:, 2] + np.sqrt(disc)) / G_MPS2
        return self._landing_as_asked(p[:, 0] + v[:, 0] * t, p[:, 1] + v[:, 1] * t, hitter_xy)

    def _landing_as_asked(self, lx: np.ndarray, ly: np.ndarray,
                          hitter_xy: np.ndarray) -> np.ndarray:
        """(N,) bool: a ball landing at (lx, ly), struck by the hitter standing at hitter_xy
        (N, 2 or more), goes as `option` asks."""
        if isinstance(self.option, tuple):
            x0, x1, y0, y1 = self.option
            return (lx >= x0) & (lx <= x1) & (ly >= y0) & (ly <= y1)
        if self.stroke == "serve":
            return court.serve_zone(ly) == self.option
        stroke = self.stroke if self.stroke in ("forehand", "backhand", "forehand_volley",
                                                "backhand_volley", "overhead") else "forehand"
        got = court.shot_direction(hitter_xy[:, 0], hitter_xy[:, 1], lx, ly,
                                   np.full(len(lx), self.handedness), np.full(len(lx), stroke))
        want = {"cross_court": ("cross_court", "inside_out"),
                "down_the_line": ("down_the_line", "inside_in")}.get(self.option, (self.option,))
        return np.isin(got, want)


def _handedness(name: str) -> str:
    from sportsngen.synth.profiles import named_profiles

    prof = named_profiles().get(name)
    return prof.handedness if prof is not None else "right"


def counterfactual(sim, data: RallyData, rally_id: int, shot_index: int,
                   options=("cross_court", "down_the_line"), n: int = 100,
                   seed: int = 0, return_branches: bool = False):
    """The hitter's point-win probability if shot `shot_index` of the rally went each way.

    `options`: direction names ("cross_court", "down_the_line", "middle", "inside_out",
    "inside_in"; for a serve "wide", "body", "T") or target boxes (x_min, x_max, y_min, y_max)
    in metres where the shot must land. -> DataFrame with columns option, win_probability,
    ci_low, ci_high, n (realistic decided branches), n_sims, n_unrealistic, n_forced_failed
    (branches whose shot could not be made to go that way in `MAX_TRIES` draws, or whose ball
    never left the hitter within `LEAVE_WINDOW_FRAMES`: those go unconstrained)."""
    n = check_int("n", n, 1, MAX_BRANCHES)
    seed = check_int("seed", seed, 0)
    row, pos, first = _rally(data, rally_id)
    shots = data.shots[data.shots["rally_id"] == int(rally_id)].sort_values("shot_index")
    shot_index = check_int("shot_index", shot_index)
    if not 0 <= shot_index < len(shots):
        raise ArgumentError(f"rally {rally_id} has {len(shots)} shots; no shot {shot_index}")
    shot = shots.iloc[shot_index]
    options = _check_options(options, str(shot["stroke"]) == "serve")
    k = int(shot["frame"]) - first - 1            # the last frame before the contact
    if k < 1:
        raise ArgumentError("the shot is struck too early in the track to branch before it")
    hitter = 0 if shot["hitter"] == row["server"] else 1
    hitter_end = int(row["server_end"]) * (1 if hitter == 0 else -1)
    init = np.repeat(pos[None, :k + 1], n, axis=0)
    serve = str(shot["stroke"]) == "serve"
    by_head = (sim.model.serve_head if serve else sim.model.strike_head) is not None
    rows, branches = [], {}
    for j, opt in enumerate(options):
        con = ShotConstraint(opt, hitter, hitter_end, _handedness(str(shot["hitter"])),
                             str(shot["stroke"]), str(row["side"]), k + 1, fps=sim.fps,
                             by_head=by_head)
        out = sim.simulate_rallies(_plan(row, n), seed=seed + 7919 * j, init_pos_m=init,
                                   constraint=con)
        plan = _plan(row, n)
        res = _summary(_branch_outcomes(sim, plan, out, seed + 7919 * j))
        p = res["p"] if hitter == 0 else 1.0 - res["p"]
        wins = int(round(p * res["n"])) if res["n"] else 0
        lo, hi = wilson_interval(wins, res["n"])
        rows.append({"option": opt if isinstance(opt, str) else str(opt), "win_probability": p,
                     "ci_low": lo, "ci_high": hi, "n": res["n"], "n_sims": res["n_sims"],
                     "n_unrealistic": res["n_unrealistic"],
                     "n_forced_failed": len(con.failed) + n - len(con.done)})
        branches[rows[-1]["option"]] = out
    table = pd.DataFrame(rows)
    return (table, branches) if return_branches else table


def _check_options(options, serve: bool) -> list:
    """Counterfactual options: direction names valid for the stroke, or target boxes."""
    names = SERVE_OPTIONS if serve else SHOT_OPTIONS
    valid = f"direction names {list(names)} or (x_min, x_max, y_min, y_max) boxes in metres"
    if isinstance(options, str) or not hasattr(options, "__iter__"):
        raise ArgumentError(f"options must be a list of {valid}, got {options!r}"
                            + (f" (did you mean [{options!r}]?)" if isinstance(options, str)
                               else ""))
    out = []
    for opt in options:
        if isinstance(opt, str):
            if opt not in names:
                kind = "a serve" if serve else "a shot"
                extra = " (a serve direction)" if opt in SERVE_OPTIONS else \
                    " (not a serve direction)" if opt in DIRECTIONS else ""
                raise ArgumentError(f"option {opt!r}{extra} is not a direction of {kind}; "
                                    f"options must be {valid}")
            out.append(opt)
            continue
        try:
            box = tuple(float(v) for v in opt)
        except (TypeError, ValueError):
            box = ()
        if len(box) != 4 or not all(math.isfinite(v) for v in box) or box[0] >= box[1] \
                or box[2] >= box[3]:
            raise ArgumentError(f"option {opt!r} is neither a direction name nor a box "
                                f"(x_min < x_max, y_min < y_max); options must be {valid}")
        out.append(box)
    if not out:
        raise ArgumentError(f"options is empty; give {valid}")
    return out


def match_win_probability(sim, player1: str, player2: str, surface: str,
                          state: MatchState | None = None, fmt: MatchFormat | None = None,
                          n_points: int = 200, seed: int = 0) -> dict:
    """P(player1 wins the match) from `state` (default: the start, player1 serving): each
    player's point-win rate on serve from `n_points` simulated service points against the
    other (realistic points only), then the exact Markov chain of the scoring."""
    check_players(player1, player2, ("player1", "player2"))
    if fmt is not None and not isinstance(fmt, MatchFormat):
        raise ArgumentError(f"fmt must be a MatchFormat (or None), got {fmt!r}")
    rates = []
    for k, (a, b) in enumerate(((player1, player2), (player2, player1))):
        pts = realistic_points(sim.simulate_points(a, b, surface, n_points, seed=seed + k))
        table = pts.points()
        if not len(table):
            raise ValueError(f"no realistic simulated service point of {a}")
        rates.append(float((table["winner"] == a).mean()))
    fmt = fmt or (state.fmt if state is not None else MatchFormat())
    p = markov_match_win(rates[0], rates[1], fmt, state)
    return {"p_match": p, "p_serve_player1": rates[0], "p_serve_player2": rates[1]}
