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
        self.n_shots = np.full(n, 3)                        # a rally ball
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
    rule = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS, accel_mps2=0.0)
    late, role, unit, along, least, cap = rule.late(np.arange(3), pos, vel)
    assert torch.equal(least[0], along[0])              # no `accel_mps2`: his own speed
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
    fresh = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS,
                        accel_mps2=0.0).late(sub, pos[sub], vel[sub])
    for a, b in zip(again, fresh):
        assert torch.equal(a, b)


def test_once_his_tries_run_out_a_late_player_holds_his_speed_toward_the_ball():
    pos, vel, hist = _state([[-12.0, -2.0], [-12.0, 3.0], [-12.0, -2.0]],
                            [[1.0, 2.0], [0.0, 2.0], [1.0, 2.0]])
    rows = np.arange(3)
    rule = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS, accel_mps2=0.0)
    late, _, unit, along, _, _ = rule.late(rows, pos, vel, frame=50)
    assert late.tolist() == [True, False, True]
    # Row 0 stops, row 1 (not late) stops, row 2 runs faster than before.
    nxt = _moved(pos, [[0.0, 0.0], [0.0, 0.0], [2.0, 4.0]])
    out = rule.settle(rows, pos, nxt)
    step = (out[0, 1, :2] - pos[0, 1, :2]) * FPS
    u = unit[0]
    assert (step * u).sum().item() == pytest.approx(along[0].item(), abs=1e-4)
    across = torch.tensor([-u[1], u[0]])
    assert (step * across).sum().item() == pytest.approx(0.0, abs=1e-4)  # the model's: 0
    assert torch.equal(out[1:], nxt[1:]) and torch.equal(out[0, [0, 2]], nxt[0, [0, 2]])
    assert rule.held == 1
    # A row not read this frame, or the rule without `hold`, leaves the draw alone.
    fresh = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS)
    assert torch.equal(fresh.settle(rows, pos, nxt), nxt)
    off = KeepChasing(_Tracker(hist, np.full(3, 10)), fps=FPS, hold=False)
    off.late(rows, pos, vel, frame=50)
    assert torch.equal(off.settle(rows, pos, nxt), nxt)


def test_with_an_acceleration_a_late_player_must_speed_up_toward_the_ball():
    pos, vel, hist = _state([[-12.0, -2.0], [-12.0, 3.0]], [[0.0, 2.0], [0.0, 2.0]])
    rows = np.arange(2)
    rule = KeepChasing(_Tracker(hist, np.full(2, 10)), fps=FPS, accel_mps2=6.0)
    late, _, unit, along, least, _ = rule.late(rows, pos, vel, frame=50)
    assert late.tolist() == [True, False]
    assert least[0].item() == pytest.approx(along[0].item() + 6.0 / FPS, abs=1e-5)
    u = unit[0, 1].item()                          # nearly all along y
    same = rule.accept(rows, 50, pos, _moved(pos, [[0.0, 2.0], [0.0, 2.0]]), vel)
    assert same.tolist() == [False, True]         # holding his speed is not enough now
    faster = rule.accept(rows, 50, pos, _moved(pos, [[0.0, 2.0 + 7.0 / FPS / u]] * 2), vel)
    assert faster.tolist() == [True, True]
    out = rule.settle(rows, pos, _moved(pos, [[0.0, 0.0], [0.0, 0.0]]))
    step = (out[0, 1, :2] - pos[0, 1, :2]) * FPS
    assert (step * unit[0]).sum().item() == pytest.approx(least[0].item(), abs=1e-4)
    # What he needs caps it: standing 5 m from the ball's line, with any acceleration he must
    # only reach (within 1 m of) its nearest playable point in the time the ball takes there.
    from sportsngen.model.forecast import ball_forecast, nearest_playable
    pos2, vel2, hist2 = _state([[-12.0, -2.0]], [[0.0, 0.0]])
    keen = KeepChasing(_Tracker(hist2, np.full(1, 10)), fps=FPS, accel_mps2=1000.0)
    late2, _, _, along2, least2, _ = keen.late(np.arange(1), pos2, vel2)
    prev = torch.as_tensor((hist2[:, -2, 2] - hist2[:, -3, 2]) * FPS, dtype=torch.float32)
    track = ball_forecast(pos2[:, 2], vel2[:, 2], prev, FPS, path=True)[1]
    near = nearest_playable(track, pos2[:, 1:2, :2])[0, 0]
    wanted = (torch.linalg.vector_norm(near[:2]) - 1.0) / near[2]
    assert late2[0] and along2[0].item() == 0.0
    assert least2[0].item() == pytest.approx(wanted.item(), rel=1e-5) and wanted.item() < 7.0
    # A serve (one contact so far) asks for no acceleration from the shot 2 on default.
    tracker = _Tracker(hist, np.full(2, 10))
    tracker.n_shots[:] = 1
    serve = KeepChasing(tracker, fps=FPS, accel_mps2=6.0).late(rows, pos, vel)
    assert serve[0][0] and torch.equal(serve[4][0], serve[3][0])
    with pytest.raises(ValueError, match="accel_mps2"):
        KeepChasing(rule.tracker, accel_mps2=-1.0)


