"""The strike head's shift by the strike's number in the rally (`ModelConfig.strike_shots`,
`sportsngen.train.strike_inputs`), and by the hitter and his opponent
(`ModelConfig.strike_players`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import strike_bias
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.strike_heads import N_SHOT_BUCKETS, shot_bucket
from sportsngen.train.head_fit import HeadStates, head_inputs
from sportsngen.train.strike_inputs import (
    fit_strike_inputs,
    held_out,
    shot_profile,
    with_strike_players,
    with_strike_shots,
)
from tests.test_strike_bias import small_model


def test_shots_one_to_six_have_rows_of_their_own_and_later_ones_pool_by_hitter():
    got = shot_bucket(torch.arange(0, 12)).tolist()
    assert got == [0, 0, 1, 2, 3, 4, 5, 6, 7, 6, 7, 6]
    assert max(got) == N_SHOT_BUCKETS - 1


def _states(rally_id, receiver, d=32) -> HeadStates:
    n = len(rally_id)
    return HeadStates(torch.zeros(n, d), torch.zeros(n, 4, dtype=torch.long),
                      np.asarray(rally_id), np.zeros(n, dtype=np.int64), np.zeros((n, 3)),
                      np.asarray(receiver, dtype=bool), np.zeros(n, dtype=np.int64))


def test_shot_numbers_count_along_each_rally_by_the_turn_of_the_hitter():
    # Rally 5: return, server, receiver, then the receiver again (the server's shot 4 was
    # not read); rally 7 starts with the server (its return not read); rally 9 again.
    st = _states([5, 5, 5, 5, 7, 7, 7, 9, 9], [1, 0, 1, 1, 0, 1, 0, 1, 1])
    assert st.shot_numbers().tolist() == [1, 2, 3, 5, 2, 3, 4, 1, 3]
    # Rows taken keep the numbers counted on the whole; concatenation keeps each part's.
    keep = np.array([0, 0, 0, 1, 0, 1, 0, 0, 1], dtype=bool)
    assert st.take(keep).shot_numbers().tolist() == [5, 3, 3]
    both = HeadStates.concat([st.take(keep), _states([5, 5], [1, 0])])
    assert both.shot_numbers().tolist() == [5, 3, 3, 1, 2]


def test_the_shift_is_added_at_zero_and_read_by_shot():
    plain = small_model(strike_roles=True)
    assert plain.strike_shot is None
    model = with_strike_shots(plain)
    assert model.cfg.strike_shots and with_strike_shots(model) is model
    assert model.strike_shot.weight.shape == (N_SHOT_BUCKETS, model.cfg.d_model)
    h = torch.randn(4, model.cfg.d_model)
    role = torch.tensor([0, 1, 2, 3])
    torch.testing.assert_close(model.strike_input(h, role, torch.tensor([1, 2, 3, 9])),
                               plain.strike_input(h, role))
    with torch.no_grad():
        model.strike_shot.weight[:] = torch.arange(N_SHOT_BUCKETS)[:, None].float()
    got = model.strike_input(h, role, torch.tensor([1, 2, 7, 12])) - plain.strike_input(h, role)
    assert got[:, 0].tolist() == pytest.approx([0.0, 1.0, 6.0, 7.0], abs=1e-5)
    # Without the count (no tracker), the head reads as without the shift.
    torch.testing.assert_close(model.strike_input(h, role), plain.strike_input(h, role))
    # Without the role shift the number is read alone.
    alone = with_strike_shots(small_model())
    with torch.no_grad():
        alone.strike_shot.weight[2] = 5.0
    torch.testing.assert_close(alone.strike_input(h, None, torch.full((4,), 3)), h + 5.0)
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.strike_shot.weight, model.strike_shot.weight)
    with pytest.raises(ValueError, match="strike_head"):
        SportsNGEN(ModelConfig(strike_shots=True))


def test_a_strike_placed_in_a_rollout_frame_reads_its_number():
    model = with_strike_shots(small_model())
    seen = []

    def sample(h, top_p, generator, dim_bias=None):
        seen.append(h.clone())
        return torch.full((len(h), 4), 40, dtype=torch.long)

    model.strike_head.sample = sample
    with torch.no_grad():
        model.strike_shot.weight[0] = 1.0          # the return
        model.strike_shot.weight[3] = 2.0          # shot 4
    pos = torch.zeros(2, 3, 3)
    pos[:, 0, 0], pos[:, 1, 0] = 12.0, -12.0
    pos[:, 2] = torch.tensor([-11.0, 0.0, 1.0])
    h = torch.zeros(2, 3, model.cfg.d_model)
    forced = torch.tensor([True, True])
    model.place_strikes(h, pos, torch.zeros(2, 3, 3), pos.clone(), forced=forced,
                        shot=torch.tensor([1, 4]))
    assert seen[0][:, 0].tolist() == [1.0, 2.0]
    seen.clear()
    model.place_strikes(h, pos, torch.zeros(2, 3, 3), pos.clone(), forced=forced)
    assert seen[0][:, 0].tolist() == [0.0, 0.0]


def test_a_rollout_hands_the_trackers_contact_count_to_the_strike_head():
    from sportsngen.sim.rollout import RolloutInputs, rollout

    model = with_strike_shots(small_model())
    got = {}
    place = model.place_strikes

    def spy(*args, **kw):
        got["shot"] = kw.get("shot")
        return place(*args, **kw)

    model.place_strikes = spy

    class Counting:
        def __init__(self, n):
            self.n_shots = np.array([1, 3, 6, 2])[:n]

        def update(self, pos_m, active=None):
            return np.zeros(len(pos_m), dtype=bool)

    b, t0 = 4, 3
    init = np.zeros((b, t0, 3, 3), dtype=np.float32)
    init[:, :, 0] = [12.0, 0.5, 0.0]
    init[:, :, 1] = [-12.0, -3.0, 0.0]
    for k in range(t0):
        init[:, k, 2] = [5.0 - 1.0 * k, 0.4, 1.5]
    inputs = RolloutInputs(init, np.array([[2, 3, 0]] * b), np.zeros(b, dtype=np.int64),
                           np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.int64),
                           np.zeros((b, 7), dtype=np.float32))
    rollout(model, inputs, t0 + 1, tracker=Counting(b), seed=0)
    assert got["shot"].tolist() == [1, 3, 6, 2]
    rollout(model, inputs, t0 + 1, seed=0)            # no tracker: no count
    assert got["shot"] is None


def _shot_states(model, n_rallies=400, seed=0) -> HeadStates:
    """Rallies of six strikes whose depth depends on the shot's number alone: the receiver's
    second rally ball (shot 3) short, every other ball deep; the decoder's states noise."""
    rng = np.random.default_rng(seed)
    n = n_rallies * 6
    rally = np.repeat(np.arange(n_rallies), 6)
    shot = np.tile(np.arange(1, 7), n_rallies)
    in_play = np.flatnonzero(~strike_bias.error_bins()[0])
    short, deep = in_play[:12], in_play[-12:]
    depth = np.where(shot == 3, rng.choice(short, n), rng.choice(deep, n))
    bins = np.stack([depth, rng.integers(40, 56, n), rng.integers(40, 56, n),
                     rng.integers(40, 56, n)], -1)
    g = torch.Generator().manual_seed(seed)
    return HeadStates(0.1 * torch.randn(n, model.cfg.d_model, generator=g),
                      torch.as_tensor(bins), rally, np.zeros(n, dtype=np.int64),
                      np.zeros((n, 3)), shot % 2 == 1, np.full(n, 2, dtype=np.int64),
                      np.full(n, 3, dtype=np.int64))


