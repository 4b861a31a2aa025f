"""Rally-end rules (`sportsngen.tennis.rally`) on hand-made ballistic tracks and on generated data.

Tracks are built here: a toss, then shots launched from wherever the ball is at each contact
time toward a landing point in a given flight time (gravity only, integrated at 1 ms, bounces
with restitution, optionally a net the ball rebounds from), sampled at 25 Hz. Players walk
between key points and stand beside the ball at their contacts. Default geometry: the server at
the +x end serving from the deuce court (y > 0) into the box x in [-6.4, 0], y in [-4.115, 0].
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import sportsngen.tennis.rally as rally_module
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.synth import generate_matches
from sportsngen.tennis.court import BALL_RADIUS_M, BASELINE_X_M, net_height_m
from sportsngen.tennis.rally import (
    CHECKS,
    MAX_RALLY_S,
    RallyTracker,
    analyse_rallies,
    awaiting_return,
    end_class,
)

G = 9.81
R = BALL_RADIUS_M
FPS = 25.0
STEP_S = 1e-3
STEPS_PER_FRAME = 40
TOSS_S = 0.8               # the serve is struck 0.8 s after the toss starts (at z = 2.66 m)
SERVE = (TOSS_S, (-5.0, -2.0), 0.6)      # a good serve down the middle of the deuce box
RETURN_AT = 1.7            # ... reached by the receiver 0.3 s after its bounce, at z ~ 1.3 m


def _launch(p: np.ndarray, target_xy, flight_s: float) -> np.ndarray:
    t = flight_s
    return np.array([(target_xy[0] - p[0]) / t, (target_xy[1] - p[1]) / t,
                     (R - p[2] + 0.5 * G * t * t) / t])


def ball_track(shots, duration_s: float, server_end: int = 1, net: bool = True):
    """(frames (n, 3), contacts [(t, xyz)]) of a toss then `shots` [(t_s, target_xy, flight_s)],
    in the frame where the server is at the +x end; mirrored (x, y -> -x, -y) for -1."""
    p = np.array([BASELINE_X_M - 0.25, 0.7, 1.0])
    v = np.array([0.0, 0.0, 6.0])
    pending, contacts, frames, rolling = list(shots), [], [], False
    for step in range(int(round(duration_s / STEP_S)) + 1):
        t = step * STEP_S
        if pending and t >= pending[0][0] - 1e-9:
            _, target, flight = pending.pop(0)
            contacts.append((t, p.copy()))
            v, rolling = _launch(p, target, flight), False
        if step % STEPS_PER_FRAME == 0:
            frames.append(p.copy())
        if rolling:
            speed = np.hypot(v[0], v[1])
            v[:2] *= max(speed - 2.0 * STEP_S, 0.0) / max(speed, 1e-9)
            new = p + v * STEP_S
        else:
            new = p + v * STEP_S + np.array([0.0, 0.0, -0.5 * G * STEP_S ** 2])
            v = v + np.array([0.0, 0.0, -G * STEP_S])
        if new[2] < R and v[2] < 0:
            new[2] = 2 * R - new[2]
            v[2], v[:2] = -0.75 * v[2], 0.8 * v[:2]
            if v[2] < 1.0:
                v[2], new[2], rolling = 0.0, R, True
        if net and np.sign(new[0]) != np.sign(p[0]):
            w = abs(p[0]) / (abs(p[0]) + abs(new[0]))
            if p[2] + w * (new[2] - p[2]) - R < net_height_m(p[1]):
                new[0] = np.sign(p[0]) * R
                v[0], v[1] = -0.1 * v[0], 0.1 * v[1]
        p = new
    out = np.array(frames)
    if server_end == -1:
        out[:, :2] *= -1
        contacts = [(t, c * np.array([-1, -1, 1])) for t, c in contacts]
    return out, contacts


def walk(keys, n: int) -> np.ndarray:
    """(n, 3) positions walking straight between key points [(t_s, (x, y))], z = 0."""
    t = np.arange(n) / FPS
    kt = [k[0] for k in keys]
    out = np.zeros((n, 3))
    for d in range(2):
        out[:, d] = np.interp(t, kt, [k[1][d] for k in keys])
    return out


def make_rally(shots, duration_s: float = 6.0, server_end: int = 1, net: bool = True,
               receiver_home=(-12.4, -1.0), server_after=None, receiver_after=None,
               reach_offset_m: float = 0.7) -> np.ndarray:
    """(n, 3, 3) [server, receiver, ball]. Players stand `reach_offset_m` toward the centre from
    the ball at their contacts; `*_after` (t_s, xy) keys are added after the last contact."""
    ball, contacts = ball_track(shots, duration_s, 1, net)
    n = len(ball)
    keys = [[(0.0, (BASELINE_X_M + 0.2, 0.8))], [(0.0, receiver_home)]]
    for k, (t, c) in enumerate(contacts):
        beside = (c[0], c[1] - np.sign(c[1]) * reach_offset_m if c[1] else c[1] + reach_offset_m)
        keys[k % 2].append((t, (BASELINE_X_M + 0.2, 0.8) if k == 0 else beside))
    for who, extra in ((0, server_after), (1, receiver_after)):
        if extra is not None:
            keys[who].append(extra)
    pos = np.stack([walk(keys[0], n), walk(keys[1], n), ball], axis=1)
    if server_end == -1:
        pos[..., :2] *= -1
    return pos


def judge(pos, server_end=1, side="deuce", serve_number=1, **kw) -> dict:
    """The tracker's results row for one track."""
    df = analyse_rallies(pos[None], [len(pos)], [server_end], [side], [serve_number], FPS, **kw)
    return df.iloc[0].to_dict()