def _high_bounce_state(receiver_xy):
    """A ball coming down steeply at the receiver's end (bouncing about 9.7 m from the net and
    rising 2.6 m after): the frame (B, 3, 3), velocities and a tracker's history, its last
    frames under gravity."""
    b = len(receiver_xy)
    pos, vel = torch.zeros(b, 3, 3), torch.zeros(b, 3, 3)
    pos[:, 0, :2] = torch.tensor([12.0, 0.0])
    pos[:, 1, :2] = torch.as_tensor(receiver_xy, dtype=torch.float32)
    pos[:, 2] = torch.tensor([-3.0, 3.0, 4.0])
    vel[:, 2] = torch.tensor([-12.0, 0.0, -4.0])
    hist = np.zeros((b, 6, 3, 3))
    for k in range(6):
        t = -(5 - k) / FPS
        hist[:, k] = pos.numpy() + t * vel.numpy()
        hist[:, k, 2, 2] += -0.5 * 9.81 * t * t
    return pos, vel, hist


def test_for_a_high_bounce_the_player_runs_to_where_it_is_at_a_comfortable_height():
    # A receiver standing where the ball, risen from its bounce, passes just under 2.3 m is
    # not late for the nearest playable ball (0.2-2.3 m); with the band (0.5-1.4 m) his ball
    # is where the flight is within it after the bounce, more than his 1 m from him, and
    # standing still he is late for it. A ball that bounces low is read as before.
    from sportsngen.model.forecast import ball_forecast, nearest_playable
    pos, vel, hist = _high_bounce_state([[0.0, 0.0]])
    prev = torch.as_tensor((hist[:, -2, 2] - hist[:, -3, 2]) * FPS, dtype=torch.float32)
    track = ball_forecast(pos[:, 2], vel[:, 2], prev, FPS, path=True)[1]
    z = track[0, :, 2]
    bounce = int(torch.argmin(z))
    assert z[bounce:].max() > 2.3
    rise = torch.nonzero((z > 1.8) & (z < 2.3)
                         & (torch.arange(len(z)) > bounce)).squeeze(1)
    pos[0, 1, :2] = track[0, int(rise[-1]), :2] + torch.tensor([0.0, 0.2])
    hist[:, :, 1] = pos[:, 1].numpy()
    rows = np.arange(1)
    plain = KeepChasing(_Tracker(hist, np.full(1, 10)), fps=FPS)
    banded = KeepChasing(_Tracker(hist, np.full(1, 10)), fps=FPS, band_m=(0.5, 1.4))
    assert not plain.late(rows, pos, vel)[0][0]
    late, _, unit, _, _, _ = banded.late(rows, pos, vel)
    post = track.clone()
    post[0, : bounce + 1, 2] = -1.0
    near = nearest_playable(post, pos[:, 1:2, :2], (0.5, 1.4))[0, 0]
    assert late[0] and torch.linalg.vector_norm(near[:2]).item() > 1.0
    torch.testing.assert_close(unit[0], near[:2] / torch.linalg.vector_norm(near[:2]))
    # The groundstroke of the other tests bounces low: the band changes nothing.
    pos2, vel2, hist2 = _state([[-12.0, -2.0], [-12.0, 3.0]], [[0.0, 2.0], [0.0, 2.0]])
    a = KeepChasing(_Tracker(hist2, np.full(2, 10)), fps=FPS, band_m=(0.5, 1.4))
    b = KeepChasing(_Tracker(hist2, np.full(2, 10)), fps=FPS)
    for x, y in zip(a.late(np.arange(2), pos2, vel2), b.late(np.arange(2), pos2, vel2)):
        torch.testing.assert_close(x, y)
    with pytest.raises(ValueError, match="band_m"):
        KeepChasing(plain.tracker, band_m=(1.4, 0.5))


