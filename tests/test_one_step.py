"""Frames drawn one step from the record, and the server's coupling to his serve's speed."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import DiagnosticsSetup, serve_strike_frames, truth_points
from sportsngen.eval.one_step import (
    COUPLING_AFTER_FRAMES,
    SERVER_SLOT,
    one_step_frames,
    paced_serves,
    server_pace_response,
    server_serve_coupling,
)
from sportsngen.model.inputs import BALL
from tests.test_shot_branches import _Replay


class _ReplayOneStep(_Replay):
    """The record replayed, noting whether event labels were asked for (the draws leave them
    out) and, if given, the server's frame `frame` of each rally replaced by
    `server(rally_id, track)`."""

    def __init__(self, truth: RallyData, frames: pd.Series | None = None, server=None):
        super().__init__(truth)
        self.frames, self.server, self.seen_events = frames, server, []

    def simulate_rallies(self, plan, seed, init_pos_m, max_duration_s, forced_pos_m=None,
                         init_frames=None, label_events=True):
        self.seen_events.append(label_events)
        out = super().simulate_rallies(plan, seed, init_pos_m, max_duration_s, forced_pos_m,
                                       init_frames)
        if self.server is None:
            return out
        frames = out.frames.copy()
        servers = out.rallies.set_index("rally_id")["server"]
        for new_id, init, k in zip(plan["rally_id"], init_pos_m, init_frames):
            rid = next(r for r, t in self.tracks.items() if np.array_equal(t[:k], init[:k]))
            mine = frames["rally_id"] == new_id
            at = mine & (frames["frame"] == frames.loc[mine, "frame"].min() + k) & \
                (frames["object"] == servers[new_id])
            assert at.sum() == 1
            frames.loc[at, ["x", "y"]] = self.server(rid, self.tracks[rid], k)
        return RallyData(frames, out.rallies, out.shots, fps=out.fps)


@pytest.fixture(scope="module")
def truth():
    return truth_points(DiagnosticsSetup(n_points=40, seed=5))


def test_a_replay_draws_the_records_frames_and_its_coupling(truth):
    frames = serve_strike_frames(truth) + COUPLING_AFTER_FRAMES
    sim = _ReplayOneStep(truth)
    drawn = one_step_frames(sim, truth, frames, draws=3)
    assert len(drawn) > 20
    for rid, d in drawn.items():
        assert d.shape == (3, 3, 3)
        np.testing.assert_allclose(d, np.repeat(sim.tracks[rid][None, frames[rid]], 3, 0))
    assert sim.seen_events == [False]
    table = server_serve_coupling(sim, truth, draws=2)
    assert table["serve_number"].tolist() == [1, 2]
    np.testing.assert_allclose(table["model_corr"], table["record_corr"])
    np.testing.assert_allclose(table["model_slope"], table["record_slope"], atol=1e-9)
    np.testing.assert_allclose(table["model_median_mps"], table["record_median_mps"])
    assert (table["record_median_mps"] > 0.5).all()      # the servers are running back
    with pytest.raises(ValueError, match="draws"):
        one_step_frames(sim, truth, frames, draws=0)


def test_a_server_slower_after_faster_serves_is_read_as_a_full_negative_coupling(truth):
    serves = truth.shots[truth.shots["shot_index"] == 0].set_index("rally_id")["speed_mps"]

    def server(rid, track, k):
        # He steps 100 / (serve's speed) m/s along x from his frame before (about 2 m/s).
        before = track[k - 1, SERVER_SLOT, :2]
        return before + np.array([100.0 / serves[rid] / 25.0, 0.0])

    sim = _ReplayOneStep(truth, server=server)
    table = server_serve_coupling(sim, truth, draws=1)
    assert (table["model_corr"] < -0.99).all()       # a rank or two tied at 1 mm/s
    assert (table["model_slope"] < 0).all()
    # His speed is 100 / serve speed (m/s): the slope over the serves is that curve's.
    drawn = one_step_frames(_ReplayOneStep(truth), truth,
                            serve_strike_frames(truth) + COUPLING_AFTER_FRAMES, draws=1)
    number = truth.rallies.set_index("rally_id")["serve_number"]
    for n, row in table.set_index("serve_number").iterrows():
        sp = serves[[r for r in drawn if number[r] == n]]
        expected = np.polyfit(sp, 100.0 / sp, 1)[0] * 10.0
        assert row["model_slope"] == pytest.approx(expected, rel=5e-3)   # float32, 1 mm/s
    # The record's servers do not slow after faster first serves (its rank correlation is
    # positive: 0.08-0.30 over 400-point samples, 0.62 on these 25 serves; serve and volley
    # among them); after a second serve every server runs one profile: no order to read.
    first, second = table["record_corr"]
    assert first > -0.3 and np.isnan(second)


def test_paced_serves_move_only_the_serves_ball_before_the_drawn_frame(truth):
    until = COUPLING_AFTER_FRAMES
    paced = paced_serves(truth, 1.1, until)
    strike = serve_strike_frames(truth)
    vocab = Vocab.from_data(truth, generic=True)
    a, b = rally_arrays(truth, vocab), rally_arrays(paced, vocab)
    assert np.array_equal(a.rally_id, b.rally_id)
    for rid, start, n in zip(a.rally_id, a.start, a.length):
        old, new = a.pos_m[start:start + n], b.pos_m[start:start + n]
        k = int(strike[rid])
        np.testing.assert_array_equal(new[:, :BALL], old[:, :BALL])      # the players
        np.testing.assert_array_equal(new[:k + 1], old[:k + 1])           # up to the strike
        np.testing.assert_array_equal(new[k + until:], old[k + until:])   # the drawn frame on
        np.testing.assert_allclose(new[k + 1:k + until, BALL],
                                   old[k, BALL] + 1.1 * (old[k + 1:k + until, BALL] - old[k, BALL]),
                                   atol=1e-5)
    assert paced.shots.equals(truth.shots) and paced.rallies.equals(truth.rallies)
    with pytest.raises(ValueError, match="scale"):
        paced_serves(truth, 0.0, until)


class _BallClock(_Replay):
    """The record replayed on the players' frames it was given (the ball's may be re-flown),
    the ball's frames as given, and, with `gain`, the server's drawn frame stepping along x by
    `gain` times the ball's horizontal distance from its strike at the frame before: a server
    who reads the ball's progress as his clock."""

    def __init__(self, truth: RallyData, gain: float = 0.0):
        super().__init__(truth)
        self.gain, self.strike = gain, serve_strike_frames(truth)

    def simulate_rallies(self, plan, seed, init_pos_m, max_duration_s, forced_pos_m=None,
                         init_frames=None, label_events=True):
        parts = []
        for new_id, init, k in zip(plan["rally_id"], init_pos_m, init_frames):
            rid, = [r for r, t in self.tracks.items()
                    if len(t) > k and np.array_equal(t[:k, :BALL], init[:k, :BALL])]
            one = self.truth.subset([rid])
            frames = one.frames.copy()
            rel = frames["frame"] - frames["frame"].min()
            for slot, name in ((BALL, "ball"),):
                mine = (frames["object"] == name) & (rel < k)
                frames.loc[mine, ["x", "y", "z"]] = init[:k, slot][rel[mine].to_numpy()]
            server = one.rallies["server"].iloc[0]
            at = (frames["object"] == server) & (rel == k)
            s = int(self.strike[rid])
            dist = np.linalg.norm(init[k - 1, BALL, :2] - init[s, BALL, :2])
            frames.loc[at, "x"] = init[k - 1, SERVER_SLOT, 0] + self.gain * dist
            frames.loc[at, "y"] = init[k - 1, SERVER_SLOT, 1]
            tables = {"frames": frames.assign(rally_id=int(new_id)),
                      "rallies": one.rallies.assign(rally_id=int(new_id)),
                      "shots": one.shots.assign(rally_id=int(new_id))}
            parts.append(RallyData(**tables, fps=one.fps))
        return RallyData.concat(parts)