def test_the_fit_learns_the_depth_by_shot_and_moves_nothing_else():
    model = with_strike_shots(small_model())
    st = _shot_states(model)
    head_before = {k: v.clone() for k, v in model.strike_head.state_dict().items()}
    before = shot_profile(model, st, held_out(st)).set_index("shot_row")
    history = fit_strike_inputs(model, st, ("shot",), steps=400, lr=0.05, batch_size=256,
                                eval_every=100, progress=False)
    assert history[0]["step"] == 0 and len(history) == 5
    best = min(h["val_nll"] for h in history)
    assert best < history[0]["val_nll"] - 1.0
    after = shot_profile(model, st, held_out(st)).set_index("shot_row")
    assert after.loc[2, "depth_record_m"] < 2.0 and after.loc[1, "depth_record_m"] > 10.0
    for row in range(6):
        assert abs(after.loc[row, "depth_head_m"] - after.loc[row, "depth_record_m"]) < \
            abs(before.loc[row, "depth_head_m"] - before.loc[row, "depth_record_m"])
    # A shift of a small random head's input cannot pile its odds on a dozen bins, but it
    # parts the short shot from the deep ones (before: about the same depth for all).
    assert after.loc[2, "depth_head_m"] < 3.5
    assert after.drop(index=2)["depth_head_m"].min() > 7.0
    assert before["depth_head_m"].max() - before["depth_head_m"].min() < 1.0
    # Only the shift moved; the held-out rallies are whole rallies, a fifth.
    for k, v in model.strike_head.state_dict().items():
        torch.testing.assert_close(v, head_before[k])
    assert held_out(st).mean() == pytest.approx(0.2)
    assert set(st.rally_id[held_out(st)] % 5) == {0}
    x = head_inputs(model, "strike", st, torch.arange(6))
    assert not torch.equal(x, st.h[:6])