def rally_return(ret, *more, **kw) -> np.ndarray:
    """Serve in, a return at RETURN_AT, then `more` shots."""
    return make_rally([SERVE, (RETURN_AT, *ret), *more], **kw)


GOOD_RETURN = ((8.0, 1.0), 1.0)          # bounces at t = 2.7 s, deep on the server's side
SERVER_REPLY_AT = 3.0
DROP = (SERVER_REPLY_AT, (-1.5, 0.0), 1.5)   # a drop shot: bounces twice before the baseline


def assert_clean(res: dict) -> None:
    assert res["realistic"], res["failed_checks"]
    assert res["failed_checks"] == []


# --- outcomes -------------------------------------------------------------------------------

def test_double_bounce_is_a_winner_for_the_hitter():
    pos = rally_return(GOOD_RETURN, DROP, receiver_after=(3.0, (-13.0, 2.0)))
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "winner", "unreached")
    assert res["n_shots"] == 3 and res["hitters"] == [0, 1, 0]
    # Decided at the second bounce: the first at (-1.5, 0) at t = 4.5 s, the next ~1.15 s later.
    assert len(res["bounce_frames"]) == 4
    assert res["bounces_m"][2] == pytest.approx([-1.5, 0.0], abs=0.03)
    assert abs(res["bounce_frames"][2] - 4.5 * FPS) <= 0.5
    assert res["end_frame"] == res["bounce_frames"][3]
    assert 5.5 * FPS < res["end_frame"] < 5.8 * FPS
    assert_clean(res)


def test_ball_out_loses_for_the_hitter():
    res = judge(rally_return(((14.0, 0.0), 1.0)))
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "error", "out")
    assert res["n_shots"] == 2
    assert res["bounces_m"][-1][0] == pytest.approx(14.0, abs=0.05)
    assert res["end_frame"] == round(2.7 * FPS)
    assert_clean(res)


def test_ball_into_the_net_loses_for_the_hitter():
    pos = rally_return(((3.0, 0.0), 0.5))    # crosses x = 0 at about 0.5 m: the net
    assert np.all(pos[round(RETURN_AT * FPS) + 1:, 2, 0] < 0.0)  # it never gets over
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "error", "net")
    assert res["n_shots"] == 2
    assert 2.05 * FPS <= res["end_frame"] <= 2.2 * FPS  # the net is reached ~0.4 s after 1.7 s
    assert_clean(res)