def test_the_rollout_settles_the_rows_whose_redraws_all_slow():
    from sportsngen.sim.constraints import AllOf
    from sportsngen.sim.frame_draws import redraw_rejected

    pos, vel, hist = _state([[-12.0, -2.0], [-12.0, 3.0]], [[0.0, 2.0], [0.0, 2.0]])
    stop = _moved(pos, [[0.0, 0.0], [0.0, 0.0]])

    class Braking:                               # every draw: both receivers stand still
        calls = 0

        def sample_next(self, h, pos_m, *args):
            Braking.calls += 1
            return stop[: len(pos_m)].clone()

    rule = AllOf(KeepChasing(_Tracker(hist, np.full(2, 10)), fps=FPS, accel_mps2=0.0))
    rows = np.arange(2)
    h = torch.zeros(2, 4)
    out, drawn, strike = redraw_rejected(Braking(), rule, rows, 50, h, pos, vel, vel, stop.clone(),
                                         0.9, 0.9, None)
    assert drawn.tolist() == [3, 0] and Braking.calls == 3 and not strike.any()
    speed = torch.linalg.vector_norm(out[:, 1, :2] - pos[:, 1, :2], dim=-1) * FPS
    assert speed[0].item() == pytest.approx(2.0, abs=0.05) and speed[1].item() == 0.0


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


def test_the_simulator_hands_the_high_ball_band_to_the_rule(tiny_model_file, monkeypatch):
    import sportsngen.sim.simulator as simulator
    from sportsngen.sim import Simulator
    from sportsngen.sim.constraints import HIGH_BALL_BAND_M

    bands = []

    class Recording(KeepChasing):
        def __init__(self, tracker, **kw):
            bands.append(kw.get("band_m"))
            super().__init__(tracker, **kw)

    monkeypatch.setattr(simulator, "KeepChasing", Recording)
    for high in (True, False):
        sim = Simulator.from_pretrained(tiny_model_file, max_duration_s=0.5, keep_chasing=True,
                                        chase_high_balls=high)
        assert sim.chase_high_balls is high
        sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 2, seed=0)
    assert bands == [HIGH_BALL_BAND_M, None]
    # Without keep_chasing there is no rule to hand it to.
    Simulator.from_pretrained(tiny_model_file, max_duration_s=0.5,
                              chase_high_balls=True).simulate_points(
        "Roger Federer", "Rafael Nadal", "hard", 2, seed=0)
    assert len(bands) == 2


def test_a_late_player_is_not_asked_beyond_his_own_top_speed():
    # Two late receivers running toward the ball at 5.9 m/s: one's top speed 6.0 m/s, the
    # other's the rule's 7.0.
    pos, vel, hist = _state([[-12.0, -4.0], [-12.0, -4.0]], [[0.0, 5.9], [0.0, 5.9]])
    rows = np.arange(2)
    rule = KeepChasing(_Tracker(hist, np.full(2, 10)), fps=FPS, accel_mps2=6.0)
    rule.max_speed_rows_mps = np.array([[6.5, 6.0], [6.5, 9.0]])   # server, receiver
    late, role, unit, along, least, cap = rule.late(rows, pos, vel)
    assert late.tolist() == [True, True] and role.tolist() == [1, 1]
    assert cap.tolist() == pytest.approx([6.0, 7.0])
    assert least[0].item() == pytest.approx(6.0)                 # his own cap
    assert least[1].item() == pytest.approx(along[1].item() + 6.0 / FPS)
    # At his top speed he is running flat out: the rule leaves him; the other is asked on.
    at_top = vel.clone()
    at_top[:, 1, :2] = unit * 6.0
    rule2 = KeepChasing(_Tracker(hist, np.full(2, 10)), fps=FPS, accel_mps2=6.0)
    rule2.max_speed_rows_mps = rule.max_speed_rows_mps
    slower = rule2.accept(rows, 50, pos, _moved(pos, [[0.0, 5.0], [0.0, 5.0]]), at_top)
    assert slower.tolist() == [True, False]