def test_the_fit_refuses_a_model_without_the_shift_and_bad_arguments():
    model = small_model()
    st = _shot_states(model, n_rallies=10)
    with pytest.raises(ValueError, match="with_strike_shots"):
        fit_strike_inputs(model, st)
    with pytest.raises(ValueError, match="with_strike_players"):
        fit_strike_inputs(model, st, ("players",))
    with pytest.raises(ValueError, match="subset"):
        fit_strike_inputs(model, st, ("spin",))
    model = with_strike_shots(model)
    with pytest.raises(ValueError, match="positive"):
        fit_strike_inputs(model, st, steps=0)
    with pytest.raises(ValueError, match="every"):
        held_out(st, every=1)
    with pytest.raises(ValueError, match="strike_head"):
        with_strike_shots(SportsNGEN(ModelConfig(d_model=32, n_heads=2, n_layers=1)))


def test_the_players_shifts_are_read_by_the_hitters_and_the_opponents_rows_in_his_role():
    plain = small_model(strike_roles=True)
    model = with_strike_players(plain)
    assert model.strike_player.shape == (6, 2, model.cfg.d_model)
    assert with_strike_players(model) is model
    with torch.no_grad():
        model.strike_player[3, 1] = 1.0          # player 3 receiving
        model.strike_player[3, 0] = 2.0          # player 3 serving
        model.strike_opponent[2, 1] = 10.0       # answering player 2, as the receiver
        model.strike_player[2, 0] = 4.0          # player 2 serving
    h = torch.zeros(3, model.cfg.d_model)
    role = torch.tensor([2, 0, 3])               # receiver, server, receiver (second serve)
    got = model.strike_input(h, role, None, torch.tensor([3, 3, 4]), torch.tensor([2, 2, 2]))
    assert got[:, 0].tolist() == [11.0, 2.0, 10.0]
    # Without the identities the head reads as without the shifts.
    torch.testing.assert_close(model.strike_input(h, role), plain.strike_input(h, role))
    # In a rollout frame: the receiver strikes a ball on his end, the server one on his.
    seen = []

    def sample(x, top_p, generator, dim_bias=None):
        seen.append(x.clone())
        return torch.full((len(x), 4), 40, dtype=torch.long)

    model.strike_head.sample = sample
    pos = torch.zeros(2, 3, 3)
    pos[:, 0, 0], pos[:, 1, 0] = 12.0, -12.0
    pos[0, 2] = torch.tensor([-11.0, 0.0, 1.0])
    pos[1, 2] = torch.tensor([11.0, 0.0, 1.0])
    model.place_strikes(torch.zeros(2, 3, model.cfg.d_model), pos, torch.zeros(2, 3, 3),
                        pos.clone(), forced=torch.tensor([True, True]),
                        serve=torch.tensor([0, 0]), server_ident=torch.tensor([2, 2]),
                        receiver_ident=torch.tensor([3, 3]))
    assert seen[0][:, 0].tolist() == [11.0, 4.0]      # receiver 3 answering 2; server 2
    with pytest.raises(ValueError, match="strike_roles"):
        with_strike_players(small_model())
    with pytest.raises(ValueError, match="strike_roles"):
        ModelConfig(strike_head=True, strike_players=True)


def test_the_players_fit_learns_each_servers_depth_and_leaves_absent_players_at_zero():
    model = with_strike_players(small_model(strike_roles=True))
    st = _shot_states(model, n_rallies=300, seed=2)
    # Two servers: player 2's rally balls all short, player 4's all deep; the receivers' as
    # `_shot_states` makes them.
    server = np.where(st.rally_id % 2 == 0, 2, 4)
    st.server_id = server.astype(np.int64)
    in_play = np.flatnonzero(~strike_bias.error_bins()[0])
    rng = np.random.default_rng(5)
    mine = ~st.receiver
    depth = st.bins[:, 0].numpy().copy()
    depth[mine] = np.where(server[mine] == 2, rng.choice(in_play[:12], mine.sum()),
                           rng.choice(in_play[-12:], mine.sum()))
    st.bins[:, 0] = torch.as_tensor(depth)
    short = torch.zeros(strike_bias.error_bins().shape[1], dtype=torch.bool)
    short[in_play[:24]] = True

    def short_odds(who: int) -> float:
        rows = torch.as_tensor(np.flatnonzero(mine & (server == who)))
        x = head_inputs(model, "strike", st, rows)
        p = model.strike_head.dim_logits(x, st.bins[rows], 0).softmax(-1).detach()
        return float(p[:, short].sum(-1).mean())

    before = short_odds(2), short_odds(4)
    assert abs(before[0] - before[1]) < 0.05
    history = fit_strike_inputs(model, st, ("players",), steps=300, lr=0.05, batch_size=256,
                                eval_every=100, weight_decay=0.01, progress=False)
    assert min(h["val_nll"] for h in history) < history[0]["val_nll"] - 0.3
    assert short_odds(2) > before[0] + 0.3 and short_odds(4) < before[1]
    # Players who strike nowhere in the states keep zero rows; the head is not fitted and
    # trainable again after.
    assert (model.strike_player[[0, 1, 5]] == 0).all()
    assert (model.strike_opponent[[0, 1, 5]] == 0).all()
    assert all(p.requires_grad for p in model.strike_head.parameters())