def test_ball_off_the_bottom_of_the_net_is_no_bounce():
    # A return driven down into the net 6 cm up, coming back off it and rising again a
    # little before it drops on the returner's side (as a generated return did): the net, and
    # no bounce past it.
    pos = rally_return(((3.0, 0.0), 0.5))
    k = round(RETURN_AT * FPS) + 1
    start = pos[k - 1, 2].copy()
    arrive = 9                                   # frames to the net, descending
    hit = np.array([-0.05, start[1], 0.06])
    for i in range(1, arrive + 1):               # straight in, falling faster near the net
        w = i / arrive
        pos[k - 1 + i, 2] = start + (hit - start) * np.array([w, w, w ** 1.5])
    p, v = hit.copy(), np.array([-1.5, 0.0, 1.8])
    for f in range(k + arrive, len(pos)):
        v[2] -= G / FPS
        p = p + v / FPS
        if p[2] < R:
            p[2], v[2], v[0] = R, 0.0, 0.7 * v[0]
        pos[f, 2] = p
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "error", "net")
    assert all(b[0] < 0.0 for b in res["bounces_m"][1:])   # nothing read past the net
    assert len(res["bounce_frames"]) == 1                 # the serve's bounce alone


def test_passing_shot_beyond_the_baseline_wins_before_its_second_bounce():
    fast = ((10.5, -3.0), 0.8)               # deep, away from the server who stands wide
    pos = rally_return(fast, server_after=(1.5, (12.5, 3.5)))
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (1, "winner", "unreached")
    assert res["n_shots"] == 2
    bounce = res["bounce_frames"][-1]
    assert res["bounces_m"][-1] == pytest.approx([10.5, -3.0], abs=0.05)
    assert bounce < res["end_frame"] <= bounce + 8   # passed 2 m behind the line, not bounced
    end = res["end_frame"]
    assert pos[end, 2, 0] > BASELINE_X_M + 2.0 and pos[end - 1, 2, 0] <= BASELINE_X_M + 2.0
    assert_clean(res)


def test_ace():
    pos = make_rally([SERVE], receiver_home=(-12.4, 3.0))
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "ace", "unreached")
    assert res["n_shots"] == 1 and res["hitters"] == [0]
    assert res["contact_frames"] == [round(TOSS_S * FPS)]
    assert res["contacts_m"][0] == pytest.approx([BASELINE_X_M - 0.25, 0.7, 2.661], abs=0.01)
    assert res["bounces_m"][0] == pytest.approx([-5.0, -2.0], abs=0.03)
    assert_clean(res)


@pytest.mark.parametrize("late", [0.5, 0.9, 0.905, 0.95, 0.99])
def test_a_fast_serve_struck_late_in_a_frame_interval_is_found(late):
    # A 200 km/h serve struck `late` of a frame after frame 20. At 0.9 the first frame after it
    # holds a sliver of the flight, 5.5 m/s along x: too small a share of the serve to be its
    # segment and too fast for a toss, so the rules had found no serve and stopped the rally
    # undecided (0.88-0.90 of a frame), and from 0.91 to 0.95 read the contact 0.11-0.17 m
    # nearer the net (real trackers' frames fall anywhere; the generator's serves at one phase).
    t = TOSS_S + late / FPS
    shots = [(t, (-6.0, -1.5), 0.32)]
    pos = make_rally(shots, receiver_home=(-12.4, 3.0))
    contact = ball_track(shots, 6.0)[1][0][1]
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (0, "ace", "unreached")
    assert res["n_shots"] == 1 and abs(res["contact_frames"][0] - t * FPS) <= 0.5 + 1e-9
    assert res["contacts_m"][0] == pytest.approx(contact, abs=0.05)
    assert_clean(res)


@pytest.mark.parametrize("still_at, frame, winner, reason, detail", [
    ((8.0, 1.0, R), 68, 1, "winner", "unreached"),   # dies where it lands: a good bounce
    ((5.0, 1.0, 1.0), 60, 0, "error", "out"),         # stopped in the air (a fence) before landing
    ((-0.3, 0.0, R), 60, 0, "error", "net")])         # lying at the net on the hitter's side
def test_ball_at_rest_decides(still_at, frame, winner, reason, detail):
    pos = rally_return(GOOD_RETURN)
    pos[frame:, 2] = still_at
    res = judge(pos)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (winner, reason, detail)
    assert res["n_shots"] == 2
    assert frame <= res["end_frame"] <= frame + 10


