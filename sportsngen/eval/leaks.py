"""Leak check: does a player's movement after a racket contact tell the contact's outcome
before that player could have seen it?

Tracking in which players "know the future" (stop when the serve will be an ace, brake when the
shot will be a winner) teaches a model to move on information it cannot have; rolled out, it
then runs backwards. This check measures that on any `RallyData` before training.

Classes of a contact (a row of the ``shots`` table), from the tables only:

- ``error``: ``outcome == "error"`` (``error_kind`` "fault" on a serve, "forced"/"unforced"
  after); ``in``: ``outcome`` "in_play" or "winner";
- ``returned``: in, and the rally has a shot with ``shot_index + 1``;
- ``unreturned``: in, no next shot, and the rally's ``end_reason`` is "ace" or "winner"
  (an in-ball without a next shot in a rally ending otherwise is left out: the data is cut).

Pairs (positive class first; serves are ``shot_index == 0``, rally shots ``>= 1``):
``fault_vs_in`` serves error / in; ``ace_vs_returned`` serves unreturned / returned;
``winner_vs_returned`` rally shots unreturned / returned; ``error_vs_in`` rally shots error / in.

When the outcome becomes visible (frames, from the tracks only, through the rally-end rules of
`sportsngen.tennis.rally`): for error/in pairs, the first of the first bounce, the next
contact and the rally's end by the rules (the net, a ball at rest); for returned/unreturned
pairs, the first of the next contact, the second bounce, the rally's end and the first frame at
which the ball is farther from the net than the opponent (it has passed him). The next contact
is the earlier of the shots table's and the rules' (which agree within a frame); the end of the
track bounds both. A contact after the rules have ended its rally (rules and labels disagree)
is left out.

Features: each role's (``hitter``, ``opponent``; for a serve the server and the receiver)
horizontal speed (m/s) and acceleration magnitude (m/s^2) at contact frame + k, from backward
differences (frames t, t-1, t-2: only what has happened by frame t). A contact enters at k only
if contact frame + k is strictly before its pair's visible frame. k is in frames at 25 Hz
(scaled to the data's fps).

Stratified by what both players could see: positives are compared only with negatives of the
same stratum (the hitter and opponent, the serve number, the shot's direction label (of a
simulated serve its bounce's third of the box, `sim.assemble`: the event classifier's label had
put wide aces beside returned T serves), the
hitter's depth behind his baseline at the contact in `CONTACT_DEPTH_BINS_M`, for a serve where
in its frame interval it was struck (`contact_phase`: the labelled frame is the contact
rounded), the role's speed
at the contact in `CONTACT_SPEED_BINS_MPS`, and the ball's flight as seen a reaction time
before the measured frame, ``seen_flight`` for the hitter's cells and
``opponent_seen_flight`` for the opponent's, which differ only for a serve's receiver, who
reads it sooner; for the opponent's cells also how far sideways that flight passes him,
``seen_reach``; for the hitter's cells also how fast he saw his ball leave, ``seen_pace``,
and, after rally shots, how far across the court he saw it go, ``seen_width``),
and the AUC pools the strata by their number of
pairs. Without that, causes everyone can see pass for leaks: a player who aces more and whose
receiver reacts later, a wide serve (more often an ace) after which the server recovers further,
a harder serve (more often an ace) after which he runs back slower, a ball sent far across
the court (more often a winner) after which the hitter recovers further,
an opponent still running at the contact (more often passed), a ball seen flying long that the
opponent chases deeper (more often an error), a receiver sprinting at a serve that passes out
of his reach (more often an ace), a receiver who had read a wide serve by the sixth frame
and sprinted (more often an ace). ``stratify=False`` gives the raw AUC; ``diff_within`` says
how large a difference an AUC ranks (m/s, m/s^2): a rank statistic can put 4 mm/s between
receivers all near their top acceleration outside the band (0.63 in the bundled model's serve
branches, where version 5's frozen players differ by 1-3 m/s). So two values within a
feature's `FEATURE_RESOLUTION` (1 cm/s, 0.05 m/s^2) tie: a difference a player's legs cannot
turn into an outcome is not ranked (``resolution={}`` gives the exact floats' AUC).

The seen flight, reach and pace are defined in `sportsngen.eval.seen`.

An AUC far from 0.5 says the classes move differently before the outcome is visible; it is a
prompt to look, not proof of a leak: the opponent sees the ball in flight, and a ball that sends
him sprinting wide is more often a winner. The same AUC at k = 0 (the contact itself) tells a
difference that was there before the shot from one that appears after it.

`contact_kinematics` gives the per-contact table (one row a contact and k, saveable);
`leak_auc` turns such a table into AUCs with rally-bootstrap intervals; `check_leaks` does
both; `render_leaks` writes a markdown table. A cell outside the band is read with its
interval: ``unsure`` where the interval holds 0.5 (`sure_leaks` leaves those out), ``thin``
where it rests on too few comparable pairs to read at all (`thin_cells`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.seen import (
    SEEN_LAG_S,
    SEEN_NONE,
    SEEN_RETURN_LAG_S,
    seen_ball,
    seen_flight,
    seen_pace,
    seen_reach,
    seen_width,
)
from sportsngen.tennis.court import BASELINE_X_M

BASE_FPS = 25.0
DEFAULT_KS = (6, 12)
ROLES = ("hitter", "opponent")
FEATURES = ("speed_mps", "acc_mps2")
# pair -> column holding the frame at which its outcome is visible
PAIRS = {"fault_vs_in": "land_frame", "ace_vs_returned": "outcome_frame",
         "winner_vs_returned": "outcome_frame", "error_vs_in": "land_frame"}
FEATURE_COLUMNS = tuple(f"{r}_{f}" for r in ROLES for f in FEATURES)
CONTACT_SPEED_COLUMNS = tuple(f"{r}_speed0_mps" for r in ROLES)
STRATA_COLUMNS = ("hitter", "opponent", "serve_number", "direction", "contact_depth",
                  "contact_phase")
# The flight as each role saw it: a serve's receiver reads it sooner (`SEEN_RETURN_LAG_S`).
OPPONENT_STRATA_COLUMNS = ("opponent_seen_flight", "seen_reach")  # the opponent's cells only
HITTER_STRATA_COLUMNS = ("seen_flight", "seen_pace", "seen_width")  # the hitter's cells only
TABLE_COLUMNS = ("rally_id", "shot_index", "frame", "k", "at_frame", "land_frame",
                 "outcome_frame") + tuple(PAIRS) + FEATURE_COLUMNS
CONTACT_SPEED_BINS_MPS = (0.25, 0.75, 1.5, 2.25, 3.0, 4.0, 5.0)
# The hitter's distance behind his baseline at the contact: inside / up to 1 m / deeper. A
# player who struck from inside the court recovers backward, and such balls are more often
# winners (the hitter's speed 12 frames on: AUC 0.61 -> 0.56 with this stratum).
CONTACT_DEPTH_BINS_M = (0.0, 1.0)
# Where in its frame interval a serve fell (`contact_phase`): k frames after the labelled
# frame are k - 0.5 to k + 0.5 frames of flight, and what a player has seen and how long he has
# run by then with them. A generator whose serves start anywhere in a frame read the receiver
# before faults at 0.621 [0.564, 0.673] on 2,166 pairs without this stratum (500 points).
CONTACT_PHASE_BINS = (-0.25, 0.0, 0.25)
# An AUC resting on fewer comparable pairs is not read (`thin_cells`): below 10 one pair moves
# it by more than the band's half-width (0.1). At 800 generated points the receiver's
# acceleration 12 frames before a fault rested on 2 pairs and read 0.000.
MIN_READ_PAIRS = 10
# Two values of a feature this close tie in the AUC (`leak_auc`). On exact floats a rank statistic
# ranks differences no tracking resolves and no outcome follows from: seed 1's branch receivers
# into aces, 6 frames on, read 0.620 [0.568, 0.670] on a difference of 1.9 mm/s (0.564 and
# -0.2 mm/s with other rollout draws), 0.531 with speeds tied within 1 cm/s. The acceleration's
# is the widest that keeps a lean the rules then fixed (the seventy-seventh part's own-serve
# receiver into aces, 0.372 exact): 0.381 at 0.05 m/s^2, 0.431 at 0.25 (docs/evaluation.md,
# eightieth part).
FEATURE_RESOLUTION = {"speed_mps": 0.01, "acc_mps2": 0.05}
LABEL_TOL_FRAMES = 1  # a labelled contact and the rules' detected one differ by at most this
_BOOT_CELLS = 4_000_000  # replicate x contact weights held at once


def contact_classes(data: RallyData) -> pd.DataFrame:
    """One row a contact: rally_id, shot_index, frame, hitter, opponent and one int8 column a
    pair (1 positive, 0 negative, -1 not in the pair); definitions in the module doc."""
    s = data.shots.sort_values(["rally_id", "shot_index"], kind="stable").reset_index(drop=True)
    r = data.rallies.set_index("rally_id")
    server = s["rally_id"].map(r["server"]).to_numpy(dtype=object)
    receiver = s["rally_id"].map(r["receiver"]).to_numpy(dtype=object)
    hitter = s["hitter"].to_numpy(dtype=object)
    stranger = (hitter != server) & (hitter != receiver)
    if stranger.any():
        i = int(np.flatnonzero(stranger)[0])
        raise ValueError(f"shots row {i} (rally {int(s['rally_id'].iat[i])}): hitter "
                         f"{hitter[i]!r} is neither the rally's server nor its receiver")
    outcome = s["outcome"].astype(str).to_numpy()
    serve = s["shot_index"].to_numpy() == 0
    error = outcome == "error"
    landed = np.isin(outcome, ("in_play", "winner"))
    nxt = pd.MultiIndex.from_arrays([s["rally_id"], s["shot_index"] + 1])
    has_next = nxt.isin(pd.MultiIndex.from_arrays([s["rally_id"], s["shot_index"]]))
    ended_won = s["rally_id"].map(r["end_reason"]).isin(("ace", "winner")).to_numpy()
    returned, unreturned = landed & has_next, landed & ~has_next & ended_won

    def pair(pos: np.ndarray, neg: np.ndarray, members: np.ndarray) -> np.ndarray:
        return np.where(members & pos, 1, np.where(members & neg, 0, -1)).astype(np.int8)

    return pd.DataFrame({
        "rally_id": s["rally_id"].to_numpy(np.int64),
        "shot_index": s["shot_index"].to_numpy(np.int64),
        "frame": s["frame"].to_numpy(np.int64), "hitter": hitter,
        "opponent": np.where(hitter == server, receiver, server),
        "serve_number": s["rally_id"].map(r["serve_number"]).to_numpy(np.int64),
        "direction": s["direction"].astype(str).to_numpy(object),
        "fault_vs_in": pair(error, landed, serve),
        "ace_vs_returned": pair(unreturned, returned, serve),
        "winner_vs_returned": pair(unreturned, returned, ~serve),
        "error_vs_in": pair(error, landed, ~serve)})


def _next_event(ev_rally: np.ndarray, ev_frame: np.ndarray, rally: np.ndarray,
                after: np.ndarray, nth: int = 0) -> np.ndarray:
    """Frame of the (nth + 1)-th event of the same rally strictly after frame `after`, else inf
    (events given as parallel rally-index / frame arrays; one sorted search, no loops)."""
    span = int(max(ev_frame.max(initial=0), after.max(initial=0))) + 2
    keys = np.sort(ev_rally.astype(np.int64) * span + ev_frame)
    i = np.searchsorted(keys, rally * span + after + 1, side="left") + nth
    hit = keys[np.minimum(i, len(keys) - 1)] if len(keys) else np.zeros(len(rally), np.int64)
    ok = (i < len(keys)) & (hit // span == rally)
    return np.where(ok, hit - rally * span, np.inf)


def _explode(rules: pd.DataFrame, column: str, first: np.ndarray) -> tuple[np.ndarray, ...]:
    """(rally index, absolute frame) of every event in a list column of the rules' results."""
    n = rules[column].map(len).to_numpy()
    frames = np.concatenate([np.asarray(v, dtype=np.int64) for v in rules[column]] +
                            [np.zeros(0, np.int64)])
    rally = np.repeat(np.arange(len(rules)), n)
    return rally, frames + first[rally]


