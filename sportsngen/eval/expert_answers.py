"""Would the data's own players have played it so? The generator's kernel on a rally's states.

A simulated rally whose fourth shot goes out more often than the record's may do so because the
model's hitter chose badly there, or because the state the rally had reached was already worse
than any the record's hitter met. The generator's shot-cycle kernel
(`sportsngen.synth.rally.continue_rally`) plays a rally on from any state the way the data's
players would, so it tells the two apart: handed each rally's state `after_frames` frames after
shot `shot - 1` (the ball in flight to the next hitter, both players where the rally put them),
its shot `shot` stands beside the rally's own shot from that state. Where the two agree, the
model's choice is the data's and what differs from the record lies in the state; on recorded
rallies the same comparison measures the kernel itself (it should agree with the record).

A shot is read from the ball's track as the strike head reads it (`sportsngen.model.strike`:
the first rally strike after the hand-over, landing depth and lateral, height over the net),
and called in by those numbers (`lands_in`), so the rally's and the kernel's shots are judged
alike, whatever either did afterwards.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import RallyArrays, Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_profile import first_strike, hitter_behind_m
from sportsngen.model.inputs import BALL
from sportsngen.tennis.court import (
    BALL_RADIUS_M,
    BASELINE_X_M,
    NET_HEIGHT_CENTRE_M,
    SINGLES_HALF_WIDTH_M,
)

AFTER_FRAMES = 8     # the expert's own hand-over (`train.expert`): past the ball's read
SHOT_COLUMNS = ("struck", "in_play", "net_height_m", "depth_m", "side_m", "hitter_behind_m")


def lands_in(labels: np.ndarray) -> np.ndarray:
    """(..., 4) strike values (`strike.STRIKE_DIMS`) -> (...) bool: the ball clears the net's
    lowest point and lands in the opponent's singles court (NaN: False)."""
    labels = np.asarray(labels, dtype=float)
    with np.errstate(invalid="ignore"):
        return ((labels[..., 0] > 0.0) & (labels[..., 0] <= BASELINE_X_M)
                & (np.abs(labels[..., 1]) <= SINGLES_HALF_WIDTH_M)
                & (labels[..., 2] > NET_HEIGHT_CENTRE_M + BALL_RADIUS_M))


def _shot_row(track_m: np.ndarray, from_frame: int, fps: float) -> dict:
    """`SHOT_COLUMNS` of the first strike at or after `from_frame` of a (T, 3, 3) track."""
    got = first_strike(track_m[:, BALL], from_frame, fps)
    if got is None:
        return {"struck": False, "in_play": False, **{c: np.nan for c in SHOT_COLUMNS[2:]}}
    k, lab = got
    return {"struck": True, "in_play": bool(lands_in(lab)), "net_height_m": float(lab[2]),
            "depth_m": float(lab[0]), "side_m": float(abs(lab[1])),
            "hitter_behind_m": hitter_behind_m(track_m[k, :BALL, 0], track_m[k, BALL, 0])}