@pytest.mark.parametrize("serve_number, winner, reason", [(1, -1, "fault"),
                                                          (2, 1, "double_fault")])
def test_serve_into_the_wrong_box(serve_number, winner, reason):
    wrong = (TOSS_S, (-5.0, 2.0), 0.6)       # the ad box, from the deuce court
    res = judge(make_rally([wrong]), serve_number=serve_number)
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (winner, reason, "out")
    assert res["n_shots"] == 1
    assert res["end_frame"] == round((TOSS_S + 0.6) * FPS)
    assert_clean(res)
    # The same serve is good from the ad court.
    assert judge(make_rally([wrong]), side="ad")["end_reason"] == "ace"


def test_serve_long_and_serve_into_the_net_are_faults():
    long = judge(make_rally([(TOSS_S, (-8.0, -2.0), 0.7)]))
    assert (long["winner"], long["end_reason"], long["end_detail"]) == (-1, "fault", "out")
    low = judge(make_rally([(TOSS_S, (-2.0, -1.0), 0.3)]), serve_number=2)
    assert (low["winner"], low["end_reason"], low["end_detail"]) == (1, "double_fault", "net")


def test_results_do_not_depend_on_the_end():
    """The same rally played from the -x end (x and y mirrored) is judged the same."""
    shots = [SERVE, (RETURN_AT, *GOOD_RETURN), DROP]
    a = judge(make_rally(shots))
    b = judge(make_rally(shots, server_end=-1), server_end=-1)
    for key in ("winner", "end_reason", "end_detail", "end_frame", "n_shots", "contact_frames",
                "bounce_frames"):
        assert a[key] == b[key], key
    assert np.allclose(np.array(a["bounces_m"]), -np.array(b["bounces_m"]), atol=1e-6)


# --- realism checks -------------------------------------------------------------------------

def _through_net():
    return rally_return(((3.0, 0.0), 0.5), net=False)


def _through_ground():
    pos = rally_return(GOOD_RETURN)
    k = int(np.argmin(pos[30:45, 2, 2])) + 30    # the serve's bounce
    pos[k, 2, 2] = -0.3
    return pos


def _player_jump():
    pos = rally_return(GOOD_RETURN)
    pos[60:, 1, 0] -= 1.0                         # the receiver jumps 1 m in one frame
    return pos


def _ball_jump():
    pos = rally_return(GOOD_RETURN)
    pos[60, 2, 1] += 4.0                          # 100 m/s there and back
    return pos


def _out_of_reach():
    return make_rally([SERVE, (RETURN_AT, *GOOD_RETURN)], reach_offset_m=3.5)


def _serve_position():
    pos = make_rally([SERVE])
    pos[:, :, 0] -= 3.0                           # everything 3 m forward: served from inside
    return pos


def _no_serve():
    return make_rally([], duration_s=6.0)


BROKEN = {"through_net": _through_net, "through_ground": _through_ground,
          "position_jump": _player_jump, "contact_out_of_reach": _out_of_reach,
          "serve_position": _serve_position, "no_serve": _no_serve}


@pytest.mark.parametrize("check", list(BROKEN))
def test_each_realism_check_fires_on_a_broken_track(check):
    res = judge(BROKEN[check]())
    assert check in res["failed_checks"]
    assert not res["realistic"]
    assert res["ended"]


def test_ball_jump_and_duration_cap_fire():
    assert judge(_ball_jump())["failed_checks"] == ["position_jump"]
    res = judge(rally_return(GOOD_RETURN), max_duration_s=2.0)
    assert res["failed_checks"] == ["duration_cap"]
    assert (res["winner"], res["end_reason"], res["end_frame"]) == (-1, "none", 49)


def test_no_serve_stops_undecided():
    res = judge(_no_serve())
    assert (res["winner"], res["end_reason"], res["end_detail"]) == (-1, "none", "none")
    assert res["failed_checks"] == ["no_serve"] and res["n_shots"] == 0