def frames_flown(contact_xy: np.ndarray, next_xy: np.ndarray, after_xy: np.ndarray
                 ) -> np.ndarray:
    """(N, 2) each a contact's position and the ball's at the two frames after the contact's
    labelled frame -> how many frames the ball had flown from the contact at the labelled frame
    (negative: the contact came after it), the flight between the two frames carried back to
    the contact (drag slows a fast ball a few per cent a frame: about 0.04 of a frame
    over, which quarter-frame bins do not feel); NaN where the ball did not move."""
    step = after_xy - next_xy
    norm2 = (step ** 2).sum(axis=1)
    return ((next_xy - contact_xy) * step).sum(axis=1) / np.where(norm2 > 0, norm2, np.nan) - 1.0


def contact_phase(data: RallyData, contacts: pd.DataFrame, ball_xy: np.ndarray,
                  row0: np.ndarray, f: np.ndarray, track_end: np.ndarray,
                  bins=CONTACT_PHASE_BINS) -> np.ndarray:
    """Per contact, the bin in `bins` of how far the ball had flown from the contact at its
    labelled frame, in frames (the label is the contact's time rounded: -0.5 to 0.5), read by
    carrying the flight from frame f + 1 to f + 2 back to the shots table's contact position;
    `SEEN_NONE` where either is missing."""
    shots = data.shots.set_index(["rally_id", "shot_index"])
    key = pd.MultiIndex.from_arrays([contacts["rally_id"], contacts["shot_index"]])
    cols = [col for col in ("contact_x", "contact_y") if col in shots]
    contact = (shots.reindex(key)[cols].to_numpy(float) if len(cols) == 2
               else np.full((len(contacts), 2), np.nan))
    ok = f + 2 < track_end
    flown = frames_flown(contact, ball_xy[np.where(ok, row0 + f + 1, 0)],
                         ball_xy[np.where(ok, row0 + f + 2, 0)])
    seen = ok & np.isfinite(flown)
    code = np.digitize(np.where(seen, flown, 0.0), bins)
    return np.where(seen, code, SEEN_NONE).astype(np.int64)


