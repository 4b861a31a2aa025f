"""A player's reach for a contact, drawn per ball from his own record: the return's and the
rally balls'.

The rollouts' rules decide whether a good ball is answered by how near it passes the player due
to play it: within his reach it is struck (`constraints.StrikeInReach`), beyond it no contact
is allowed (`constraints.PhysicalLimits`). With one reach for every receiver and serve (1.5 m),
every serve passing within 1.5 m of him was returned and none beyond, where the generator's
receivers return all the serves passing within 1.3 m, then fewer and fewer to none beyond 1.7 m
(a serve within reach can still pass a receiver who cannot reach it in time), and where that
fall lies is the receiver's own (half returned at 1.48 m for Nadal, 1.62 m for Isner, over
0.02-0.04 m; docs/evaluation.md, fifty-third part). Read on the bundled file's own serves, the
receivers' odds put the servers' aces 0.2-1.9 points above what the hard edge gave. The rally
balls (every contact after the return) had the same hard edges, forced within 1.5 m and barred
beyond 1.8 m: the rollouts' players answered 0.99 of the good rally balls passing 1.2-1.5 m
from them and none beyond 1.8 m, where the generator's answer 0.92-0.97 and 0.17-0.49, its
women (reach 1.70-1.75 m, slower) fewer than its men (fifty-fourth part).

`ReachTable` holds, per player, where his share of good balls answered falls through one half
(`centre_m`) and how fast (`scale_m`): a logistic in the distance the ball passes from him
(`sportsngen.eval.reach.reach_rows`' `gap_m`), fitted by maximum likelihood (`fit_logistic`).
A rollout draws each ball's reach from it (`draw`: centre + scale x a standard logistic draw),
so that a ball passing `gap` from him is answered with his record's odds. A player without a
row (one the table was not fitted on) plays the pooled row. One table for the returns (by the
receiver, `serve_rows`) and one for the rally balls (by the player due, `rally_rows`). Pure
numpy and scipy: no model is involved.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

# The reaches a draw may give (m): inside the truth's nearest unanswered balls and beyond the
# farthest answered one (the generator's bodies reach 1.7-1.95 m plus a 0.15 m run).
MIN_REACH_M = 1.0
MAX_REACH_M = 2.2
MIN_BALLS = 200           # a player's good balls for his own row (fewer: the pooled one)
MIN_SCALE_M = 0.005


@dataclass
class ReachTable:
    """Per player (centre_m, scale_m) of his odds of answering a good ball (a serve, or a rally
    ball) by the distance it passes from him; `pooled` for players without a row."""

    pooled: tuple[float, float]
    players: dict[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for who, (c, s) in [("pooled", self.pooled), *self.players.items()]:
            if not (np.isfinite(c) and np.isfinite(s) and c > 0 and s > 0):
                raise ValueError(f"reach of {who}: centre and scale must be positive, "
                                 f"got ({c}, {s})")

    def centre_scale(self, players) -> tuple[np.ndarray, np.ndarray]:
        """(N,) centres and scales (m) of these players' names."""
        rows = [self.players.get(str(r), self.pooled) for r in np.ravel(players)]
        cs = np.asarray(rows, dtype=float).reshape(-1, 2)
        return cs[:, 0], cs[:, 1]

    def answered_odds(self, players, gap_m) -> np.ndarray:
        """(N,) the odds that a good ball passing `gap_m` from each player is answered."""
        c, s = self.centre_scale(players)
        return 1.0 / (1.0 + np.exp((np.asarray(gap_m, dtype=float) - c) / s))

    def draw(self, players, rng: np.random.Generator) -> np.ndarray:
        """One reach (m) a ball for each player named in `players` (any shape, the result's):
        a ball passing nearer is answered."""
        shape = np.shape(players)
        c, s = self.centre_scale(players)
        u = rng.uniform(1e-9, 1.0 - 1e-9, size=len(c))
        return np.clip(c + s * np.log(u / (1.0 - u)), MIN_REACH_M, MAX_REACH_M).reshape(shape)

    def to_dict(self) -> dict:
        return {"pooled": [float(v) for v in self.pooled],
                "players": {k: [float(v) for v in cs] for k, cs in self.players.items()}}

    @staticmethod
    def from_dict(d: dict) -> ReachTable:
        return ReachTable(tuple(d["pooled"]), {k: tuple(v) for k, v in d["players"].items()})