def kernel_answers(data: RallyData, shots: tuple[int, ...], after_frames: int = AFTER_FRAMES,
                   seed: int = 0, profiles: dict | None = None,
                   arrays: RallyArrays | None = None, counts: dict | None = None):
    """The kernel handed each rally of `data` `after_frames` frames after shot `j - 1`, for
    each `j` of `shots` (1 the return) the rally reached with its ball still in flight then,
    whether or not the rally went on to play shot `j`. Yields (rally position in the arrays,
    rally row, its contact frames, j, hand-over frame h, the rally's track (T, 3, 3), the
    kernel's `RallyResult`) in rally order; `arrays` are `rally_arrays(data, ...)` (default
    with a vocabulary of the data). `profiles`: player name -> generator profile (default
    the named players'); rallies of other players, and states the kernel cannot read or
    refuses, are skipped and counted in `counts` (keys states, other_players, no_flight,
    kernel_refused, answered)."""
    from sportsngen.synth.profiles import named_profiles
    from sportsngen.train.expert import _play_on, rally_state

    if not shots or min(shots) < 1:
        raise ValueError(f"shots count contacts after the serve (>= 1), got {shots}")
    if after_frames < 3:
        raise ValueError(f"after_frames must be >= 3 (the ball's flight is read from the "
                         f"frames after the contact), got {after_frames}")
    profiles = named_profiles() if profiles is None else profiles
    counts = {} if counts is None else counts
    for k in ("states", "other_players", "no_flight", "kernel_refused", "answered"):
        counts.setdefault(k, 0)
    rules = analyse_rally_data(data)
    arr = rally_arrays(data, Vocab.from_data(data), unknown="generic") if arrays is None \
        else arrays
    rallies = data.rallies.set_index("rally_id")
    rng = np.random.default_rng(seed)
    fps = float(data.fps)
    for ri, rid in enumerate(arr.rally_id):
        if rid not in rules.index:
            continue
        r = rallies.loc[rid]
        contacts = list(rules.loc[rid, "contact_frames"])
        track = arr.pos_m[arr.start[ri]:arr.start[ri] + arr.length[ri]].astype(float)
        for j in shots:
            if len(contacts) < j:
                break
            h = int(contacts[j - 1]) + after_frames
            nxt = contacts[j] if len(contacts) > j else len(track)
            if h >= min(nxt - 3, len(track) - 1):   # struck back (or over) by then
                continue
            counts["states"] += 1
            if r["server"] not in profiles or r["receiver"] not in profiles:
                counts["other_players"] += 1
                continue
            state = rally_state(track, h, int(contacts[j - 1]), (j - 1) % 2, j, fps)
            if state is None:
                counts["no_flight"] += 1
                continue
            try:
                res = _play_on(profiles, r, state, rng, fps)
            except ValueError:               # a state the kernel refuses: not an answer
                counts["kernel_refused"] += 1
                continue
            counts["answered"] += 1
            yield ri, r, contacts, j, h, track, res


def expert_shots(data: RallyData, shot: int | tuple[int, ...] = 3,
                 after_frames: int = AFTER_FRAMES, seed: int = 0, profiles: dict | None = None,
                 unplayed: bool = False) -> pd.DataFrame:
    """Each rally of `data` that played shot `shot` (1 the return; several shots: each of
    them), handed to the kernel `after_frames` frames after the shot before
    (`kernel_answers`) -> two rows a rally and shot, `who` "rally" (its own shot from there)
    and "expert" (the kernel's), with `SHOT_COLUMNS`, the `shot`, the rally's `server` and
    `receiver`, the shot's `hitter` and, for the kernel's rows that struck nothing, how its
    rally ended (`expert_end`). `unplayed`: also the rallies whose ball was still in flight
    then but whose shot never came (a ball let go, or missed: would the kernel have struck
    it?)."""
    shots = (shot,) if isinstance(shot, (int, np.integer)) else tuple(int(s) for s in shot)
    if not shots or min(shots) < 2:
        raise ValueError(f"shot counts contacts after the serve and needs one before it "
                         f"(>= 2), got {shot}")
    fps = float(data.fps)
    rows = []
    for _, r, contacts, j, h, track, res in kernel_answers(data, shots, after_frames, seed,
                                                           profiles):
        if len(contacts) <= j and not unplayed:      # the rally's own shot never came
            continue
        answer = np.concatenate([track[:h + 1], np.zeros((res.n_frames - 1, 3, 3))])
        answer[h + 1:, BALL] = res.ball_m[1:]
        answer[h + 1:, :BALL, :2] = np.transpose(res.players_m[:, 1:], (1, 0, 2))
        own, kernel = _shot_row(track, h, fps), _shot_row(answer, h, fps)
        base = {"rally_id": int(r.name), "shot": j, "server": r["server"],
                "receiver": r["receiver"], "hitter": r["receiver"] if j % 2 else r["server"]}
        rows.append({**base, "who": "rally", **own, "expert_end": ""})
        end = "" if kernel["struck"] else f"{res.end_reason}: {res.end_detail}"
        rows.append({**base, "who": "expert", **kernel, "expert_end": end})
    if not rows:
        raise ValueError(f"no rally of the data played shot {shot} with a state the kernel "
                         f"could answer")
    return pd.DataFrame(rows)


