"""The per-server shift of the receiver's odds of starting his run at the serve
(`sportsngen.model.receiver_start`, `sportsngen.train.receiver_start`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import receiver_start as rs
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.receiver_start import (
    WaitStates,
    collect_wait_states,
    fit_receiver_start,
    with_receiver_start,
)
from tests.test_serve_bias import small_model as serve_small_model


def small_model(**kw) -> SportsNGEN:
    return serve_small_model(**{"bin_centre": "cv", **kw})


def frame(receiver_x=-12.0, receiver_v=(0.0, 0.0), ball_v=(-40.0, 3.0, -2.0)):
    pos = torch.zeros(3, 3)
    pos[0] = torch.tensor([12.0, 0.5, 0.0])
    pos[1] = torch.tensor([receiver_x, -3.0, 0.0])
    pos[2] = torch.tensor([9.0, 0.4, 2.5])
    vel = torch.zeros(3, 3)
    vel[1, :2] = torch.tensor(receiver_v)
    vel[2] = torch.tensor(ball_v)
    return pos, vel


@pytest.mark.parametrize("kw, want", [
    ({}, True),                                          # a served ball flying at him
    ({"receiver_x": 12.5, "ball_v": (40.0, 3.0, -2.0)}, True),   # the other end, mirrored
    ({"receiver_v": (0.0, 0.12)}, False),                # he has started
    ({"receiver_v": (0.05, -0.05)}, True),               # 0.07 m/s: still standing
    ({"ball_v": (-11.0, 3.0, -2.0)}, False),             # 11.4 m/s: a toss or a slow ball
    ({"ball_v": (40.0, 3.0, -2.0)}, False),              # flying away from him
])
def test_a_receiver_waits_while_a_served_ball_flies_at_him_and_he_stands(kw, want):
    pos, vel = frame(**kw)
    assert bool(rs.receiver_waiting(pos, vel)) is want
    # Batched alike.
    assert rs.receiver_waiting(pos.expand(4, 3, 3), vel.expand(4, 3, 3)).tolist() == [want] * 4


def test_the_bias_shifts_a_waiting_receivers_centre_bins_by_his_wait():
    table = torch.zeros(6, 2, rs.N_WAIT)
    table[3, 0] = torch.arange(rs.N_WAIT, dtype=torch.float32)      # shift = wait - 1
    table[3, 1] = -0.5
    got = rs.player_dim_bias(table, torch.tensor([3, 3, 3, 2, 3]),
                             torch.tensor([0, 1, 0, 0, 0]), torch.tensor([4, 1, 0, 2, 40]), 9)
    assert got.shape == (5, 2, 2, 9)
    want = torch.zeros(5, 2, 2, 9)
    want[0, rs.RECEIVER, :, 4] = 3.0
    want[1, rs.RECEIVER, :, 4] = -0.5
    want[4, rs.RECEIVER, :, 4] = rs.N_WAIT - 1.0     # waits past the table share its last
    torch.testing.assert_close(got, want)


def test_waits_count_consecutive_waiting_frames():
    waiting = torch.tensor([[False, True, True, False, True, True, True],
                            [True, True, True, True, True, True, True]])
    assert rs.wait_counts(waiting).tolist() == [[0, 1, 2, 0, 1, 2, 3], [1, 2, 3, 4, 5, 6, 7]]
    assert rs.wait_bin(torch.tensor([1, 5, 13, 14, 99])).tolist() == [0, 4, 12, 12, 12]


def test_the_start_probability_is_one_minus_both_centres_and_falls_with_the_shift():
    first = torch.log(torch.tensor([[0.1, 0.2, 0.4, 0.2, 0.1]]))
    second = torch.log(torch.tensor([[0.25, 0.25, 0.5, 0.0 + 1e-9, 0.0 + 1e-9]]))
    p = rs.start_probability(first, second, torch.tensor([0.0, 1.0, -1.0]))
    assert p[0, 0] == pytest.approx(1 - 0.4 * 0.5, abs=1e-6)
    e = np.e
    c1, c2 = 0.4 * e / (0.6 + 0.4 * e), 0.5 * e / (0.5 + 0.5 * e)
    assert p[1, 0] == pytest.approx(1 - c1 * c2, abs=1e-6)
    assert p[1, 0] < p[0, 0] < p[2, 0]


def _states(model, n_per=(400, 100), seed=0):
    """Recorded waits of servers 2 (receivers start on 10 % of frames) and 3 (on 60 %), all
    at their third frame of waiting."""
    g = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    parts = []
    for sid, n, share in ((2, n_per[0], 0.1), (3, n_per[1], 0.6)):
        parts.append(WaitStates(torch.randn(n, model.cfg.d_model, generator=g),
                                rng.random(n) < share, rng.integers(1, 10, n),
                                np.full(n, 3), np.arange(n), np.zeros(n, dtype=np.int64),
                                np.full(n, sid, dtype=np.int64)))
    return WaitStates.concat(parts)


def test_the_fit_matches_each_servers_share_of_starts_pulled_toward_the_head():
    model = with_receiver_start(small_model())
    st = _states(model)
    table = fit_receiver_start(model, st, prior_frames=0.0, min_frames=50).set_index("server_id")
    for sid in (2, 3):
        assert table.loc[sid, "after"] == pytest.approx(table.loc[sid, "record"], abs=1e-4)
    # Server 2's receivers wait longer: his shift toward standing is the larger.
    assert table.loc[2, "shift"] > table.loc[3, "shift"]
    assert (table["wait"] == 3).all()
    assert model.receiver_start[2, 0, 2] == pytest.approx(table.loc[2, "shift"])
    assert (model.receiver_start[2, 0, [0, 1, 3]] == 0).all()       # other waits: none seen
    assert (model.receiver_start[:, 1] == 0).all()
    assert (model.receiver_start[[0, 1, 4, 5]] == 0).all()
    pulled = fit_receiver_start(model, st, prior_frames=100.0,
                                min_frames=50).set_index("server_id")
    w = 400 / 500
    r = pulled.loc[2]
    assert r["target"] == pytest.approx(w * r["record"] + (1 - w) * r["head"])
    fresh = with_receiver_start(small_model())
    assert 3 not in set(fit_receiver_start(fresh, st, min_frames=200)["server_id"])
    with pytest.raises(ValueError, match="with_receiver_start"):
        fit_receiver_start(small_model(), st)


def test_the_table_is_added_at_zero_saved_and_read_by_the_sampler():
    plain = small_model()
    assert plain.receiver_start is None
    pos, vel = frame()
    assert plain.receiver_start_bias(torch.tensor([3]), torch.tensor([0]),
                                     torch.tensor([2])) is None
    model = with_receiver_start(plain)
    assert model.receiver_start.shape == (6, 2, rs.N_WAIT)
    assert (model.receiver_start == 0).all() and with_receiver_start(model) is model
    model.receiver_start[3, 0, 1] = 60.0           # server 3: none start at their second frame
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.receiver_start, model.receiver_start)
    n = 200
    p, v = pos.expand(n, 3, 3).clone(), vel.expand(n, 3, 3).clone()
    ident = torch.tensor([3, 2] * (n // 2))
    h = torch.randn(n, 3, model.cfg.d_model, generator=torch.Generator().manual_seed(1))
    half = float(model.player_bins.width(torch.tensor([4, 4])).max()) / 2   # centre bin

    def moved(wait):
        bias = model.receiver_start_bias(ident, torch.zeros(n, dtype=torch.long),
                                         torch.full((n,), wait))
        nxt = model.sample_next(h, p, v, 1.0, 1.0, torch.Generator().manual_seed(0), v,
                                player_bias=bias)
        return (nxt[:, rs.RECEIVER, :2] - p[:, rs.RECEIVER, :2]).abs().amax(-1)

    # Server 3's waiting receivers stay in the centre bin (cv centre: standing, they stay put)
    # at their second frame; at their third, and server 2's at any, some leave it.
    assert (moved(2)[ident == 3] <= half + 1e-6).all()
    assert (moved(2)[ident == 2] > half).any() and (moved(3)[ident == 3] > half).any()
    # Not waiting (0): no shift.
    none = model.receiver_start_bias(ident, torch.zeros(n, dtype=torch.long),
                                     torch.zeros(n, dtype=torch.long))
    assert (none == 0).all()
    with pytest.raises(ValueError, match="factorised"):
        ModelConfig(receiver_start=True, head="joint")


def test_the_rollout_counts_waits_until_the_return():
    from sportsngen.sim.rollout import _wait_step

    pos, vel = frame()
    p, v = pos.expand(3, 3, 3), vel.expand(3, 3, 3)

    class Tracker:
        n_shots = np.array([0, 1, 2, 1])

    alive = np.array([0, 1, 2])                 # row 3 has ended
    wait = _wait_step(Tracker(), alive, p, v, torch.tensor([0, 4, 4]))
    assert wait.tolist() == [1, 5, 0]           # the third's return is struck
    moving = v.clone()
    moving[:, rs.RECEIVER, 1] = 1.0
    assert _wait_step(Tracker(), alive, p, moving, torch.tensor([3, 3, 3])).tolist() == [0, 0, 0]
    # Without a shot count (no tracker), only the frame decides.
    assert _wait_step(object(), alive, p, v, torch.tensor([0, 1, 2])).tolist() == [1, 2, 3]


def test_a_rollout_with_the_table_holds_the_receivers_of_one_server():
    from sportsngen.sim.rollout import RolloutInputs, rollout

    model = with_receiver_start(small_model())
    model.receiver_start[3] = 60.0              # server 3's receivers never start
    b, t0 = 8, 3
    init = np.zeros((b, t0, 3, 3), dtype=np.float32)
    init[:, :, 0] = [12.0, 0.5, 0.0]
    init[:, :, 1] = [-12.0, -3.0, 0.0]
    for k in range(t0):                          # a serve in flight toward the receiver
        init[:, k, 2] = [9.0 - 1.6 * k, 0.4, 2.5 - 0.05 * k]
    ident = np.array([[3, 4, 0]] * 4 + [[2, 4, 0]] * 4)
    inputs = RolloutInputs(init, ident, np.zeros(b, dtype=np.int64),
                           np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.int64),
                           np.zeros((b, 7), dtype=np.float32))
    # One sampled frame: its token's receiver has waited 2 frames (the toss's first frame
    # has no velocity; the initial frames but the last, then the loop's first step).
    out = rollout(model, inputs, t0 + 1, seed=0)
    step = np.abs(out.pos_m[:, t0, rs.RECEIVER, :2] - init[:, -1, rs.RECEIVER, :2]).max(-1)
    half = float(model.player_bins.width(torch.tensor([4, 4])).max()) / 2
    assert (step[:4] <= half + 1e-6).all()      # server 3's: still (within the centre bin)
    assert (step[4:] > half).any()              # server 2's: the (untrained) model's odds
    model.receiver_start[3] = 0.0
    model.receiver_start[3, 0, 1] = 60.0        # the second frame of a wait only
    out = rollout(model, inputs, t0 + 1, seed=0)
    step = np.abs(out.pos_m[:, t0, rs.RECEIVER, :2] - init[:, -1, rs.RECEIVER, :2]).max(-1)
    assert (step[:4] <= half + 1e-6).all()


def test_waits_are_read_from_recorded_serves():
    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.synth.generate import generate_matches

    data = generate_matches([("Serena Williams", "Maria Sharapova")], "hard", 6, seed=0,
                            workers=1)
    vocab = Vocab.from_data(data)
    # The bundled model's bins (61): a start's first step (0.2 m/s) leaves the centre bin.
    model = with_receiver_start(small_model(n_ids=vocab.n_ids, n_bins=61))
    arr = rally_arrays(data, vocab)
    st = collect_wait_states(model, arr, progress=False)
    assert len(st) == len(st.h) == len(st.server_id) and st.h.shape[1] == model.cfg.d_model
    assert (st.frames_after >= 1).all() and (st.frames_after <= rs.WAIT_FRAMES).all()
    # The generator's receivers stand until they read the serve, then start once: one start
    # a rally at most in the wait that began at the serve, a few frames after the contact,
    # and waits before it. (A receiver who reaches the ball early and stands for it waits
    # again, read the same way, as a rollout reads it.)
    began = st.frames_after - st.wait                     # the frame before each wait began
    first = {r: began[st.rally_id == r].min() for r in set(st.rally_id.tolist())}
    from_serve = began == np.array([first[r] for r in st.rally_id])
    starts = st.rally_id[st.start & from_serve]
    assert 0 < len(starts) == len(set(starts.tolist())) <= len(data.rallies)
    assert 2 <= np.median(st.frames_after[st.start & from_serve]) <= 8
    assert (st.frames_after[~from_serve] > 8).all()
    assert st.start.mean() < 0.5
    servers = {vocab.player_index(n) for n in data.rallies["server"]}
    assert set(st.server_id.tolist()) <= servers
    # Turned windows (the world frame) add as many again.
    both = collect_wait_states(model, arr, flip=True, progress=False)
    assert len(both) == 2 * len(st)


def test_a_player_added_for_fine_tuning_gets_a_row_at_zero():
    from sportsngen.data.tokens import Vocab
    from sportsngen.train.finetune import add_player

    vocab = Vocab(players=("A", "B", "C", "D"))
    model = with_receiver_start(small_model(n_ids=vocab.n_ids))
    model.receiver_start[2:] = 0.5
    new, _, idx = add_player(model, vocab, "New Player")
    assert new.receiver_start.shape == (vocab.n_ids + 1, 2, rs.N_WAIT)
    torch.testing.assert_close(new.receiver_start[:vocab.n_ids], model.receiver_start)
    assert (new.receiver_start[idx] == 0).all()
