"""The rule that a player late for the ball does not slow down (`sim.constraints.KeepChasing`)
and the rally tracker's reading of the frames since the last contact."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sportsngen.sim.constraints import KeepChasing
from sportsngen.tennis.rally import RallyTracker

FPS = 25.0


class _Tracker:
    """What the rule reads of a rally tracker, for rallies whose last hitter is the server."""

    def __init__(self, pos_hist: np.ndarray, since: np.ndarray):
        n = len(since)
        self.ended = np.zeros(n, dtype=bool)
        self.hitter = np.zeros(n, dtype=np.int64)          # the server struck last
        self.n_bounces = np.zeros(n, dtype=np.int64)
        self.seen = np.full(n, 50)
        self._hist, self._since = pos_hist, np.asarray(since)

    def frames_since_contact(self, rows):
        return self._since[np.asarray(rows)]

    def recent_frames(self, rows):
        return self._hist[np.asarray(rows)]


def _state(receiver_xy, receiver_vel):
    """A groundstroke from the server's baseline (+x) flying to the receiver's end (-x) at
    25 m/s along y = 3: positions and velocities of the frame (B, 3, 3) and a tracker."""
    b = len(receiver_xy)
    pos = torch.zeros(b, 3, 3)
    vel = torch.zeros(b, 3, 3)
    pos[:, 0, :2] = torch.tensor([12.0, 0.0])
    pos[:, 1, :2] = torch.as_tensor(receiver_xy, dtype=torch.float32)
    vel[:, 1, :2] = torch.as_tensor(receiver_vel, dtype=torch.float32)
    pos[:, 2] = torch.tensor([6.0, 3.0, 1.2])
    vel[:, 2] = torch.tensor([-25.0, 0.0, 2.0])
    hist = np.zeros((b, 6, 3, 3))
    for k in range(6):                       # the ball's last frames: the same flight, no spin
        hist[:, k] = pos.numpy() - (5 - k) * vel.numpy() / FPS
    return pos, vel, hist


def _moved(pos, step_xy):
    nxt = pos.clone()
    nxt[:, 1, :2] += torch.as_tensor(step_xy, dtype=torch.float32) / FPS
    return nxt


def test_a_late_player_may_not_slow_down_toward_the_ball():
    # Receivers on their baseline: one 5 m from the ball's line (late, running toward it at
    # 2 m/s), one on it (not late), one late but flat out (7.5 m/s).
    pos, vel, hist = _state([[-12.0, -2.0], [-12.0, 3.0], [-12.0, -2.0]],
                            [[0.0, 2.0], [0.0, 2.0], [0.0, 7.5]])
    rule = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS)
    late, role, unit, along = rule.late(np.arange(3), pos, vel)
    assert late.tolist() == [True, False, False]
    assert role.tolist() == [1, 1, 1]
    assert unit[0, 1].item() > 0.95 and along[0].item() == pytest.approx(2.0 * unit[0, 1].item())
    rows = np.arange(3)
    slower = rule.accept(rows, 50, pos, _moved(pos, [[0.0, 1.0], [0.0, 1.0], [0.0, 7.0]]), vel)
    assert slower.tolist() == [False, True, True]
    faster = rule.accept(rows, 50, pos, _moved(pos, [[0.0, 2.5], [0.0, 0.0], [0.0, 8.0]]), vel)
    assert faster.tolist() == [True, True, True]
    # Away from the ball: rejected for the late one.
    away = rule.accept(rows, 50, pos, _moved(pos, [[0.0, -1.0], [0.0, -1.0], [0.0, -1.0]]), vel)
    assert away.tolist() == [False, True, True]
    # Judged `max_tries` (3) times in this frame, the late row's next draw stands.
    assert rule.accept(rows, 50, pos, _moved(pos, [[0.0, -1.0]] * 3), vel).all()
    assert not rule.accept(rows, 51, pos, _moved(pos, [[0.0, -1.0]] * 3), vel)[0]
    # A frame's redraws ask for some of its rows again: read from the frame's first reading,
    # the same as read afresh.
    rule.late(rows, pos, vel, frame=7)
    sub = np.array([2, 0])
    again = rule.late(sub, pos[sub], vel[sub], frame=7)
    fresh = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS).late(sub, pos[sub], vel[sub])
    for a, b in zip(again, fresh):
        assert torch.equal(a, b)


def test_before_his_reaction_time_and_after_the_ball_passes_the_rule_is_silent():
    pos, vel, hist = _state([[-12.0, -2.0]] * 2, [[0.0, 2.0]] * 2)
    tracker = _Tracker(hist, np.array([2, 10]))
    tracker.n_bounces[1] = 2                       # the ball has bounced twice: the point is over
    rule = KeepChasing(tracker, fps=FPS)
    stop = _moved(pos, [[0.0, 0.0], [0.0, 0.0]])
    assert rule.accept(np.arange(2), 50, pos, stop, vel).tolist() == [True, True]
    assert not rule.late(np.arange(2), pos, vel)[0].any()
    # Without velocities (a constraint asked without them) nothing is judged.
    assert rule.accept(np.arange(2), 50, pos, stop, None).all()
    with pytest.raises(ValueError, match="positive"):
        KeepChasing(tracker, reach_m=0.0)


def test_the_tracker_counts_the_frames_since_the_last_contact(federer_points_and_head_model):
    data = federer_points_and_head_model[0]
    frames = data.frames.sort_values(["rally_id", "frame"])
    rallies = data.rallies.set_index("rally_id")
    checked = 0
    for rid, g in frames.groupby("rally_id"):
        obj = {o: d[["x", "y", "z"]].to_numpy(float) for o, d in g.groupby("object")}
        r = rallies.loc[rid]
        track = np.stack([obj[r["server"]], obj[r["receiver"]], obj["ball"]], axis=1)
        def tracker(r=r):
            return RallyTracker(np.array([r["server_end"]]), np.array([r["side"]]),
                                np.array([r["serve_number"]]), FPS, 60.0)
        whole = tracker()
        for k in range(len(track)):
            whole.update(track[k][None])
        c = whole.contact_frame[0, :whole.n_shots[0]]
        if len(c) < 2 or c[1] + 10 >= whole.end_frame[0]:
            continue
        t = tracker()
        assert t.frames_since_contact(np.array([0]))[0] >= 10 ** 6
        for k in range(c[1] + 11):                 # frames 0 .. contact + 10
            t.update(track[k][None])
        assert t.n_shots[0] == 2
        assert t.frames_since_contact(np.array([0]))[0] == 10
        np.testing.assert_array_equal(t.recent_frames(np.array([0]))[0, -1], track[c[1] + 10])
        checked += 1
        if checked >= 5:
            break
    assert checked >= 1
