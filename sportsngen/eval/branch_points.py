"""The rally-outcome study's branch points: where in held-out rallies the model is asked who
wins (`scripts/rally_outcome_study.py`; the reference `eval.expert_outcomes` answers the same).

For each of `n_rallies` decided rallies (first-serve faults left out) drawn in a seeded order,
a branch point at each of `BRANCH_S` seconds after the rally's start that lies before the
tracks' last two frames. The tracks go on a second after the point's end, so some branch
points come after it: `decided` marks them (frame at or after the rules' `end_frame`); their
outcome is known at the branch.

`truth_rates` gives the truth's own server's share won by group of branch points (server,
serve, branch time) over a large generated truth: what any calibrated predictor's mean over a
group's states must come to, without a held-out sample's luck (docs/evaluation.md,
seventy-fourth part: the 200 rallies of seed 0 ran 0.07 below their groups' rates).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tracking import RallyData
from sportsngen.eval.rules import analyse_rally_data

BRANCH_S = (1.0, 2.0, 3.0, 4.0, 6.0)
# The rallies are picked for having a winner, so a first serve's rally is one whose serve went
# in: branched before its contact, the rollouts serve it themselves and may fault it (30 % of
# the 1 s branches, every serve being struck at 1.08 s), against an outcome that assumed it in
# (docs/evaluation.md, twenty-eighth part). Branched once it is struck, the serve is the record's.
AFTER_SERVE_FRAMES = 3
TRUTH_GROUPS = ("server", "serve_number", "branch_s")


def study_branch_points(data: RallyData, n_rallies: int, seed: int = 0,
                        branch_s: tuple[float, ...] = BRANCH_S) -> pd.DataFrame:
    """One row per branch point: rally_id, frame, server, receiver, serve_number, branch_s,
    half (the rally's draw order mod 2, the study's folds), server_won (0 or 1) and decided
    (the branch frame at or after the point's end)."""
    if n_rallies < 1:
        raise ValueError(f"n_rallies must be >= 1, got {n_rallies}")
    r = data.rallies[data.rallies["winner"] != ""]
    if len(r) < n_rallies:
        raise ValueError(f"asked for {n_rallies} rallies, the data has {len(r)} decided")
    rng = np.random.default_rng(seed)
    pick = r.iloc[rng.permutation(len(r))[:n_rallies]]
    length = data.frames.groupby("rally_id")["frame"].max()
    rules = analyse_rally_data(data)
    contacts, end = rules["contact_frames"], rules["end_frame"]
    rows = []
    for k, (_, row) in enumerate(pick.iterrows()):
        served = list(contacts.loc[row["rally_id"]])
        for b in branch_s:
            f = int(round(b * data.fps))
            if served:
                f = max(f, int(served[0]) + AFTER_SERVE_FRAMES)
            if f < int(length[row["rally_id"]]) - 2:
                rows.append({"rally_id": int(row["rally_id"]), "frame": f,
                             "server": row["server"], "receiver": row["receiver"],
                             "serve_number": int(row["serve_number"]), "branch_s": b,
                             "half": k % 2,
                             "server_won": float(row["winner"] == row["server"]),
                             "decided": f >= int(end.loc[row["rally_id"]])})
    return pd.DataFrame(rows)


def truth_rates(truth: RallyData, by: tuple[str, ...] = TRUTH_GROUPS) -> pd.DataFrame:
    """Per group of `by`: `n` branch points and `rate`, the server's share won, over every
    decided rally of `truth` branched as the study branches (undecided branch points only)."""
    n = int((truth.rallies["winner"] != "").sum())
    pts = study_branch_points(truth, n)
    live = pts[~pts["decided"]]
    grp = live.groupby(list(by))["server_won"]
    return pd.DataFrame({"n": grp.size(), "rate": grp.mean()})


def with_truth_rates(points: pd.DataFrame, rates: pd.DataFrame,
                     by: tuple[str, ...] = TRUTH_GROUPS) -> pd.DataFrame:
    """`points` with `p_truth`: its group's rate in `rates` (NaN where decided or where the
    truth has no such group)."""
    out = points.drop(columns=["p_truth"], errors="ignore").merge(
        rates["rate"].rename("p_truth").reset_index(), on=list(by), how="left")
    out.index = points.index
    if "decided" in out:
        out.loc[out["decided"].astype(bool), "p_truth"] = float("nan")
    return out


def pool_branch_points(parts: list[pd.DataFrame]) -> pd.DataFrame:
    """Several runs' branch points (other seeds' held-out rallies) as one table, each part's
    rally ids moved past the previous part's largest, so pooled rallies stay apart in the folds
    and in errors clustered by rally. Only the columns every part has are kept: a run written
    before a column existed (``decided``) left NaN in it, which read as True flagged all its
    points decided (seed 1's 842 of the seventy-fifth part's pool)."""
    if not parts:
        raise ValueError("no branch points to pool")
    common = [c for c in parts[0].columns if all(c in part.columns for part in parts[1:])]
    out, offset = [], 0
    for part in parts:
        out.append(part[common].assign(rally_id=part["rally_id"] + offset))
        offset += int(part["rally_id"].max()) + 1
    return pd.concat(out, ignore_index=True)