def simulated_expert_arrays(data: RallyData, vocab: Vocab, shots: tuple[int, ...],
                            after_frames: int = AFTER_FRAMES, keep_frames: int = 75,
                            seed: int = 0, profiles: dict | None = None):
    """Training rallies from the kernel's answers on simulated points (a later round of
    DAgger than `train.expert`, whose branches hold the model's frames for one flight): each
    answer of `kernel_answers` is the point's frames up to the hand-over (inputs) and at most
    `keep_frames` of the kernel's (targets, `learn_from` at the hand-over), identities in
    `vocab` -> (`RallyArrays`, counts)."""
    from sportsngen.train.expert import _answered, _expert_rallies

    counts: dict = {}
    arr = rally_arrays(data, vocab, unknown="generic")
    kept = []
    for ri, _, _, _, h, track, res in kernel_answers(data, shots, after_frames, seed,
                                                     profiles, arr, counts):
        near = arr.near_contact[arr.start[ri]:arr.start[ri] + h + 1]
        kept.append((*_answered(track[:h + 1].astype(np.float32), res, keep_frames,
                                float(data.fps), near), h, ri))
    return _expert_rallies(arr, kept, counts), counts


def summarise_expert_shots(rows: pd.DataFrame) -> pd.DataFrame:
    """`expert_shots` rows -> per shot, server and `who`: n, the share struck, in play of
    those struck, and the medians of the struck shots' net height, depth, distance from the
    centre line and the hitter's distance behind his baseline."""
    g = rows.groupby(["shot", "server", "who"])
    out = pd.concat([g.size().rename("n"), g["struck"].mean(),
                     g["in_play"].sum() / g["struck"].sum().clip(lower=1)
                     ] + [g[c].median() for c in SHOT_COLUMNS[2:]], axis=1)
    out.columns = ["n", "struck", "in_play_of_struck", *SHOT_COLUMNS[2:]]
    return out.reset_index()


def paired_expert_gaps(rows: pd.DataFrame) -> pd.DataFrame:
    """`expert_shots` rows -> per hitter and role (the shot's hitter serving the point or
    receiving it), over the shots struck both by the rally and by the kernel from the same
    state: n, the rally's and the kernel's shares in play, the rally's less the kernel's
    (`gap`) and that paired gap's standard error. A rally whose hitters err more than the
    kernel's from the same states erred by its own choice, not by the states it reached;
    the same table on recorded rallies measures the kernel's own bias."""
    key = ["rally_id", "shot"]
    own = rows[rows["who"] == "rally"].set_index(key)
    kernel = rows[rows["who"] == "expert"].set_index(key)[["struck", "in_play"]]
    both = own.join(kernel, rsuffix="_kernel", how="inner")
    both = both[both["struck"] & both["struck_kernel"]].reset_index()
    if both.empty:
        raise ValueError("no shot was struck both by the rally and by the kernel")
    both["role"] = np.where(both["hitter"] == both["server"], "server", "receiver")
    both["diff"] = both["in_play"].astype(float) - both["in_play_kernel"].astype(float)
    g = both.groupby(["hitter", "role"])
    out = pd.DataFrame({"n": g.size(), "rally_in": g["in_play"].mean(),
                        "kernel_in": g["in_play_kernel"].mean(), "gap": g["diff"].mean(),
                        "gap_se": g["diff"].std(ddof=1) / np.sqrt(g.size())})
    return out.reset_index()
