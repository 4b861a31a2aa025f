"""Path-matched leak check for faults: is a player's movement after a serve explained by the
ball's path and where he stood, or does it also tell whether the serve will be a fault?

The stratified check (`sportsngen.eval.leaks`) compares contacts that looked alike to the
players. For fault against in that has a blind spot: a fault lies beyond a line by definition,
so a stratum that straddles the line pairs faults with ins that came elsewhere, and a receiver
whose run varies smoothly with where the serve comes (a long serve comes on to him) reads as
one who knows. Here each serve's feature (a role's speed or acceleration k frames on, from
`contact_kinematics`) is predicted from the `n_neighbours` nearest serves of the negative class
(in) of the same server, receiver and serve number, nearest in the ball's path (its
bounce point, the serve's contact y and speed) and the role's position at the contact (a
negative serve is not its own neighbour). The AUC compares the positives' residuals with the
negatives'. Movement that depends on the path and the position only gives 0.5 whatever the
geometry; a player who
stops before faults (generator version 5) stays far from it, since no in-serve on the same path
shows him stopping.

Only fault against in: its label is a line on the path, which neighbours on the path straddle.
Ace against returned is a matter of reach, a sharp function of path and position (on 10,000
generated points the receiver is at full acceleration 12 frames after all 929 aces, he sprints
at any serve he can barely reach, and after 81 % of the returned serves), so the mean of ten
neighbours does not predict it (residual AUC 0.34 where the stratified check reads 0.52); the
stratified check, which compares him with receivers on the same seen flight at the same speed,
is the tool there.
For the server's own cells of ace against returned, `pairs` can ask for them: his run back
after the serve does not turn on reach (on the bundled model's own serves his speed 12 frames
on reads 0.449 [0.384, 0.511] here, where the stratified check, then blind to his serve's
speed, read 0.31-0.40; docs/evaluation.md, sixty-fifth part; it holds the seen pace since).

The bounce point is a fact of the ball's path, which the player watches from the launch, not
of the outcome label; what this check cannot see is a leak that acts through the path itself.
Coordinates are turned so that every server stands at +x. A serve without a bounce (into the
net) or without a feature at k is left out. Intervals: `level` percentiles of `n_boot`
resamples of the serves (one serve a rally), with the predictions held fixed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from sportsngen.data.tracking import RallyData
from sportsngen.eval.leaks import (
    DEFAULT_KS,
    FEATURES,
    PAIRS,
    ROLES,
    contact_kinematics,
    weighted_auc,
)

PATH_PAIRS = ("fault_vs_in",)
# Covariate -> the distance that counts as one unit when looking for neighbours.
PATH_SCALES = {"bounce_x": 0.5, "bounce_y": 0.5, "contact_y": 0.5, "speed_mps": 2.0}
POSITION_SCALE_M = 0.5


def serve_paths(data: RallyData, kin: pd.DataFrame) -> pd.DataFrame:
    """The serve rows of a `contact_kinematics` table with the path covariates: bounce_x,
    bounce_y, contact_y, speed_mps and each role's x / y at the contact (``hitter_x`` ...),
    turned so that the server stands at +x."""
    serves = kin[kin["shot_index"] == 0]
    shots = data.shots.set_index(["rally_id", "shot_index"])
    key = pd.MultiIndex.from_arrays([serves["rally_id"], serves["shot_index"]])
    shot = shots.loc[key, ["contact_x", "contact_y", "speed_mps", "bounce_x", "bounce_y"]]
    turn = np.where(shot["contact_x"].to_numpy(dtype=float) >= 0, 1.0, -1.0)
    out = serves.assign(bounce_x=shot["bounce_x"].to_numpy(dtype=float) * turn,
                        bounce_y=shot["bounce_y"].to_numpy(dtype=float) * turn,
                        contact_y=shot["contact_y"].to_numpy(dtype=float) * turn,
                        speed_mps=shot["speed_mps"].to_numpy(dtype=float))
    players = data.frames[data.frames["object"] != "ball"].set_index(
        ["rally_id", "frame", "object"])[["x", "y"]]
    for role in ROLES:
        at = pd.MultiIndex.from_arrays([serves["rally_id"], serves["frame"], serves[role]])
        xy = players.reindex(at).to_numpy(dtype=float)
        out[f"{role}_x"], out[f"{role}_y"] = xy[:, 0] * turn, xy[:, 1] * turn
    return out


def _neighbour_means(cov: np.ndarray, neg: np.ndarray, x: np.ndarray,
                     n_neighbours: int) -> np.ndarray:
    """Per row, the mean of each column of `x` (rows, features) over the row's `n_neighbours`
    nearest negatives in `cov` (a negative not counting itself)."""
    neg_rows = np.flatnonzero(neg)
    _, idx = cKDTree(cov[neg]).query(cov, k=n_neighbours + 1)
    own = np.full(len(cov), -1)
    own[neg_rows] = np.arange(len(neg_rows))
    keep = idx != own[:, None]
    keep &= np.cumsum(keep, axis=1) <= n_neighbours
    picked = np.where(keep[:, :, None], x[neg_rows][idx], 0.0)
    return picked.sum(axis=1) / n_neighbours


def path_matched_auc(table: pd.DataFrame, n_neighbours: int = 10, n_boot: int = 500,
                     seed: int = 0, level: float = 0.95,
                     pairs: tuple[str, ...] = PATH_PAIRS) -> pd.DataFrame:
    """AUC of residuals per (pair, role, feature, k) of a `serve_paths` table (module doc), with
    n_pos / n_neg and the classes' mean feature (mean_pos / mean_neg); serves of a (server,
    receiver, serve number) with no more negatives than `n_neighbours` are left out."""
    if n_neighbours < 1 or n_boot < 0 or not 0 < level < 1:
        raise ValueError(f"need n_neighbours >= 1, n_boot >= 0, 0 < level < 1; got "
                         f"{n_neighbours}, {n_boot}, {level}")
    q = 50 * (1 - level), 50 * (1 + level)
    out = []
    for pi, pair in enumerate(pairs):
        visible = PAIRS[pair]
        for k in sorted(int(v) for v in table["k"].unique()):
            sub = table[(table["k"] == k) & (table[pair] >= 0)
                        & (table["at_frame"] < table[visible])]
            group = pd.factorize(sub["serve_number"].astype(str) + "|" + sub["hitter"].astype(str)
                                 + "|" + sub["opponent"].astype(str))[0]
            rng = np.random.default_rng([seed, pi, k])
            cls = sub[pair].to_numpy()
            for role in ROLES:
                cols = list(PATH_SCALES) + [f"{role}_x", f"{role}_y"]
                scale = np.array(list(PATH_SCALES.values()) + [POSITION_SCALE_M] * 2)
                cov = sub[cols].to_numpy(dtype=float) / scale
                # Speed and acceleration come from the same frames: missing together.
                x = sub[[f"{role}_{f}" for f in FEATURES]].to_numpy(dtype=float)
                ok = np.isfinite(x).all(axis=1) & np.isfinite(cov).all(axis=1)
                res = np.full(x.shape, np.nan)
                for g in np.unique(group):
                    rows = ok & (group == g)
                    neg = rows & (cls == 0)
                    if neg.sum() > n_neighbours:
                        # Rounded: equal movement must tie, not differ by summation order
                        # (features are rounded to 1 mm/s and 0.01 m/s^2 already).
                        res[rows] = np.round(x[rows] - _neighbour_means(
                            cov[rows], neg[rows], x[rows], n_neighbours), 6)
                mp, mn = np.isfinite(res[:, 0]) & (cls == 1), np.isfinite(res[:, 0]) & (cls == 0)
                for j, feature in enumerate(FEATURES):
                    row = {"pair": pair, "role": role, "feature": feature, "k": k,
                           "auc": np.nan, "lo": np.nan, "hi": np.nan,
                           "n_pos": int(mp.sum()), "n_neg": int(mn.sum()),
                           "mean_pos": x[mp, j].mean() if mp.any() else np.nan,
                           "mean_neg": x[mn, j].mean() if mn.any() else np.nan}
                    if mp.any() and mn.any():
                        r = res[:, j]
                        row["auc"] = float(weighted_auc(r[mp], r[mn], np.ones((1, mp.sum())),
                                                        np.ones((1, mn.sum())))[0])
                        if n_boot:
                            both = np.flatnonzero(mp | mn)
                            w = np.zeros((n_boot, len(r)))
                            w[:, both] = rng.multinomial(len(both), np.full(len(both),
                                                                            1 / len(both)),
                                                         size=n_boot)
                            boot = weighted_auc(r[mp], r[mn], w[:, mp], w[:, mn])
                            row["lo"], row["hi"] = np.nanpercentile(boot, q)
                    out.append(row)
    return pd.DataFrame(out)


def check_fault_paths(data: RallyData, ks=DEFAULT_KS, n_neighbours: int = 10,
                      n_boot: int = 500, seed: int = 0) -> pd.DataFrame:
    """`path_matched_auc` of a `RallyData`: the whole path-matched check of its faults."""
    table = serve_paths(data, contact_kinematics(data, ks))
    return path_matched_auc(table, n_neighbours=n_neighbours, n_boot=n_boot, seed=seed)
