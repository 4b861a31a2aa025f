"""The serve head's per-server shifts of its odds of a long and a wide serve
(`sportsngen.model.serve_bias`, `sportsngen.train.serve_bias`)."""

import numpy as np
import pytest
import torch

from sportsngen.eval.serve_draws import serve_faults
from sportsngen.model import serve_bias, strike
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.heads import FactorisedHead
from sportsngen.tennis.court import SERVICE_LINE_X_M
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.serve_bias import (
    MAX_SHIFT,
    binary_mask_odds,
    bisect_shift,
    fit_serve_bias,
    fit_serve_lateral,
    fit_serve_short,
    mean_odds,
    solve_shift,
    with_serve_bias,
    with_serve_lateral,
    with_serve_short,
)

FPS = 25.0


def test_a_binary_masks_odds_are_read_from_four_sums_as_the_softmax_gives_them():
    g = torch.Generator().manual_seed(3)
    logits = torch.randn(300, 11, generator=g, dtype=torch.float64) * 2.0
    mask = (torch.arange(11) % 3 == 0).expand(300, -1)
    speed = torch.linspace(100.0, 200.0, 11, dtype=torch.float64).expand(300, -1)
    odds = binary_mask_odds(logits, mask, speed)
    for s in (-4.0, -0.7, 0.0, 0.3, 2.5, 4.0):
        full = float(mean_odds(logits, mask, speed, torch.tensor([s], dtype=torch.float64))[0])
        assert odds(s) == pytest.approx(full, rel=1e-13)
    # The same root as the bisection over the whole softmax; a tilt (not 0 / 1) takes that way.
    w = mask.to(torch.float64)
    target = float(mean_odds(logits, mask, w, torch.zeros(1, dtype=torch.float64))[0]) + 0.1
    whole = bisect_shift(lambda s: float(mean_odds(logits, mask, w, torch.tensor(
        [s], dtype=torch.float64))[0]), target, MAX_SHIFT)
    assert solve_shift(logits, mask, w, target) == pytest.approx(whole, abs=1e-9)
    assert 0.0 < whole < MAX_SHIFT
    tilt = torch.linspace(-1.0, 1.0, 11, dtype=torch.float64).expand(300, -1)
    mean_speed = float(mean_odds(logits, tilt, speed, torch.zeros(1, dtype=torch.float64))[0])
    shift = solve_shift(logits, tilt, speed, mean_speed + 5.0)
    assert float(mean_odds(logits, tilt, speed, torch.tensor([shift], dtype=torch.float64))[0]) \
        == pytest.approx(mean_speed + 5.0, abs=1e-6)


def small_model(**kw) -> SportsNGEN:
    torch.manual_seed(0)
    cfg = dict(d_model=32, n_layers=1, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
               embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
               head_hidden=16, window_s=4.0, fps=FPS, n_ids=6, n_tournaments=2,
               event_d_model=16, event_layers=1, event_heads=2, ball_centre="physics",
               serve_head=True)
    cfg.update(kw)
    return SportsNGEN(ModelConfig(**cfg)).eval()


def test_a_dimensions_bias_is_added_to_its_logits():
    torch.manual_seed(1)
    head = FactorisedHead(8, 5, 2, hidden=8)
    h, idx = torch.randn(4, 8), torch.randint(5, (4, 2))
    bias = torch.zeros(4, 2, 5)
    bias[:, 0, 2] = 1.5
    bias[:, 1, 0] = -0.7
    got = head.nll(h, idx, dim_bias=bias)
    lx = head.dim_logits(h, idx, 0) + bias[:, 0]
    ly = head.dim_logits(h, idx, 1) + bias[:, 1]
    want = (torch.nn.functional.cross_entropy(lx, idx[:, 0], reduction="none")
            + torch.nn.functional.cross_entropy(ly, idx[:, 1], reduction="none"))
    torch.testing.assert_close(got, want)
    # A bin shifted far down is never drawn; unbiased, the same generator draws as before.
    bias = torch.zeros(400, 2, 5)
    bias[:, 0, :4] = -50.0
    hh = torch.randn(400, 8)
    assert (head.sample(hh, 1.0, torch.Generator().manual_seed(0), dim_bias=bias)[:, 0]
            == 4).all()
    torch.testing.assert_close(
        head.sample(hh, 1.0, torch.Generator().manual_seed(3)),
        head.sample(hh, 1.0, torch.Generator().manual_seed(3),
                    dim_bias=torch.zeros(400, 2, 5)))
    # With regions (the contact odds' split), the regions' odds are read after the bias: a
    # region holding only bins shifted far down is never chosen.
    regions = torch.tensor([True, True, False, False, False])
    bias = torch.zeros(400, 2, 5)
    bias[:, 0, :2] = -50.0
    got = head.sample(hh, 0.9, torch.Generator().manual_seed(0), regions=regions,
                      dim_bias=bias)
    assert (got[:, 0] >= 2).all()
    bias[:, 0, :2] = 50.0
    got = head.sample(hh, 0.9, torch.Generator().manual_seed(0), regions=regions,
                      dim_bias=bias)
    assert (got[:, 0] < 2).all()