def test_checks_stay_quiet_on_clean_tracks():
    clean = [rally_return(GOOD_RETURN, DROP),
             rally_return(((3.0, 0.0), 0.5)), make_rally([SERVE]),
             rally_return(((10.5, -3.0), 0.8), server_after=(1.5, (12.5, 3.5)))]
    for pos in clean:
        res = judge(pos)
        assert res["ended"] and res["realistic"] and res["failed_checks"] == []
    assert set(CHECKS) >= set(BROKEN) | {"duration_cap"}


# --- the batched tracker --------------------------------------------------------------------

def _scenarios():
    tracks = [rally_return(GOOD_RETURN, DROP),
              rally_return(((14.0, 0.0), 1.0)), make_rally([SERVE], receiver_home=(-12.4, 3.0)),
              rally_return(((3.0, 0.0), 0.5)), make_rally([(TOSS_S, (-5.0, 2.0), 0.6)]),
              _player_jump()]
    ends = [1, 1, 1, 1, -1, 1]
    tracks[4] = make_rally([(TOSS_S, (-5.0, 2.0), 0.6)], server_end=-1)
    return tracks, np.array(ends), np.array(["deuce", "deuce", "deuce", "ad", "deuce", "deuce"]), \
        np.array([1, 2, 1, 1, 2, 1])


def test_batched_tracker_with_select_matches_one_by_one():
    tracks, ends, sides, serves = _scenarios()
    single = [judge(p, e, s, n) for p, e, s, n in zip(tracks, ends, sides, serves)]
    n = max(len(p) for p in tracks)
    pos = np.stack([np.concatenate([p, np.repeat(p[-1:], n - len(p), axis=0)]) for p in tracks])
    tracker = RallyTracker(ends, sides, serves, FPS)
    order = np.arange(len(tracks))                 # original index of each tracker row
    collected = {}
    for t in range(n):
        ended = tracker.update(pos[order, t])
        if t in (45, 70, 90) or ended.all():
            # Compact as a rollout does: harvest the ended rallies, keep the rest reversed.
            res = tracker.results()
            for row in np.flatnonzero(ended):
                collected[int(order[row])] = res.iloc[row].to_dict()
            keep = np.flatnonzero(~ended)[::-1]
            tracker.select(keep)
            order = order[keep]
            if len(order) == 0:
                break
    assert sorted(collected) == list(range(len(tracks)))
    for i, one in enumerate(single):
        for key in ("ended", "end_frame", "winner", "end_reason", "end_detail", "n_shots",
                    "contact_frames", "hitters", "bounce_frames", "failed_checks"):
            assert collected[i][key] == one[key], (i, key)
    # (the fourth is the net rally judged as served from the ad court: a fault into the wrong box)
    assert [one["end_reason"] for one in single] == ["winner", "error", "ace", "fault",
                                                     "double_fault", "winner"]


def test_update_validates_and_leaves_inactive_rallies_alone():
    tracks, ends, sides, serves = _scenarios()
    tr = RallyTracker(ends[:2], sides[:2], serves[:2], FPS)
    with pytest.raises(ValueError, match="shape"):
        tr.update(np.zeros((3, 3, 3)))
    tr.update(np.stack([tracks[0][0], tracks[1][0]]), active=np.array([True, False]))
    assert tr.seen.tolist() == [1, 0]
    with pytest.raises(ValueError, match="server_end"):
        RallyTracker([0], ["deuce"], [1], FPS)
    with pytest.raises(ValueError, match="side"):
        RallyTracker([1], ["middle"], [1], FPS)


def test_end_class():
    assert end_class("forced_error") == "error"
    assert end_class(["ace", "unforced_error", "fault"]).tolist() == ["ace", "error", "fault"]
    with pytest.raises(ValueError, match="unknown"):
        end_class("let")


# --- agreement with the generator -----------------------------------------------------------

