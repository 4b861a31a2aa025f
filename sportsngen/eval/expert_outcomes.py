"""What the data's own players would win from a rally's states: the rally-outcome study's
reference without the outcomes' luck.

The rally-outcome study (`scripts/rally_outcome_study.py`) judges the model's P(server wins) at
branch points of held-out rallies against each rally's one recorded winner, and a rally's
branch points share it, so its ECE carries the sample's luck as well as the model's bias. Here
the generator's shot-cycle kernel (`sportsngen.synth.rally.continue_rally`, the process that
made the rallies) plays each branch point on `n` times: its share of server wins is what the
data's players win from there, and the model's share less it is the model's own error.

The kernel is handed the state `after_frames` after the last contact before the branch frame
(the branch frame itself when sooner), not the branch frame: it plans its players' runs at a
contact, so handed a state late in a flight it leaves the chaser where he stands (on version
6.4's held-out rallies its share from the 3 s branch frames was 0.46 against the outcomes'
0.64; from the hand-over states 0.67). The hand-over state knows less than the branch frame,
but the true probability is a martingale: over the branch frames reached from a hand-over
state, its mean is that state's probability of a win among the plays still going at the
branch frame. So the kernel's plays that ended before the branch frame are dropped (and
first-serve faults: the study's rallies are decided ones), and the answers have the same mean
as the true probabilities at the branch frames over any set of branch points chosen by time,
server or serve; they are less sharp, so compare means (and the ECE a calibrated predictor
scores on the sample), not single points. A branch frame at
or after the point's end (`rules.analyse_rally_data`'s `end_frame`: the study branches up to
the tracks' end, a second after it) is decided: its answer is the recorded winner.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.expert_answers import AFTER_FRAMES
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.synth.cycle import AFTER_END_S

MIN_FLIGHT_FRAMES = 3      # `train.expert.rally_state` reads a flight from this many frames on
KERNEL_COLUMNS = ("p_kernel", "n_kernel", "handover_frame", "decided")


def kernel_win_shares(data: RallyData, points: pd.DataFrame, n: int = 64,
                      after_frames: int = AFTER_FRAMES, seed: int = 0,
                      profiles: dict | None = None, progress: bool = False) -> pd.DataFrame:
    """`points` (rally_id, frame: branch frames of `data`'s rallies) -> the same rows with
    `KERNEL_COLUMNS`: the kernel's share of server wins `p_kernel` over its `n_kernel` plays
    from the hand-over state that were still going at the branch frame (NaN where no state
    can be read: before the serve's contact, a flight the rules cannot read, players without
    a generator profile, or every play ended sooner), the hand-over frame, and `decided` (the
    branch frame at or after the point's end: `p_kernel` is the recorded winner)."""
    from sportsngen.synth.profiles import named_profiles
    from sportsngen.train.expert import _play_on, rally_state

    if n < 1 or after_frames < MIN_FLIGHT_FRAMES:
        raise ValueError(f"n must be >= 1 and after_frames >= {MIN_FLIGHT_FRAMES}, got {n}, "
                         f"{after_frames}")
    missing = {"rally_id", "frame"} - set(points.columns)
    if missing:
        raise ValueError(f"points lack the column(s) {sorted(missing)}")
    profiles = named_profiles() if profiles is None else profiles
    rules = analyse_rally_data(data)
    unknown = set(points["rally_id"]) - set(rules.index)
    if unknown:
        raise ValueError(f"{len(unknown)} rally id(s) not in the data, e.g. {min(unknown)}")
    arr = rally_arrays(data, Vocab.from_data(data), unknown="generic")
    at = {rid: i for i, rid in enumerate(arr.rally_id)}
    rallies = data.rallies.set_index("rally_id")
    fps = float(data.fps)
    tail_frames = int(round(AFTER_END_S * fps))
    rng = np.random.default_rng(seed)
    rows = points.itertuples(index=False)
    if progress:
        from tqdm import tqdm
        rows = tqdm(rows, total=len(points), desc="kernel branch points")
    out = []
    for b in rows:
        rid, f = int(b.rally_id), int(b.frame)
        rule, r = rules.loc[rid], rallies.loc[rid]
        if f >= int(rule["end_frame"]):
            out.append((float(int(rule["winner"]) == 0), 0, -1, True))
            continue
        struck = [int(c) for c in rule["contact_frames"] if int(c) <= f]
        h = min(struck[-1] + after_frames, f) if struck else -1
        if not struck or h - struck[-1] < MIN_FLIGHT_FRAMES \
                or r["server"] not in profiles or r["receiver"] not in profiles:
            out.append((np.nan, 0, h, False))
            continue
        i = at[rid]
        track = arr.pos_m[arr.start[i]:arr.start[i] + arr.length[i]].astype(float)
        state = rally_state(track, h, struck[-1], (len(struck) - 1) % 2, len(struck), fps)
        wins = []
        for _ in range(n if state is not None else 0):
            try:
                res = _play_on(profiles, r, state, rng, fps, render=False)
            except ValueError:                 # a state the kernel refuses: no answer
                break
            # The study's rallies are decided (a first serve's went in) and went on past f.
            if res.winner_role is not None and h + res.n_frames - 1 - tail_frames > f:
                wins.append(res.winner_role == 0)
        out.append((float(np.mean(wins)) if wins else np.nan, len(wins), h, False))
    extra = pd.DataFrame(out, columns=list(KERNEL_COLUMNS), index=points.index)
    return pd.concat([points.drop(columns=[c for c in KERNEL_COLUMNS if c in points]), extra],
                     axis=1)


def paired_reference_gaps(points: pd.DataFrame, by: str | list[str] | None = None,
                          pred: str = "p", reference: str = "p_kernel") -> pd.DataFrame:
    """Per group of `by` (None: all), over points with both numbers: `n`, the mean prediction,
    the mean reference, the outcomes' mean (`server_won`) and `gap` = mean(pred - reference)
    with `se`, its standard error clustered by rally (a rally's points share its state)."""
    need = {pred, reference, "rally_id", "server_won"}
    if need - set(points.columns):
        raise ValueError(f"points lack the column(s) {sorted(need - set(points.columns))}")
    ok = points[points[pred].notna() & points[reference].notna()]
    ok = ok.assign(_d=ok[pred] - ok[reference], _all="all")
    rows = []
    for key, g in ok.groupby(by if by is not None else "_all", sort=True):
        m = len(g)
        dev = (g["_d"] - g["_d"].mean()).groupby(g["rally_id"]).sum()
        rows.append({"group": key, "n": m, "rallies": g["rally_id"].nunique(),
                     "pred": g[pred].mean(), "reference": g[reference].mean(),
                     "outcome": g["server_won"].mean(), "gap": g["_d"].mean(),
                     "se": float(np.sqrt((dev ** 2).sum())) / m})
    return pd.DataFrame(rows).set_index("group")