def test_the_long_bins_are_those_beyond_the_service_line():
    frac = serve_bias.long_fraction()
    e = strike.serve_edges()[0]
    assert frac.shape == (strike.STRIKE_BINS,)
    assert (frac[e[1:] <= SERVICE_LINE_X_M] == 0).all()
    assert (frac[e[:-1] >= SERVICE_LINE_X_M] == 1).all()
    k = int(np.searchsorted(e, SERVICE_LINE_X_M)) - 1       # the bin across the line
    assert frac[k] == pytest.approx((e[k + 1] - SERVICE_LINE_X_M) / (e[k + 1] - e[k]))
    assert 0 < frac[k] < 1 and int(((0 < frac) & (frac < 1)).sum()) == 1


@pytest.mark.parametrize("contact", [[11.9, -0.8, 2.9], [11.9, 0.8, 2.9], [-11.9, 0.8, 2.9],
                                     [-11.9, -0.8, 2.9]])
def test_the_wide_bins_are_the_lateral_bins_the_fault_reading_calls_wide(contact):
    e = strike.serve_edges()[1]
    centres = 0.5 * (e[1:] + e[:-1])
    values = np.stack([np.full_like(centres, 5.0), centres, np.full_like(centres, 45.0),
                       np.zeros_like(centres)], -1)
    read = serve_faults(np.tile(contact, (len(centres), 1)), values, FPS)["wide"]
    got = serve_bias.wide_bins(torch.tensor([contact], dtype=torch.float32))[0].numpy()
    assert got.tolist() == (read == 1).tolist()
    assert 0 < got.sum() < len(got)


def _states(model, n_per=(300, 40), seed=0):
    """Recorded serves of two servers (ids 2 and 3), first serves, with bins drawn so that
    server 2 serves long 40 % of the time and server 3 5 %, server 2 fast and server 3 slow."""
    rng = np.random.default_rng(seed)
    n = sum(n_per)
    sid = np.repeat([2, 3], n_per)
    frac = serve_bias.long_fraction()
    long_bins, in_bins = np.flatnonzero(frac == 1), np.flatnonzero(frac == 0)
    want = np.where(sid == 2, 0.4, 0.05)
    depth = np.where(rng.random(n) < want, rng.choice(long_bins[:8], n),
                     rng.choice(in_bins[-20:], n))
    speed = np.where(sid == 2, rng.integers(60, 90, n), rng.integers(10, 40, n))
    bins = np.stack([depth, rng.integers(40, 56, n), speed, rng.integers(96, size=n)], -1)
    contact = np.tile([11.9, -0.8, 2.9], (n, 1))
    return HeadStates(torch.randn(n, model.cfg.d_model), torch.as_tensor(bins), np.arange(n),
                      np.zeros(n, dtype=np.int64), contact, np.zeros(n, dtype=bool),
                      sid.astype(np.int64))