def fit_logistic(gap_m: np.ndarray, answered: np.ndarray) -> tuple[float, float]:
    """Maximum-likelihood (centre_m, scale_m) of P(answered) = 1 / (1 + exp((gap - centre) /
    scale)) over good balls passing `gap_m` from the player due."""
    gap = np.asarray(gap_m, dtype=float)
    y = np.asarray(answered, dtype=bool)
    if len(gap) != len(y) or len(gap) == 0:
        raise ValueError(f"need as many answered flags as gaps, and some: {len(gap)}, {len(y)}")
    if y.all() or not y.any():
        raise ValueError("every ball answered or none: the fall of the odds cannot be read")

    def nll(theta):
        c, log_s = theta
        z = (gap - c) / np.exp(log_s)
        # -log sigmoid(-z) for answered, -log sigmoid(z) otherwise
        return float(np.sum(np.logaddexp(0.0, np.where(y, z, -z))))

    # Imported here: scipy.optimize is 0.5 s of every simulator process's start-up, and
    # only a table's fit needs it.
    from scipy.optimize import minimize

    start = np.array([float(np.median(gap[~y])), np.log(0.1)])
    res = minimize(nll, start, method="Nelder-Mead",
                   options={"xatol": 1e-5, "fatol": 1e-7, "maxiter": 2000})
    c, log_s = res.x
    return float(c), float(max(np.exp(log_s), MIN_SCALE_M))


def _named(r: pd.DataFrame, s: pd.DataFrame, player: np.ndarray) -> pd.DataFrame:
    return pd.DataFrame({"server": r.loc[s["rally_id"], "server"].astype(str).to_numpy(),
                         "receiver": r.loc[s["rally_id"], "receiver"].astype(str).to_numpy(),
                         "player": player, "shot": s["shot"].to_numpy(int),
                         "gap_m": s["gap_m"].to_numpy(float),
                         "answered": s["answered"].to_numpy(bool)})


def _by_rally(rallies: pd.DataFrame) -> pd.DataFrame:
    return rallies.set_index("rally_id") if "rally_id" in rallies.columns else rallies


def serve_rows(rows: pd.DataFrame, rallies: pd.DataFrame) -> pd.DataFrame:
    """The good serves of `reach_rows` (shot 0) with their server's and receiver's names (from
    `rallies`, indexed by rally_id) -> columns server, receiver, player (the receiver, due to
    answer), shot, gap_m, answered."""
    s = rows[rows["shot"] == 0]
    r = _by_rally(rallies)
    return _named(r, s, r.loc[s["rally_id"], "receiver"].astype(str).to_numpy())


def rally_rows(rows: pd.DataFrame, rallies: pd.DataFrame) -> pd.DataFrame:
    """The good rally balls of `reach_rows` (shot >= 1), as `serve_rows` with the player due
    to answer each (`reach_rows`' role) in `player`."""
    s = rows[rows["shot"] >= 1]
    r = _by_rally(rallies)
    who = np.where(s["role"].to_numpy() == "server", r.loc[s["rally_id"], "server"].to_numpy(),
                   r.loc[s["rally_id"], "receiver"].to_numpy()).astype(str)
    return _named(r, s, who)


BALLS = {"serve": serve_rows, "rally": rally_rows}


def fit_reach_table(balls: pd.DataFrame, min_balls: int = MIN_BALLS) -> ReachTable:
    """A `ReachTable` from good balls (`serve_rows` or `rally_rows`' columns): each player due
    with at least `min_balls` his own row, the pooled row from all of them."""
    if not {"player", "gap_m", "answered"} <= set(balls.columns):
        raise ValueError("balls needs columns player, gap_m, answered")
    pooled = fit_logistic(balls["gap_m"], balls["answered"])
    players = {}
    for name, g in balls.groupby("player"):
        if len(g) >= min_balls and g["answered"].any() and not g["answered"].all():
            players[str(name)] = fit_logistic(g["gap_m"], g["answered"])
    return ReachTable(pooled, players)


def reach_table_from_data(parts: list, shots: str = "serve", min_balls: int = MIN_BALLS,
                          progress: bool = True) -> tuple[ReachTable, pd.DataFrame]:
    """Fit a `ReachTable` on the good serves (`shots="serve"`: the return's reach) or rally
    balls (`"rally"`) of recorded rallies (`RallyData` parts: a model file's training split and
    more of its players' play) -> (table, the balls read)."""
    from tqdm.auto import tqdm

    from sportsngen.eval.reach import reach_rows

    if shots not in BALLS:
        raise ValueError(f"shots must be one of {sorted(BALLS)}, got {shots!r}")
    if not parts:
        raise ValueError("no rallies to read the balls from")
    balls = pd.concat([BALLS[shots](reach_rows(d), d.rallies)
                       for d in tqdm(parts, desc=f"{shots} balls", disable=not progress)],
                      ignore_index=True)
    return fit_reach_table(balls, min_balls=min_balls), balls