@pytest.mark.parametrize("band_m", [None, (0.5, 1.4)])
def test_the_compiled_reading_is_the_torch_one(monkeypatch, band_m):
    """`constraint_kernel.chase_rows` against the rule's torch reading, over balls flying
    low, high and bouncing toward receivers standing and running all over their end."""
    from sportsngen.sim import constraints

    g = torch.Generator().manual_seed(8)
    n = 3000
    pos, vel = torch.zeros(n, 3, 3), torch.zeros(n, 3, 3)
    pos[:, 0, :2] = torch.tensor([12.0, 0.0])
    pos[:, 1, 0] = torch.empty(n).uniform_(-15, -1, generator=g)
    pos[:, 1, 1] = torch.empty(n).uniform_(-6, 6, generator=g)
    vel[:, 1, :2] = torch.randn(n, 2, generator=g) * 3
    pos[:, 2, 0] = torch.empty(n).uniform_(-4, 10, generator=g)
    pos[:, 2, 1] = torch.empty(n).uniform_(-4, 4, generator=g)
    pos[:, 2, 2] = torch.empty(n).uniform_(0.3, 4.5, generator=g)
    vel[:, 2, 0] = torch.empty(n).uniform_(-35, -8, generator=g)
    vel[:, 2, 1] = torch.randn(n, generator=g) * 3
    vel[:, 2, 2] = torch.empty(n).uniform_(-8, 6, generator=g)
    hist = np.zeros((n, 6, 3, 3))
    for k in range(6):
        s = -(5 - k) / FPS
        hist[:, k] = pos.numpy() + s * vel.numpy()
        hist[:, k, 2, 2] += -0.5 * 9.81 * s * s
    tracker = _Tracker(hist, np.full(n, 10))
    tracker.n_bounces[::3] = 1
    tracker.n_shots[::4] = 1                                   # serves: no acceleration
    rule = KeepChasing(tracker, fps=FPS, band_m=band_m)
    rule.max_speed_rows_mps = np.full((n, 2), 6.5)
    rows = np.arange(n)
    got = rule.late(rows, pos, vel)
    with monkeypatch.context() as m:
        m.setattr(constraints, "kernel_inputs", lambda *t: False)
        want = rule.late(rows, pos, vel)
    assert (got[0] != want[0]).sum() <= 3                     # float32 rounding at a threshold
    assert 0.1 < want[0].float().mean() < 0.9
    same = got[0] == want[0]
    for a, b in zip(got[1:], want[1:]):
        assert (a[same] - b[same]).abs().max() < 1e-3


def test_the_numpy_verdict_is_the_torch_one(monkeypatch):
    """`accept`'s numpy lines against its torch ones, on the same reading: the same verdict
    for every row, late or not, slowing or not, fresh or out of tries."""
    from sportsngen.sim import constraints

    g = torch.Generator().manual_seed(9)
    n = 2000
    pos, vel, hist = _state(np.c_[-np.linspace(13.0, 6.0, n), np.linspace(-5.0, 5.0, n)],
                            torch.randn(n, 2, generator=g).numpy() * 4)
    moves = torch.randn(n, 2, generator=g).numpy() * 6
    nxt = _moved(pos, moves)
    verdicts = []
    for fast in (True, False):
        rule = KeepChasing(_Tracker(hist, np.full(n, 10)), fps=FPS, accel_mps2=6.0)
        rule._tries[::5] = rule.max_tries                      # out of tries: accepted
        with monkeypatch.context() as m:
            if not fast:
                m.setattr(constraints, "kernel_inputs", lambda *t: False)
            verdicts.append(rule.accept(np.arange(n), None, pos, nxt, vel))
    assert torch.equal(verdicts[0], verdicts[1])
    assert 0.05 < (~verdicts[0]).float().mean() < 0.95