def test_the_fit_matches_each_servers_record_pulled_toward_the_head():
    model = with_serve_bias(small_model())
    st = _states(model)
    table = fit_serve_bias(model, st, prior_serves=0.0).set_index("server_id")
    # Without pseudo-serves the head's mean odds land on each record's share.
    for sid in (2, 3):
        r = table.loc[sid]
        assert r["long_after"] == pytest.approx(r["long_record"], abs=1e-4)
        assert r["wide_after"] == pytest.approx(r["wide_record"], abs=1e-4)
        assert r["speed_after"] == pytest.approx(r["speed_record"], abs=1e-3)
    # Server 3's recorded serves are the slow ones: his speed tilts down, server 2's up.
    assert table.loc[3, "speed_shift"] < 0 < table.loc[2, "speed_shift"]
    assert table.loc[2, "long_shift"] > table.loc[3, "long_shift"]
    # The shift is in the table for that server and serve only.
    assert model.serve_bias[2, 0, serve_bias.LONG] == pytest.approx(table.loc[2, "long_shift"])
    assert (model.serve_bias[:, 1] == 0).all() and (model.serve_bias[[0, 1, 4, 5]] == 0).all()
    # With pseudo-serves the target lies between the head and the record, nearer the record
    # the more serves a server has.
    pulled = fit_serve_bias(model, st, prior_serves=100.0).set_index("server_id")
    for sid, n in ((2, 300), (3, 40)):
        r = pulled.loc[sid]
        w = n / (n + 100.0)
        assert r["long_target"] == pytest.approx(w * r["long_record"] + (1 - w) * r["long_head"])
    # Too few serves: left at zero.
    fresh = with_serve_bias(small_model())
    assert 3 not in set(fit_serve_bias(fresh, st, min_serves=50)["server_id"])
    assert (fresh.serve_bias[3] == 0).all()


def test_the_fitted_model_draws_each_servers_long_share():
    model = with_serve_bias(small_model())
    st = _states(model, n_per=(400, 400), seed=1)
    fit_serve_bias(model, st, prior_serves=0.0)
    bias = model.serve_head_bias(torch.as_tensor(st.server_id), torch.as_tensor(st.serve),
                                 torch.as_tensor(st.contact_m, dtype=torch.float32))
    frac = serve_bias.long_fraction()
    draws = torch.stack([model.serve_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                                 dim_bias=bias) for k in range(10)])
    long = frac[draws[..., 0].numpy()]          # (10, N) expected share beyond the line
    for sid, want in ((2, 0.4), (3, 0.05)):
        got = long[:, st.server_id == sid].mean()
        assert got == pytest.approx(want, abs=0.03), (sid, got)


def test_the_table_is_added_at_zero_and_read_per_server():
    plain = small_model()
    assert plain.serve_bias is None
    assert plain.serve_head_bias(torch.tensor([2]), torch.tensor([0]),
                                 torch.zeros(1, 3)) is None
    model = with_serve_bias(plain)
    assert model.cfg.serve_bias and model.serve_bias.shape == (6, 2, 3)
    assert (model.serve_bias == 0).all()
    assert with_serve_bias(model) is model
    model.serve_bias[3, 1] = torch.tensor([1.0, -2.0, 0.5])
    contact = torch.tensor([[11.9, -0.8, 2.9], [11.9, -0.8, 2.9]])
    b = model.serve_head_bias(torch.tensor([3, 3]), torch.tensor([1, 0]), contact)
    assert b.shape == (2, 4, strike.STRIKE_BINS)
    long = torch.as_tensor(serve_bias.long_fraction() > 0.5)
    assert (b[0, 0][long] == 1.0).all() and (b[0, 0][~long] == 0).all()
    assert (b[0, 1][serve_bias.wide_bins(contact[:1])[0]] == -2.0).all()
    tilt = torch.as_tensor(serve_bias.speed_tilt(), dtype=b.dtype)
    torch.testing.assert_close(b[0, 2], 0.5 * tilt)
    assert (b[0, 3] == 0).all() and (b[1] == 0).all()      # the spin, and first serves: none
    # Saved and loaded with the file; a config without it refuses it without a serve head.
    sd = model.state_dict()
    again = SportsNGEN(model.cfg)
    again.load_state_dict(sd)
    torch.testing.assert_close(again.serve_bias, model.serve_bias)
    with pytest.raises(ValueError, match="serve_head"):
        ModelConfig(serve_bias=True, serve_head=False)


def test_the_named_players_data_gives_each_named_player_four_matchups():
    from collections import Counter

    from sportsngen.synth.dataset import matchups
    from sportsngen.train.evaluate import data_config

    cfg = data_config("synthetic_named")
    small = data_config("synthetic_small")
    pairs = matchups(cfg)
    assert len(pairs) == 20                       # C(5, 2) men's + C(5, 2) women's
    count = Counter(p.name for pair in pairs for p in pair)
    for name in small["players"]["named"]:
        assert count[name] == 4
    # Its population women are synthetic_small's first three, the same names the model knows.
    pop = {n for n in count if n.startswith("Pop")}
    assert pop == {"Pop W 000", "Pop W 001", "Pop W 002"}
    known = {p.name: p for pair in matchups(small) for p in pair}
    assert all(p == known[p.name] for pair in pairs for p in pair)
    assert cfg["seed"] != small["seed"]


