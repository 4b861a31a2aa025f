"""A receiver's reach for the return, drawn per serve from his own record.

The rollouts' rules decide whether a good serve is returned by how near it passes the receiver:
within the return's reach it is struck (`constraints.StrikeInReach`), beyond it no contact is
allowed (`constraints.PhysicalLimits`). With one reach for every receiver and serve (1.5 m),
every serve passing within 1.5 m of him was returned and none beyond, where the generator's
receivers return all the serves passing within 1.3 m, then fewer and fewer to none beyond 1.7 m
(a serve within reach can still pass a receiver who cannot reach it in time), and where that
fall lies is the receiver's own (half returned at 1.48 m for Nadal, 1.62 m for Isner, over
0.02-0.04 m; docs/evaluation.md, fifty-third part). Read on the bundled file's own serves, the
receivers' odds put the servers' aces 0.2-1.9 points above what the hard edge gave.

`ReturnReach` holds, per receiver, where his share of good serves returned falls through one
half (`centre_m`) and how fast (`scale_m`): a logistic in the distance the serve passes from
him (`sportsngen.eval.reach.reach_rows`' `gap_m`), fitted by maximum likelihood
(`fit_logistic`). A rollout draws each serve's reach from it (`draw`: centre + scale x a
standard logistic draw), so that a serve passing `gap` from him is returned with his record's
odds. A receiver without a row (a player the table was not fitted on) plays the pooled row.
Pure numpy and scipy: no model is involved.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import minimize

# The reaches a draw may give (m): inside the truth's nearest unreturned serves and beyond the
# farthest returned one (the generator's bodies reach 1.7-1.95 m plus a 0.15 m run).
MIN_REACH_M = 1.0
MAX_REACH_M = 2.2
MIN_SERVES = 200          # a receiver's good serves for his own row (fewer: the pooled one)
MIN_SCALE_M = 0.005


@dataclass
class ReturnReach:
    """Per receiver (centre_m, scale_m) of his odds of returning a good serve by the distance
    it passes from him; `pooled` for receivers without a row."""

    pooled: tuple[float, float]
    players: dict[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for who, (c, s) in [("pooled", self.pooled), *self.players.items()]:
            if not (np.isfinite(c) and np.isfinite(s) and c > 0 and s > 0):
                raise ValueError(f"return reach of {who}: centre and scale must be positive, "
                                 f"got ({c}, {s})")

    def centre_scale(self, receivers) -> tuple[np.ndarray, np.ndarray]:
        """(N,) centres and scales (m) of these receivers' names."""
        rows = [self.players.get(str(r), self.pooled) for r in receivers]
        cs = np.asarray(rows, dtype=float).reshape(-1, 2)
        return cs[:, 0], cs[:, 1]

    def returned_odds(self, receivers, gap_m) -> np.ndarray:
        """(N,) the odds that a good serve passing `gap_m` from each receiver is returned."""
        c, s = self.centre_scale(receivers)
        return 1.0 / (1.0 + np.exp((np.asarray(gap_m, dtype=float) - c) / s))

    def draw(self, receivers, rng: np.random.Generator) -> np.ndarray:
        """(N,) one reach (m) a serve for each receiver: a serve passing nearer is returned."""
        c, s = self.centre_scale(receivers)
        u = rng.uniform(1e-9, 1.0 - 1e-9, size=len(c))
        return np.clip(c + s * np.log(u / (1.0 - u)), MIN_REACH_M, MAX_REACH_M)

    def to_dict(self) -> dict:
        return {"pooled": [float(v) for v in self.pooled],
                "players": {k: [float(v) for v in cs] for k, cs in self.players.items()}}

    @staticmethod
    def from_dict(d: dict) -> ReturnReach:
        return ReturnReach(tuple(d["pooled"]), {k: tuple(v) for k, v in d["players"].items()})


def fit_logistic(gap_m: np.ndarray, returned: np.ndarray) -> tuple[float, float]:
    """Maximum-likelihood (centre_m, scale_m) of P(returned) = 1 / (1 + exp((gap - centre) /
    scale)) over good serves passing `gap_m` from the receiver."""
    gap = np.asarray(gap_m, dtype=float)
    y = np.asarray(returned, dtype=bool)
    if len(gap) != len(y) or len(gap) == 0:
        raise ValueError(f"need as many returned flags as gaps, and some: {len(gap)}, {len(y)}")
    if y.all() or not y.any():
        raise ValueError("every serve returned or none: the fall of the odds cannot be read")

    def nll(theta):
        c, log_s = theta
        z = (gap - c) / np.exp(log_s)
        # -log sigmoid(-z) for returned, -log sigmoid(z) otherwise
        return float(np.sum(np.logaddexp(0.0, np.where(y, z, -z))))

    start = np.array([float(np.median(gap[~y])), np.log(0.1)])
    res = minimize(nll, start, method="Nelder-Mead",
                   options={"xatol": 1e-5, "fatol": 1e-7, "maxiter": 2000})
    c, log_s = res.x
    return float(c), float(max(np.exp(log_s), MIN_SCALE_M))


def serve_rows(rows: pd.DataFrame, rallies: pd.DataFrame) -> pd.DataFrame:
    """The good serves of `reach_rows` (shot 0) with their server's and receiver's names (from
    `rallies`, indexed by rally_id) -> columns server, receiver, gap_m, answered."""
    s = rows[rows["shot"] == 0]
    r = rallies.set_index("rally_id") if "rally_id" in rallies.columns else rallies
    return pd.DataFrame({"server": r.loc[s["rally_id"], "server"].astype(str).to_numpy(),
                         "receiver": r.loc[s["rally_id"], "receiver"].astype(str).to_numpy(),
                         "gap_m": s["gap_m"].to_numpy(float),
                         "answered": s["answered"].to_numpy(bool)})


def fit_return_reach(serves: pd.DataFrame, min_serves: int = MIN_SERVES) -> ReturnReach:
    """A `ReturnReach` from good serves (`serve_rows`' columns): each receiver with at least
    `min_serves` his own row, the pooled row from all of them."""
    if not {"receiver", "gap_m", "answered"} <= set(serves.columns):
        raise ValueError("serves needs columns receiver, gap_m, answered")
    pooled = fit_logistic(serves["gap_m"], serves["answered"])
    players = {}
    for name, g in serves.groupby("receiver"):
        if len(g) >= min_serves and g["answered"].any() and not g["answered"].all():
            players[str(name)] = fit_logistic(g["gap_m"], g["answered"])
    return ReturnReach(pooled, players)


def return_reach_from_data(parts: list, min_serves: int = MIN_SERVES,
                           progress: bool = True) -> tuple[ReturnReach, pd.DataFrame]:
    """Fit a `ReturnReach` on the good serves of recorded rallies (`RallyData` parts: a model
    file's training split and more of its players' play) -> (table, the serves read)."""
    from tqdm.auto import tqdm

    from sportsngen.eval.reach import reach_rows

    if not parts:
        raise ValueError("no rallies to read the serves from")
    serves = pd.concat([serve_rows(reach_rows(d), d.rallies)
                        for d in tqdm(parts, desc="serves", disable=not progress)],
                       ignore_index=True)
    return fit_return_reach(serves, min_serves=min_serves), serves