def test_agreement_with_the_generator(monkeypatch):
    data = generate_matches(["Roger Federer", "Rafael Nadal"], "hard", 80, seed=1, workers=1)
    selects = []
    select = RallyTracker.select
    monkeypatch.setattr(RallyTracker, "select",
                        lambda self, idx: selects.append(len(idx)) or select(self, idx))
    res = analyse_rally_data(data)
    # The batch was compacted as its rallies ended, and reads exactly as stepped whole.
    assert len(selects) >= 3 and selects == sorted(selects, reverse=True)
    n_selects = len(selects)
    monkeypatch.setattr(rally_module, "MIN_COMPACT_RALLIES", 10 ** 9)
    pd.testing.assert_frame_equal(analyse_rally_data(data), res, check_exact=True)
    assert len(selects) == n_selects
    r = data.rallies.set_index("rally_id").loc[res.index]
    assert len(res) >= 100
    winner = np.where(r["winner"] == "", -1, np.where(r["winner"] == r["server"], 0, 1))
    n_shots = data.shots.groupby("rally_id").size().reindex(res.index, fill_value=0)
    # Measured with this seed: 109 rallies, every winner, class, detail and shot count agree
    # (2038 rallies in scripts/check_rally_rules.py: 99.5 %, the rest mostly capped at the
    # former 30 s).
    assert (res["winner"] == winner).mean() >= 0.97
    assert (res["end_reason"] == end_class(r["end_reason"].to_numpy(str))).mean() >= 0.97
    assert (res["end_detail"] == r["end_detail"]).mean() >= 0.95
    assert (res["n_shots"] == n_shots).mean() >= 0.95
    assert res["ended"].all()


def test_agreement_with_the_generator_whose_serves_fall_anywhere_in_a_frame(monkeypatch):
    # Real trackers' frames fall anywhere in a serve; the generator's fall at one phase unless
    # told otherwise. On these points a serve struck 0.9 of a frame after its frame had left
    # the rules without a serve (rally 47: not ended).
    from sportsngen.synth import cycle

    monkeypatch.setattr(cycle, "SERVE_PHASE", True)
    data = generate_matches(["Roger Federer", "Rafael Nadal"], "hard", 80, seed=1, workers=1)
    res = analyse_rally_data(data)
    r = data.rallies.set_index("rally_id").loc[res.index]
    winner = np.where(r["winner"] == "", -1, np.where(r["winner"] == r["server"], 0, 1))
    assert len(res) >= 100 and res["ended"].all()
    assert (res["winner"] == winner).mean() >= 0.97
    assert (res["end_reason"] == end_class(r["end_reason"].to_numpy(str))).mean() >= 0.97


def test_a_long_clay_rally_of_the_generator_is_judged_to_its_end_not_capped():
    # Djokovic v Murray on clay, seed 2: rally 28 lasts 40 s (28 shots; the generator's clay
    # rallies last over 30 s 1.06 % of the time). At the former default cap of 30 s it was
    # stopped undecided after 22 shots and flagged, and statistics that drop flagged points lost
    # it; the default cap (`MAX_RALLY_S`) judges it as the generator recorded it.
    data = generate_matches(["Novak Djokovic", "Andy Murray"], "clay", 40, seed=2, workers=1)
    rally = data.subset([28])
    res = analyse_rally_data(rally).iloc[0]
    assert (res["end_reason"], res["end_detail"], res["n_shots"]) == ("winner", "unreached", 28)
    assert res["winner"] == 1 and res["realistic"] and res["failed_checks"] == []
    assert res["end_frame"] / data.fps > 30.0 and MAX_RALLY_S >= 90.0
    capped = analyse_rally_data(rally, max_duration_s=30.0).iloc[0]
    assert (capped["end_reason"], capped["n_shots"], capped["failed_checks"]) == \
        ("none", 22, ["duration_cap"])


def test_the_return_is_awaited_from_the_serve_until_the_receiver_strikes():
    """`awaiting_return` on the tracker's count: before the serve no, between the serve and the
    return yes, after the return no (the rollout's returns' tables and reaches read it)."""
    pos = rally_return(GOOD_RETURN)
    tracker = RallyTracker([1], ["deuce"], [1], FPS)
    seen = []
    for k in range(len(pos)):
        tracker.update(pos[k][None])
        seen.append(bool(awaiting_return(tracker.n_shots)[0]))
    serve_f, return_f = round(TOSS_S * FPS), round(RETURN_AT * FPS)
    assert not any(seen[:serve_f])
    assert all(seen[serve_f + 3:return_f])
    assert not any(seen[return_f + 3:])
    assert awaiting_return(np.array([0, 1, 2, 3])).tolist() == [False, True, False, False]
