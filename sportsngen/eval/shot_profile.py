"""Whole points shot by shot: how each shot after the serve is struck and how it ends.

The strikes table (`shot_branches.strike_shares`) strikes each recorded approach once, so it
shows the model's strike given the record's state. Whole simulated points add the drift of a
rally: a player a little out of place at the fourth shot strikes from there. `shot_profile`
reads any points (simulated or recorded) the same way, so the two compare row by row: per
shot, the share in play of those struck and answered of those in play (`shot_outcomes`), and
what its strikes look like (the medians of `sportsngen.model.strike`'s description of each
rally strike: depth beyond the net, distance from the centre line, height over the net,
speed just after the racket; and how far behind his baseline its hitter stood).

`unanswered_by_flight` splits the balls in play left unanswered by their flight: a slow ball
(first bounce 1.32 s or more after its contact: a lob or a high ball) on clay was left
unanswered ten times as often by the model's players as by the truth's (0.156 against 0.016),
most of the clay rallies' lost shots (docs/evaluation.md, thirty-ninth part); a low-noise signal
of where rallies end.

`strike_endings` reads the shots table alone (no rules pass, so it is quick on large truths):
per hitter, his role in the point and the stage of the rally, the share of his strikes that
ended the point as his error or his winner. Both players' ends count: Djokovic's clay serve
points won over his truth's came with Murray's late rally balls erring 0.04 more often than the
truth's, in both roles (docs/evaluation.md, forty-seventh part).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_branches import shot_outcomes
from sportsngen.model import strike
from sportsngen.tennis.court import BASELINE_X_M

PROFILE_COLUMNS = ("n", "in_play", "answered", "depth_m", "side_m", "net_height_m",
                   "speed_mps", "hitter_behind_m")
SLOW_FLIGHT_S = 1.32       # a first bounce this long after the contact: a slow ball
# The stages of `strike_endings` by their first shot index (1 = the return), each running to
# the next's start: the return, the next three strikes, the rest; a rally's early balls answer
# the serve's and the return's pace.
STRIKE_STAGES = (("return", 1), ("shots 2-4", 2), ("shots 5+", 5))


def first_strike(ball_m: np.ndarray, from_frame: int, fps: float,
                 last_frame: int | None = None) -> tuple[int, np.ndarray] | None:
    """(T, 3) a ball's track -> (frame t, the `strike.strike_labels` of its frames t + 2 ..
    t + 4) of the first rally strike at a frame t from `from_frame` (to `last_frame`) whose
    frames are there to read, or None. The strike is looked for between a frame's incoming
    step and the step after the next one: a contact in the middle of a step mixes the ball's
    way in and out, and that step alone may not show a strike."""
    b = np.asarray(ball_m, dtype=float)
    lo = max(int(from_frame), 1)
    hi = len(b) - 5 if last_frame is None else min(int(last_frame), len(b) - 5)
    if hi < lo:
        return None
    t = np.arange(lo, hi + 1)
    hit = strike.is_strike(b[t], (b[t] - b[t - 1]) * fps, b[t] + (b[t + 2] - b[t + 1]), fps)
    if not hit.any():
        return None
    k = int(t[np.argmax(hit)])
    return k, strike.strike_labels(b[None, k + 2:k + 5], np.sign(b[k:k + 1, 0]), fps)[0]


def hitter_behind_m(players_x_m: np.ndarray, ball_x_m: float) -> float:
    """How far behind his baseline the player on the ball's half stands (m; NaN: nobody)."""
    side = np.sign(ball_x_m)
    xs = np.asarray(players_x_m, dtype=float)
    mine = xs[np.sign(xs) == side]
    return float(side * mine[0] - BASELINE_X_M) if len(mine) else np.nan


def _strike_rows(data: RallyData, rules: pd.DataFrame, max_shot: int) -> pd.DataFrame:
    """One row per rally strike up to shot `max_shot` whose frames exist (`first_strike`
    within two frames before and one after the rules' contact, which they put on the nearer
    frame of its step): its shot, its `strike.strike_labels`, its speed, and how far behind his
    baseline the hitter stood."""
    f = data.frames.sort_values(["rally_id", "frame"])
    is_ball = (f["object"] == "ball").to_numpy()
    balls = dict(tuple(f[is_ball].groupby("rally_id", sort=False)))
    players = dict(tuple(f[~is_ball].groupby("rally_id", sort=False)))
    rows = []
    for rid, g in balls.items():
        if rid not in rules.index or rid not in players:
            continue
        b = g[["x", "y", "z"]].to_numpy(float)
        first = int(g["frame"].iloc[0])
        pl = players[rid]
        for shot, t in enumerate(rules.loc[rid, "contact_frames"]):
            if shot == 0:
                continue          # the serve, struck from a toss
            if shot > max_shot:
                break
            got = first_strike(b, t - 2, data.fps, last_frame=t + 1)
            if got is None:
                continue
            k, lab = got
            behind = hitter_behind_m(pl.loc[pl["frame"] == first + k, "x"].to_numpy(float),
                                     b[k, 0])
            rows.append((shot, *lab[:3], float(np.linalg.norm(b[k + 3] - b[k + 2]) * data.fps),
                         behind))
    if not rows:
        return pd.DataFrame(columns=["shot", *PROFILE_COLUMNS[3:]])
    shot, depth, lateral, net, speed, behind = (np.array(c) for c in zip(*rows))
    return pd.DataFrame({"shot": shot, "depth_m": depth, "side_m": np.abs(lateral),
                         "net_height_m": net, "speed_mps": speed, "hitter_behind_m": behind})