def test_the_pace_response_of_a_server_who_ignores_the_ball_is_zero(truth):
    table = server_pace_response(_BallClock(truth), truth, draws=1)
    assert table["serve_number"].tolist() == [1, 2]
    assert (table["n"] > 5).all()
    np.testing.assert_allclose(table["slope"], 0.0, atol=1e-9)
    np.testing.assert_allclose(table["lo_mps"], table["hi_mps"])


def test_the_pace_response_of_a_server_clocked_by_the_ball(truth):
    # His speed is gain x fps x (the ball's distance from its strike at the frame before),
    # which the pace scales: per 10 m/s of pace, gain x fps x distance / serve speed x 10.
    gain = 0.01
    table = server_pace_response(_BallClock(truth, gain), truth, draws=1)
    strike = serve_strike_frames(truth)
    arr = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    serves = truth.shots[truth.shots["shot_index"] == 0].set_index("rally_id")["speed_mps"]
    number = truth.rallies.set_index("rally_id")["serve_number"]
    expected = {1: [], 2: []}
    for rid, start, n in zip(arr.rally_id, arr.start, arr.length):
        k = int(strike[rid]) + COUPLING_AFTER_FRAMES
        if rid not in strike.index or n <= k:
            continue
        track = arr.pos_m[start:start + n]
        dist = np.linalg.norm(track[k - 1, BALL, :2] - track[int(strike[rid]), BALL, :2])
        expected[int(number[rid])].append(gain * 25.0 * dist / serves[rid] * 10.0)
    for row in table.itertuples():
        assert row.n == len(expected[row.serve_number])
        # Speeds rounded to 1 mm/s: a 0.2 x pace change moves them about 0.1 m/s.
        assert row.slope == pytest.approx(np.mean(expected[row.serve_number]), rel=0.02)
        assert row.slope > 0.05                  # he runs faster the faster it flies