def test_a_rollouts_serve_is_drawn_with_its_servers_shift():
    from sportsngen.sim.frame_draws import follow_strikes

    model = with_serve_bias(small_model())
    n = 64
    pos = torch.zeros(n, 3, 3)
    pos[:, 2] = torch.tensor([11.4, 0.7, 2.9])            # the toss at its top, ad court
    vel = torch.zeros_like(pos)
    vel[:, 2, 2] = -1.0
    nxt = pos.clone()
    nxt[:, 2] += torch.tensor([-1.9, -0.2, -0.1])          # the model's draw: a serve
    h = torch.randn(n, 3, model.cfg.d_model)
    plan = torch.full((n, 2, 3), float("nan"))
    ident = torch.tensor([2, 3] * (n // 2))
    serve = torch.ones(n, dtype=torch.long)
    # Server 3's second serves never go long or wide; server 2's always long.
    model.serve_bias[3, 1, :2] = torch.tensor([-60.0, -60.0])
    model.serve_bias[2, 1, serve_bias.LONG] = 60.0
    drawn = []
    real = model.serve_head.sample
    model.serve_head.sample = lambda *a, **k: drawn.append(real(*a, **k)) or drawn[-1]
    follow_strikes(model, h, pos, vel, nxt, plan, torch.Generator().manual_seed(0),
                   serve=serve, server_ident=ident)
    bins = drawn[0]
    frac = serve_bias.long_fraction()
    wide = serve_bias.wide_bins(pos[:, 2])
    three, two = ident == 3, ident == 2
    assert (frac[bins[three, 0].numpy()] == 0).all()
    assert not wide[three, :].gather(1, bins[three, 1:2]).any()
    assert (frac[bins[two, 0].numpy()] > 0.5).all()
    # Without the servers' identities the table is not read: some serves go long.
    drawn.clear()
    follow_strikes(model, h, pos, vel, nxt, plan, torch.Generator().manual_seed(0),
                   serve=serve)
    assert (frac[drawn[0][:, 0].numpy()] > 0.5).any()


def test_a_player_added_for_fine_tuning_gets_a_row_at_zero():
    from sportsngen.data.tokens import Vocab
    from sportsngen.train.finetune import add_player

    vocab = Vocab(players=("A", "B", "C", "D"))
    model = with_serve_bias(small_model(n_ids=vocab.n_ids))
    model.serve_bias[2:] = 0.5
    new, new_vocab, idx = add_player(model, vocab, "New Player")
    assert new.serve_bias.shape == (vocab.n_ids + 1, 2, 3)
    torch.testing.assert_close(new.serve_bias[:vocab.n_ids], model.serve_bias)
    assert idx == vocab.n_ids and (new.serve_bias[idx] == 0).all()


def _served_without(states_of, fit, adder: str):
    """A small model with its serve table fitted on `states_of(model)`, and those states; the
    table `fit` fills is refused until `adder` adds it."""
    model = with_serve_bias(small_model())
    st = states_of(model)
    fit_serve_bias(model, st, prior_serves=0.0)
    with pytest.raises(ValueError, match=adder):
        fit(model, st)
    return model, st


def _short_states(model, n_per=(400, 400), seed=0):
    """First serves of servers 2 and 3: server 2 lands 30 % of his short of 3.9 m, server 3
    5 %, both 30 % long (the untrained head puts about half its mass beyond the line)."""
    rng = np.random.default_rng(seed)
    n = sum(n_per)
    sid = np.repeat([2, 3], n_per)
    frac = serve_bias.long_fraction()
    short = np.flatnonzero(serve_bias.short_bins())
    long_bins = np.flatnonzero(frac == 1)
    mid = np.flatnonzero((frac == 0) & ~serve_bias.short_bins())
    u = rng.random(n)
    depth = np.where(u < 0.3, rng.choice(long_bins[:8], n),
                     np.where(u < np.where(sid == 2, 0.6, 0.35), rng.choice(short[-6:], n),
                              rng.choice(mid, n)))
    bins = np.stack([depth, rng.integers(40, 56, n), rng.integers(30, 60, n),
                     rng.integers(96, size=n)], -1)
    return HeadStates(torch.randn(n, model.cfg.d_model), torch.as_tensor(bins), np.arange(n),
                      np.zeros(n, dtype=np.int64), np.tile([11.9, -0.8, 2.9], (n, 1)),
                      np.zeros(n, dtype=bool), sid.astype(np.int64))


def test_the_short_bins_are_the_depths_wholly_short_of_the_line():
    e = strike.serve_edges()[0]
    short = serve_bias.short_bins()
    assert (e[1:][short] <= serve_bias.SHORT_DEPTH_M).all()
    assert (e[1:][~short] > serve_bias.SHORT_DEPTH_M).all()
    assert short[:int(short.sum())].all() and not (short & (serve_bias.long_fraction() > 0)).any()
    assert e[int(short.sum())] == pytest.approx(3.885)


def test_the_short_shift_matches_each_servers_short_share_and_keeps_his_long_share():
    model, st = _served_without(_short_states, fit_serve_short, "with_serve_short")
    model = with_serve_short(model)
    assert model.serve_short.shape == (6, 2) and (model.serve_short == 0).all()
    table = fit_serve_short(model, st, prior_serves=0.0).set_index("server_id")
    short = serve_bias.short_bins()
    for sid, want in ((2, 0.3), (3, 0.05)):
        r = table.loc[sid]
        assert r["short_record"] == pytest.approx(want, abs=0.05)
        assert r["short_after"] == pytest.approx(r["short_record"], abs=1e-4)
        assert r["long_after"] == pytest.approx(r["long_target"], abs=1e-4)
    assert table.loc[2, "short_shift"] > table.loc[3, "short_shift"]
    # Drawn with the tables: each server's short and long shares are his record's.
    bias = model.serve_head_bias(torch.as_tensor(st.server_id), torch.as_tensor(st.serve),
                                 torch.as_tensor(st.contact_m, dtype=torch.float32))
    draws = torch.stack([model.serve_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                                 dim_bias=bias) for k in range(10)])
    depth = draws[..., 0].numpy()
    long = serve_bias.long_fraction()
    for sid in (2, 3):
        mine = st.server_id == sid
        assert short[depth[:, mine]].mean() == pytest.approx(
            short[st.bins[mine, 0].numpy()].mean(), abs=0.03)
        assert long[depth[:, mine]].mean() == pytest.approx(
            long[st.bins[mine, 0].numpy()].mean(), abs=0.03)
    # The shift is read on the short depth bins of that server's serve only.
    model.serve_short.zero_()
    model.serve_bias.zero_()
    model.serve_short[3, 1] = 1.5
    b = model.serve_head_bias(torch.tensor([3, 3]), torch.tensor([1, 0]), torch.zeros(2, 3))
    assert (b[0, 0][torch.as_tensor(short)] == 1.5).all() and (b[0, 0][~torch.as_tensor(short)]
                                                                 == 0).all()
    assert (b[1] == 0).all() and (b[0, 1:] == 0).all()
    with pytest.raises(ValueError, match="serve_bias"):
        ModelConfig(serve_head=True, serve_short=True)
    with pytest.raises(ValueError, match="fit it first"):
        with_serve_short(small_model())


CONTACT = [11.9, -0.8, 2.9]      # the deuce court's serve: its box lies at lateral -4.115..0


def test_the_lateral_bands_split_the_box_toward_its_sideline():
    band = serve_bias.lateral_bands(torch.tensor([CONTACT, [11.9, 0.8, 2.9]]))
    lateral = torch.as_tensor(serve_bias._LATERAL_CENTRES_M)
    for row, sign in ((0, -1.0), (1, 1.0)):
        b = band[row]
        inside = (lateral * sign > 0) & (lateral.abs() < 4.115)
        assert ((b >= 0) == inside).all() and int(inside.sum()) == 28
        toward = (lateral * sign)[inside]
        assert (b[inside] == (toward / (4.115 / 7)).floor().long()).all()
        assert torch.bincount(b[inside]).tolist() == [4] * 7
    shifts = torch.arange(7.0)[None].expand(2, -1)
    got = serve_bias.lateral_shift(shifts, torch.tensor([CONTACT, [11.9, 0.8, 2.9]]))
    assert (got[band < 0] == 0).all() and (got[band >= 0] == band[band >= 0].float()).all()


def _lateral_states(model, n_per=(600, 600), seed=0):
    """First serves in the box: server 2 to the T (band 0) or out wide (band 6) half and half,
    server 3 anywhere in the box; every depth in the box."""
    rng = np.random.default_rng(seed)
    n = sum(n_per)
    sid = np.repeat([2, 3], n_per)
    band = serve_bias.lateral_bands(torch.tensor([CONTACT]))[0].numpy()
    inside = np.flatnonzero(band >= 0)
    ends = np.flatnonzero((band == 0) | (band == 6))
    lateral = np.where(sid == 2, rng.choice(ends, n), rng.choice(inside, n))
    depth = rng.choice(np.flatnonzero(serve_bias.long_fraction() == 0)[-24:], n)
    bins = np.stack([depth, lateral, rng.integers(30, 60, n), rng.integers(96, size=n)], -1)
    return HeadStates(torch.randn(n, model.cfg.d_model), torch.as_tensor(bins), np.arange(n),
                      np.zeros(n, dtype=np.int64), np.tile(CONTACT, (n, 1)),
                      np.zeros(n, dtype=bool), sid.astype(np.int64))


def test_the_lateral_shifts_match_each_servers_bands_and_keep_his_wide_odds():
    model, st = _served_without(_lateral_states, fit_serve_lateral, "with_serve_lateral")
    model = with_serve_lateral(model)
    assert model.serve_lateral.shape == (6, 2, 7) and (model.serve_lateral == 0).all()
    table = fit_serve_lateral(model, st, prior_serves=0.0)
    assert set(table["server_id"]) == {2, 3} and (table["n"] == 600).all()
    for _, g in table.groupby("server_id"):
        assert g["after"].to_numpy() == pytest.approx(g["record"].to_numpy(), abs=0.01)
        assert g["wide_after"].iloc[0] == pytest.approx(g["wide_odds"].iloc[0], abs=1e-3)
        assert g["shift"].sum() == pytest.approx(0.0, abs=1e-4)
    two = table[table["server_id"] == 2].set_index("band")
    assert two.loc[[0, 6], "record"].sum() == pytest.approx(1.0) and two.loc[3, "head"] > 0.05
    # A refit on the same serves changes nothing: it keeps the wide odds the file draws with its
    # bands (read without them, the wide shift was moved a second time).
    first = model.state_dict()
    again = fit_serve_lateral(model, st, prior_serves=0.0)
    for key in ("serve_bias", "serve_lateral"):
        assert torch.allclose(model.state_dict()[key], first[key], atol=1e-3), key
    assert again["wide_odds"].to_numpy() == pytest.approx(table["wide_odds"].to_numpy(),
                                                          abs=1e-3)
    # Drawn with the tables: server 2's serves in the box go to the T or wide, server 3's do not.
    bias = model.serve_head_bias(torch.as_tensor(st.server_id), torch.as_tensor(st.serve),
                                 torch.as_tensor(st.contact_m, dtype=torch.float32))
    draws = torch.stack([model.serve_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                                 dim_bias=bias) for k in range(8)])
    band = serve_bias.lateral_bands(torch.tensor([CONTACT]))[0].numpy()[draws[..., 1].numpy()]
    for sid, lo, hi in ((2, 0.9, 1.0), (3, 0.15, 0.4)):
        got = band[:, st.server_id == sid]
        ends = ((got == 0) | (got == 6))[got >= 0].mean()
        assert lo <= ends <= hi, (sid, ends)
    # The shift is read on the box's lateral bins of that server's serve only.
    model.serve_lateral.zero_()
    model.serve_bias.zero_()
    model.serve_lateral[3, 1] = torch.arange(7.0)
    b = model.serve_head_bias(torch.tensor([3, 3]), torch.tensor([1, 0]),
                              torch.tensor([CONTACT, CONTACT]))
    box = serve_bias.lateral_bands(torch.tensor([CONTACT]))[0]
    assert (b[0, 1][box >= 0] == box[box >= 0].float()).all() and (b[0, 1][box < 0] == 0).all()
    assert (b[1] == 0).all() and (b[0, [0, 2, 3]] == 0).all()
    with pytest.raises(ValueError, match="serve_bias"):
        ModelConfig(serve_head=True, serve_lateral=True)
    with pytest.raises(ValueError, match="fit it first"):
        with_serve_lateral(small_model())