def shot_profile(data: RallyData, max_shot: int = 6,
                 rules: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per shot after the serve (1 the return) up to `max_shot`, indexed by shot: `n`
    rallies that struck it, `in_play` of those, `answered` of those in play, and the medians of
    its strikes' `depth_m`, `side_m`, `net_height_m`, `speed_mps` and `hitter_behind_m` (how
    far behind his baseline the hitter stood)."""
    if max_shot < 1:
        raise ValueError(f"max_shot counts shots after the serve (>= 1), got {max_shot}")
    rules = analyse_rally_data(data) if rules is None else rules
    strikes = _strike_rows(data, rules, max_shot)
    out = []
    for shot in range(1, max_shot + 1):
        o = shot_outcomes(data, shot, rules)
        o = o[o["struck"]]
        live = o["in_play"].astype(bool)
        s = strikes[strikes["shot"] == shot]
        out.append({"shot": shot, "n": len(o),
                    "in_play": float(live.mean()) if len(o) else np.nan,
                    "answered": float(o.loc[live, "answered"].mean()) if live.any() else np.nan,
                    **{c: float(s[c].median()) if len(s) else np.nan
                       for c in PROFILE_COLUMNS[3:]}})
    return pd.DataFrame(out).set_index("shot")[list(PROFILE_COLUMNS)]


def unanswered_by_flight(data: RallyData, rules: pd.DataFrame | None = None,
                         slow_s: float = SLOW_FLIGHT_S, max_shot: int = 60) -> pd.DataFrame:
    """Every ball in play after the serve (shots 1 .. `max_shot`; `shot_outcomes`), split by
    its flight: "slow" where its first bounce came `slow_s` or more after its contact, "other"
    (volleys included) else, and "all". -> indexed by that: `n` balls, `share` of all, the
    share `unanswered` and its binomial standard error `se`."""
    if slow_s <= 0:
        raise ValueError(f"slow_s must be > 0, got {slow_s}")
    rules = analyse_rally_data(data) if rules is None else rules
    slow_frames = slow_s * data.fps
    slow, missed = [], []
    for shot in range(1, max_shot + 1):
        o = shot_outcomes(data, shot, rules)
        if not len(o) or not o["struck"].any():
            break
        o = o[o["in_play"]]
        for rid, c in zip(o.index, o["contact_frame"]):
            after = [b for b in rules.at[rid, "bounce_frames"] if b > c]
            slow.append(bool(after) and after[0] - c >= slow_frames)
        missed.extend(~o["answered"].to_numpy(bool))
    slow, missed = np.asarray(slow, dtype=bool), np.asarray(missed, dtype=bool)
    rows = []
    for name, keep in (("all", np.ones_like(slow)), ("slow", slow), ("other", ~slow)):
        n = int(keep.sum())
        p = float(missed[keep].mean()) if n else np.nan
        rows.append({"flight": name, "n": n, "share": n / max(len(slow), 1), "unanswered": p,
                     "se": float(np.sqrt(p * (1 - p) / n)) if n else np.nan})
    return pd.DataFrame(rows).set_index("flight")


def format_unanswered(sim: pd.DataFrame, truth: pd.DataFrame) -> str:
    """Two `unanswered_by_flight` tables side by side, "sim / truth" in every cell."""
    rows = [("flight", "n", "share", "unanswered")]
    for name in sim.index:
        a, b = sim.loc[name], truth.loc[name]
        rows.append((name, f"{a['n']:.0f} / {b['n']:.0f}",
                     f"{a['share']:.3f} / {b['share']:.3f}",
                     f"{a['unanswered']:.3f}±{a['se']:.3f} / "
                     f"{b['unanswered']:.3f}±{b['se']:.3f}"))
    return "\n".join(f"{r[0]:>6} {r[1]:>13} {r[2]:>15} {r[3]:>27}" for r in rows)


def format_profiles(sim: pd.DataFrame, truth: pd.DataFrame) -> str:
    """Two `shot_profile` tables side by side, "sim / truth" in every cell."""
    fmt = {"n": "{:.0f}", "in_play": "{:.2f}", "answered": "{:.2f}", "depth_m": "{:.1f}",
           "side_m": "{:.2f}", "net_height_m": "{:.2f}", "speed_mps": "{:.1f}",
           "hitter_behind_m": "{:.2f}"}
    cols = list(PROFILE_COLUMNS)
    lines = ["shot " + " ".join(f"{c:>13}" for c in cols)]
    for shot in sim.index.union(truth.index):
        cells = []
        for c in cols:
            a = sim[c].get(shot, np.nan)
            b = truth[c].get(shot, np.nan)
            cells.append(f"{fmt[c].format(a)} / {fmt[c].format(b)}")
        lines.append(f"{shot:>4} " + " ".join(f"{x:>13}" for x in cells))
    return "\n".join(lines)


def strike_endings(data: RallyData, realistic_only: bool = True,
                   by_serve: bool = False) -> pd.DataFrame:
    """Every strike after the serve from `data`'s shots table, by hitter, his role in the point
    ("server" or "receiver") and stage (`STRIKE_STAGES`). -> indexed by those three: `n`
    strikes, the shares that were his `error` and his `winner`, each with its binomial standard
    error (`error_se`, `winner_se`). `realistic_only` leaves out rallies flagged non-realistic
    (simulated data; recorded data has no flag and keeps every rally). `by_serve` splits each
    row by the point's serve (`serve_number`, a level between role and stage): the generator's
    server carries a first or a second serve's initiative through the whole rally, and the
    bundled file's receivers erred 0.04-0.05 too often in second-serve rallies only
    (docs/evaluation.md, seventy-fourth part)."""
    rallies = data.rallies
    if realistic_only and "realistic" in rallies:
        rallies = rallies[rallies["realistic"].astype(bool)]
    cols = ["rally_id", "server"] + (["serve_number"] if by_serve else [])
    shots = data.shots.merge(rallies[cols], on="rally_id")
    shots = shots[shots["shot_index"] >= 1]
    role = np.where(shots["hitter"] == shots["server"], "server", "receiver")
    # Stages as an ordered categorical, so the groups come out in rally order.
    names, starts = zip(*STRIKE_STAGES)
    stage = pd.Categorical.from_codes(
        np.searchsorted(starts, shots["shot_index"].to_numpy(), side="right") - 1,
        categories=list(names), ordered=True)
    frame = pd.DataFrame({"hitter": shots["hitter"].to_numpy(), "role": role, "stage": stage,
                          "error": (shots["outcome"] == "error").to_numpy(),
                          "winner": (shots["outcome"] == "winner").to_numpy()})
    keys = ["hitter", "role", "stage"]
    if by_serve:
        frame.insert(2, "serve_number", shots["serve_number"].to_numpy())
        keys.insert(2, "serve_number")
    out = frame.groupby(keys, observed=True).agg(
        n=("error", "size"), error=("error", "mean"), winner=("winner", "mean"))
    for c in ("error", "winner"):
        out[f"{c}_se"] = np.sqrt(out[c] * (1 - out[c]) / out["n"])
    return out


def format_strike_endings(sim: pd.DataFrame, truth: pd.DataFrame) -> str:
    """Two `strike_endings` tables side by side ("sim / truth"), with each share's gap in
    standard errors of both sides (z) where both have strikes (split by serve: a serve
    column)."""
    serve = "serve_number" in sim.index.names
    lines = [f"{'hitter':<17} {'role':<9} " + ("serve " if serve else "")
             + f"{'stage':<10} {'n':>13} {'error':>13} {'z':>5} {'winner':>13} {'z':>5}"]
    for key in sim.index.union(truth.index, sort=False):
        a = sim.loc[key] if key in sim.index else None
        b = truth.loc[key] if key in truth.index else None
        cells = [f"{a['n'] if a is not None else 0:.0f} / {b['n'] if b is not None else 0:.0f}"]
        for c in ("error", "winner"):
            va = a[c] if a is not None else np.nan
            vb = b[c] if b is not None else np.nan
            se = np.hypot(a[f"{c}_se"], b[f"{c}_se"]) if a is not None and b is not None \
                else np.nan
            z = (va - vb) / se if se and np.isfinite(se) and se > 0 else np.nan
            cells += [f"{va:.3f} / {vb:.3f}", f"{z:+.1f}"]
        head = f"{key[0]:<17} {key[1]:<9} " + (f"{key[2]:<5} " if serve else "")
        lines.append(f"{head}{key[-1]:<10} {cells[0]:>13} {cells[1]:>13} "
                     f"{cells[2]:>5} {cells[3]:>13} {cells[4]:>5}")
    return "\n".join(lines)