def contact_kinematics(data: RallyData, ks=DEFAULT_KS) -> pd.DataFrame:
    """The per-contact table `leak_auc` works on: one row a contact and k (`TABLE_COLUMNS`,
    plus hitter / opponent names). ``k`` is in frames at 25 Hz, ``at_frame`` the data frame
    the features are measured at; ``land_frame`` / ``outcome_frame`` when the contact's
    landing / whether it is returned becomes visible (module doc; a contact after the rules
    have ended its rally gets its own frame: left out); features, rounded to 1 mm/s and
    0.01 m/s^2, are NaN where the track lacks a frame of at_frame - 2 .. at_frame."""
    ks = [int(k) for k in np.atleast_1d(ks)]
    if not ks or min(ks) < 0:
        raise ValueError(f"ks must be frame offsets >= 0, got {ks}")
    if len(data.shots) == 0:
        raise ValueError("the data has no shots (racket contacts) to check")
    c = contact_classes(data)
    arr = rally_arrays(data, Vocab.from_data(data, generic=True))
    # No duration cap: a long clay rally's later contacts keep their events.
    rules = analyse_rally_data(data, max_duration_s=(arr.length.max() + 1) / data.fps)
    rules = rules.loc[arr.rally_id]
    first = data.frames.groupby("rally_id")["frame"].min().loc[arr.rally_id].to_numpy()
    where = pd.Series(np.arange(len(arr)), index=arr.rally_id)
    r = where.loc[c["rally_id"]].to_numpy()
    f = c["frame"].to_numpy()
    row0 = arr.start[r] - first[r]                      # row of frame 0 of the contact's rally
    track_end = (first + arr.length)[r].astype(float)  # one past the last frame

    server = data.rallies.set_index("rally_id").loc[arr.rally_id, "server"].to_numpy(object)
    hitter_slot = np.where(c["hitter"].to_numpy() == server[r], 0, 1)
    pos = arr.pos_m.astype(np.float64)

    # The ball has passed the opponent: farther from the net than him, on his side.
    past = [(pos[:, 2, 0] - pos[:, s, 0]) * np.sign(pos[:, s, 0]) > 0 for s in (0, 1)]
    rally_of_row = np.repeat(np.arange(len(arr)), arr.length)
    frame_of_row = np.arange(len(pos)) - arr.start[rally_of_row] + first[rally_of_row]
    opp_slot = 1 - hitter_slot
    passed = np.full(len(c), np.inf)
    for s in (0, 1):
        m = opp_slot == s
        passed[m] = _next_event(rally_of_row[past[s]], frame_of_row[past[s]], r[m], f[m])

    bounce = _explode(rules, "bounce_frames", first)
    bounce1 = _next_event(*bounce, r, f)
    bounce2 = _next_event(*bounce, r, f, nth=1)
    # The rules' contacts of this shot lie within a frame of its label: the next one is later.
    rules_next = _next_event(*_explode(rules, "contact_frames", first), r, f + LABEL_TOL_FRAMES)
    label_next = c.groupby("rally_id")["frame"].shift(-1).fillna(np.inf).to_numpy()
    contact_next = np.minimum(rules_next, label_next)
    end = np.where(rules["ended"].to_numpy(), rules["end_frame"].to_numpy() + first, np.inf)[r]
    land = np.minimum.reduce([bounce1, contact_next, end, track_end])
    outcome = np.minimum.reduce([contact_next, bounce2, passed, end, track_end])
    # After the rules have ended the rally (they disagree with the labels) its events are
    # unknown: such a contact is left out at every k.
    land, outcome = (np.where(f < end, v, f) for v in (land, outcome))

    def kinematics(at: np.ndarray, slot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ok = (at - 2 >= first[r]) & (at < track_end)
        rows = np.where(ok, row0 + at, 0)
        p0, p1, p2 = (pos[np.maximum(rows - j, 0), slot, :2] for j in range(3))
        speed = np.hypot(*(p0 - p1).T) * data.fps
        acc = np.hypot(*(p0 - 2.0 * p1 + p2).T) * data.fps ** 2
        # Positions are float32 (rally_arrays): finer differences are rounding, not
        # movement, and rounding them away lets equal movement tie.
        return np.where(ok, speed, np.nan).round(3), np.where(ok, acc, np.nan).round(2)

    slots = (("hitter", hitter_slot), ("opponent", opp_slot))
    # Serves only: a rally ball's time of contact follows from flights, and falls anywhere in
    # its frame in any tracking (no rally cell read by it: 0 of 32 outside on 10,000 points
    # without it), where a generator's serves could share one phase.
    phase = np.full(len(c), SEEN_NONE, dtype=np.int64)
    sv = c["shot_index"].to_numpy() == 0
    phase[sv] = contact_phase(data, c[sv], pos[:, 2, :2], row0[sv], f[sv], track_end[sv])
    hitter_x = pos[np.where(f < track_end, row0 + f, 0), hitter_slot, 0]
    depth_bin = np.digitize(np.abs(hitter_x) - BASELINE_X_M, CONTACT_DEPTH_BINS_M)
    base = c.assign(land_frame=land.astype(np.int64), outcome_frame=outcome.astype(np.int64),
                    contact_depth=depth_bin.astype(np.int64), contact_phase=phase,
                    **{f"{role}_speed0_mps": kinematics(f, slot)[0] for role, slot in slots})
    parts = []
    lag = int(round(SEEN_LAG_S * data.fps))
    serve = c["shot_index"].to_numpy() == 0
    opp_lag = np.where(serve, int(round(SEEN_RETURN_LAG_S * data.fps)), lag)
    for k in ks:
        at = f + int(round(k * data.fps / BASE_FPS))
        part = base.assign(k=k, at_frame=at)
        ball = seen_ball(pos[:, 2], f, at - lag, row0, track_end, data.fps)
        part["seen_flight"] = seen_flight(pos[:, 2], f, at - lag, row0, track_end, serve,
                                          data.fps, ball=ball)
        part["seen_pace"] = seen_pace(ball)
        # A serve's width is its direction label's (wide, body, T), already a stratum.
        part["seen_width"] = np.where(serve, SEEN_NONE, seen_width(ball))
        # The opponent saw what the hitter saw, but for a serve's receiver: read those alone.
        sub = (f[serve], (at - opp_lag)[serve], row0[serve], track_end[serve])
        ball_serve = seen_ball(pos[:, 2], *sub, data.fps)
        opp_ball = {key: v.copy() for key, v in ball.items()}
        for key, v in ball_serve.items():
            opp_ball[key][serve] = v
        opp_flight = part["seen_flight"].to_numpy().copy()
        opp_flight[serve] = seen_flight(pos[:, 2], *sub, serve[serve], data.fps,
                                        ball=ball_serve)
        opp_rows = np.where(opp_ball["ok"], row0 + at - opp_lag, 0)
        part["opponent_seen_flight"] = opp_flight
        part["seen_reach"] = seen_reach(opp_ball, opp_flight, pos[opp_rows, opp_slot, :2])
        for role, slot in slots:
            part[f"{role}_speed_mps"], part[f"{role}_acc_mps2"] = kinematics(at, slot)
        parts.append(part)
    return pd.concat(parts, ignore_index=True)


def weighted_auc(pos: np.ndarray, neg: np.ndarray, w_pos: np.ndarray,
                 w_neg: np.ndarray, tie_within: float = 0.0) -> np.ndarray:
    """Mann-Whitney AUC, P(pos > neg) + 0.5 P(pos == neg), with weights: `pos` (P,), `neg`
    (N,), `w_pos` (B, P), `w_neg` (B, N) -> (B,); NaN where a class has zero weight. Exact
    (one sort and cumulative sums; integer weights give the AUC of the repeated samples).
    `tie_within` >= 0: values that close count as equal, P(pos > neg + t) + 0.5
    P(|pos - neg| <= t) (still 1 minus the AUC with the classes swapped)."""
    num, den = _pair_counts(pos, neg, w_pos, w_neg, tie_within)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def _pair_counts(pos: np.ndarray, neg: np.ndarray, w_pos: np.ndarray,
                 w_neg: np.ndarray, tie_within: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(weighted pairs with pos > neg plus half the ties, weighted pairs), each (B,); a pair
    within `tie_within` of each other is a tie."""
    if not tie_within >= 0:
        raise ValueError(f"tie_within must be >= 0, got {tie_within}")
    if pos.size == 0 or neg.size == 0:
        zero = np.zeros(w_pos.shape[0])
        return zero, zero
    order = np.argsort(neg, kind="stable")
    neg_sorted = neg[order]
    cum = np.concatenate([np.zeros((w_neg.shape[0], 1)), np.cumsum(w_neg[:, order], axis=1)],
                         axis=1)
    lo = np.searchsorted(neg_sorted, pos - tie_within, side="left")
    hi = np.searchsorted(neg_sorted, pos + tie_within, side="right")
    below, ties = cum[:, lo], cum[:, hi] - cum[:, lo]
    return (w_pos * (below + 0.5 * ties)).sum(axis=1), w_pos.sum(axis=1) * cum[:, -1]


def stratified_auc(pos: np.ndarray, neg: np.ndarray, w_pos: np.ndarray, w_neg: np.ndarray,
                   s_pos: np.ndarray, s_neg: np.ndarray, tie_within: float = 0.0) -> np.ndarray:
    """`weighted_auc` counting only pairs within a stratum (`s_pos` (P,) and `s_neg` (N,)
    integer stratum codes): the strata's AUCs pooled by their (weighted) numbers of pairs."""
    num = np.zeros(w_pos.shape[0])
    den = np.zeros(w_pos.shape[0])
    for code in np.intersect1d(s_pos, s_neg):
        mp, mn = s_pos == code, s_neg == code
        n, d = _pair_counts(pos[mp], neg[mn], w_pos[:, mp], w_neg[:, mn], tie_within)
        num += n
        den += d
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def stratified_difference(pos: np.ndarray, neg: np.ndarray, s_pos: np.ndarray,
                          s_neg: np.ndarray) -> float:
    """Mean of pos minus mean of neg within each stratum, pooled by the strata's numbers of
    pairs (the weights of `stratified_auc`): how large the difference the AUC ranks is, in
    the feature's units. NaN without a comparable pair."""
    if len(pos) == 0 or len(neg) == 0:
        return float("nan")
    size = int(max(s_pos.max(), s_neg.max())) + 1
    n_pos, n_neg = np.bincount(s_pos, minlength=size), np.bincount(s_neg, minlength=size)
    w = (n_pos * n_neg).astype(float)
    if w.sum() == 0:
        return float("nan")
    both = w > 0
    diff = (np.bincount(s_pos, pos, size)[both] / n_pos[both]
            - np.bincount(s_neg, neg, size)[both] / n_neg[both])
    return float((w[both] * diff).sum() / w.sum())


def comparable_pairs(s_pos: np.ndarray, s_neg: np.ndarray) -> int:
    """How many (positive, negative) pairs share a stratum: what a stratified AUC rests on
    (a handful of contacts can make thousands of n_pos x n_neg but few comparable pairs)."""
    if len(s_pos) == 0 or len(s_neg) == 0:
        return 0
    size = int(max(s_pos.max(), s_neg.max())) + 1
    return int(np.dot(np.bincount(s_pos, minlength=size), np.bincount(s_neg, minlength=size)))


def auc(pos, neg) -> float:
    """Mann-Whitney AUC of two samples, P(pos > neg) + 0.5 P(pos == neg); NaN if one is empty."""
    pos, neg = np.asarray(pos, dtype=float).ravel(), np.asarray(neg, dtype=float).ravel()
    if not (np.isfinite(pos).all() and np.isfinite(neg).all()):
        raise ValueError("auc: pos and neg must be finite")
    return float(weighted_auc(pos, neg, np.ones((1, pos.size)), np.ones((1, neg.size)))[0])


def _strata(sub: pd.DataFrame, role: str) -> np.ndarray:
    """Integer stratum code of each row: the visible context of the contact (`STRATA_COLUMNS`)
    and the role's speed bin at the contact."""
    speed0 = sub[f"{role}_speed0_mps"].to_numpy(dtype=float)
    speed_bin = np.where(np.isfinite(speed0), np.digitize(speed0, CONTACT_SPEED_BINS_MPS), -1)
    columns = STRATA_COLUMNS + (OPPONENT_STRATA_COLUMNS if role == "opponent" else
                                HITTER_STRATA_COLUMNS)
    keys = [sub[c].astype(str).to_numpy() for c in columns] + [speed_bin.astype(str)]
    return pd.factorize(pd.Series(["|".join(t) for t in zip(*keys)]))[0]


def leak_auc(kin: pd.DataFrame, n_boot: int = 1000, seed: int = 0, level: float = 0.95,
             stratify: bool = True, resolution: dict[str, float] | None = None
             ) -> pd.DataFrame:
    """AUC per (pair, role, k, feature) of a `contact_kinematics` table (rows whose at_frame is
    not before the pair's visible frame left out; NaN features dropped), stratified (module
    doc) unless `stratify` is False, with `level` bootstrap percentile intervals from `n_boot`
    resamples of whole rallies (all the contacts of a rally share its weight, so shots of one
    rally are not taken as independent; n_pos and n_neg vary between replicates). ``n_pairs``
    counts the (positive, negative) pairs within a stratum, what the AUC rests on;
    ``diff_within`` is the size of what it ranks (`stratified_difference`). Two values of a
    feature within its `resolution` (feature -> units; None: `FEATURE_RESOLUTION`, {}: exact)
    tie. The generator is seeded per (seed, pair, k): fixed results."""
    resolution = FEATURE_RESOLUTION if resolution is None else resolution
    unknown = sorted(set(resolution) - set(FEATURES))
    if unknown or any(not v >= 0 for v in resolution.values()):
        raise ValueError(f"resolution: features {list(FEATURES)} to sizes >= 0, got "
                         f"{resolution}")
    tie = [float(resolution.get(col.split("_", 1)[1], 0.0)) for col in FEATURE_COLUMNS]
    need = TABLE_COLUMNS + ((STRATA_COLUMNS + OPPONENT_STRATA_COLUMNS + HITTER_STRATA_COLUMNS
                             + CONTACT_SPEED_COLUMNS) if stratify else ())
    missing = [col for col in need if col not in kin.columns]
    if missing:
        raise ValueError(f"kinematics table lacks columns {missing}"
                         + (" (stratify=False gives the raw AUC)" if stratify else ""))
    if n_boot < 0 or seed < 0 or not 0 < level < 1:
        raise ValueError(f"need n_boot >= 0, seed >= 0, 0 < level < 1; got {n_boot}, {seed}, "
                         f"{level}")
    q = 50 * (1 - level), 50 * (1 + level)
    out = []
    for pi, (pair, visible) in enumerate(PAIRS.items()):
        for k in sorted(int(v) for v in kin["k"].unique()):
            sub = kin[(kin["k"] == k) & (kin[pair] >= 0) & (kin["at_frame"] < kin[visible])]
            cls = sub[pair].to_numpy()
            rallies, ridx = np.unique(sub["rally_id"].to_numpy(), return_inverse=True)
            x = sub[list(FEATURE_COLUMNS)].to_numpy(dtype=float)
            codes = {role: _strata(sub, role) if stratify else np.zeros(len(sub), np.int64)
                     for role in ROLES}
            masks = [(np.isfinite(x[:, j]) & (cls == 1), np.isfinite(x[:, j]) & (cls == 0))
                     for j in range(x.shape[1])]
            roles = [col.split("_", 1)[0] for col in FEATURE_COLUMNS]
            boot = np.full((x.shape[1], n_boot), np.nan)
            rng = np.random.default_rng([seed, pi, k])
            step = max(1, _BOOT_CELLS // max(len(sub), 1))
            for b0 in range(0, n_boot if len(rallies) else 0, step):
                nb = min(step, n_boot - b0)
                w = rng.multinomial(len(rallies), np.full(len(rallies), 1 / len(rallies)),
                                    size=nb)[:, ridx].astype(float)
                for j, (mp, mn) in enumerate(masks):
                    cj = codes[roles[j]]
                    boot[j, b0:b0 + nb] = stratified_auc(x[mp, j], x[mn, j], w[:, mp],
                                                         w[:, mn], cj[mp], cj[mn], tie[j])
            for j, col in enumerate(FEATURE_COLUMNS):
                role, feature = col.split("_", 1)
                mp, mn = masks[j]
                cj = codes[role]
                finite = np.isfinite(boot[j])
                lo, hi = np.percentile(boot[j, finite], q) if finite.any() else (np.nan,) * 2
                point = stratified_auc(x[mp, j], x[mn, j], np.ones((1, mp.sum())),
                                       np.ones((1, mn.sum())), cj[mp], cj[mn], tie[j])[0]
                out.append({"pair": pair, "role": role, "feature": feature, "k": k,
                            "auc": float(point), "lo": lo, "hi": hi,
                            "n_pos": int(mp.sum()), "n_neg": int(mn.sum()),
                            "n_pairs": comparable_pairs(cj[mp], cj[mn]),
                            "mean_pos": x[mp, j].mean() if mp.any() else np.nan,
                            "mean_neg": x[mn, j].mean() if mn.any() else np.nan,
                            "diff_within": stratified_difference(x[mp, j], x[mn, j], cj[mp],
                                                                 cj[mn])})
    return pd.DataFrame(out)


def check_leaks(data: RallyData, ks=DEFAULT_KS, n_boot: int = 1000, seed: int = 0,
                stratify: bool = True, resolution: dict[str, float] | None = None
                ) -> pd.DataFrame:
    """`leak_auc` of `contact_kinematics`: the whole check on one `RallyData`."""
    return leak_auc(contact_kinematics(data, ks), n_boot=n_boot, seed=seed, stratify=stratify,
                    resolution=resolution)


def outside_band(table: pd.DataFrame, band=(0.4, 0.6),
                 min_pairs: int = MIN_READ_PAIRS) -> pd.Series:
    """Rows whose AUC lies outside [band[0], band[1]] and rests on at least `min_pairs`
    comparable pairs (NaN AUCs are not flagged; a table without ``n_pairs`` is read whole)."""
    lo, hi = band
    return ((table["auc"] < lo) | (table["auc"] > hi)) & ~thin_cells(table, min_pairs)


def thin_cells(table: pd.DataFrame, min_pairs: int = MIN_READ_PAIRS) -> pd.Series:
    """Rows whose AUC rests on fewer than `min_pairs` comparable pairs: too few to read (an
    AUC of 2 pairs is 0, 0.5 or 1 whatever the players do)."""
    if "n_pairs" not in table:
        return pd.Series(False, index=table.index)
    return table["n_pairs"].notna() & (table["n_pairs"] < min_pairs)


def interval_holds_half(table: pd.DataFrame) -> pd.Series:
    """Rows whose bootstrap interval [lo, hi] holds 0.5: no difference beyond the sampling
    noise (rows without an interval, ``n_boot=0``, are not)."""
    if "lo" not in table or "hi" not in table:
        return pd.Series(False, index=table.index)
    return (table["lo"] <= 0.5) & (table["hi"] >= 0.5)


def sure_leaks(table: pd.DataFrame, band=(0.4, 0.6),
               min_pairs: int = MIN_READ_PAIRS) -> pd.Series:
    """`outside_band` rows whose bootstrap interval also leaves out 0.5: outside the band and
    beyond the sampling noise. Where a sample leaves a cell few pairs, its AUC can fall outside
    the band by chance: 12 cells of the generator's over five 800-point seeds, on 13-1,643
    pairs at 0.30-0.73, every interval holding 0.5, and none outside on 10,000 points."""
    return outside_band(table, band, min_pairs) & ~interval_holds_half(table)


def render_leaks(table: pd.DataFrame, band=(0.4, 0.6), min_pairs: int = MIN_READ_PAIRS) -> str:
    """A markdown table of `leak_auc` rows, and a summary. Rows outside `band` are marked LEAK,
    ``unsure`` where their bootstrap interval holds 0.5, ``thin`` where the AUC rests on fewer
    than `min_pairs` comparable pairs (and is not counted as outside)."""
    flag = outside_band(table, band, min_pairs)
    unsure = flag & interval_holds_half(table)
    thin = outside_band(table, band, min_pairs=0) & thin_cells(table, min_pairs)
    fmt = lambda v, d=2: "-" if pd.isna(v) else f"{v:.{d}f}"  # noqa: E731
    pairs = table["n_pairs"] if "n_pairs" in table else pd.Series(np.nan, index=table.index)
    diff = table["diff_within"] if "diff_within" in table else pd.Series(np.nan, index=table.index)
    lines = ["| pair | role | feature | k | AUC [interval] | n_pos | n_neg | pairs | mean pos | "
             "mean neg | pos - neg within strata | |", "|" + "---|" * 12]
    for (_, row), bad, noisy, few, n_pairs, d in zip(table.iterrows(), flag, unsure, thin,
                                                     pairs, diff):
        mark = ("unsure" if noisy else "LEAK") if bad else ("thin" if few else "")
        lines.append(f"| {row['pair']} | {row['role']} | {row['feature']} | {row['k']} | "
                     f"{fmt(row['auc'], 3)} [{fmt(row['lo'])}, {fmt(row['hi'])}] | "
                     f"{row['n_pos']} | {row['n_neg']} | {fmt(n_pairs, 0)} | "
                     f"{fmt(row['mean_pos'])} | {fmt(row['mean_neg'])} | {fmt(d, 3)} | "
                     f"{mark} |")
    summary = f"\n{int(flag.sum())} of {len(table)} AUCs outside [{band[0]:g}, {band[1]:g}]"
    if unsure.any():
        summary += f" ({int(unsure.sum())} of them unsure: their 95 % interval holds 0.5)"
    if thin.any():
        summary += (f" ({int(thin.sum())} more outside on fewer than {min_pairs} comparable "
                    "pairs: too few to read, marked thin)")
    lines.append(summary + ".")
    return "\n".join(lines)
