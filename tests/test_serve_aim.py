"""The serve head's per-server aim inside the box (`sportsngen.model.serve_bias.aim_tilt`,
`sportsngen.train.serve_bias.fit_serve_aim`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import serve_bias, strike
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.tennis.court import SINGLES_HALF_WIDTH_M
from sportsngen.train.head_fit import HeadStates
from sportsngen.train.serve_bias import fit_serve_aim, with_serve_aim, with_serve_bias

# The four places a serve is struck from: end x sign, side y sign.
CONTACTS = torch.tensor([[11.9, 0.8, 2.9], [11.9, -0.8, 2.9], [-11.9, 0.8, 2.9],
                         [-11.9, -0.8, 2.9]])


def small_model() -> SportsNGEN:
    torch.manual_seed(0)
    return SportsNGEN(ModelConfig(
        d_model=32, n_layers=1, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
        embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised", head_hidden=16,
        window_s=4.0, fps=25.0, n_ids=6, n_tournaments=2, event_d_model=16, event_layers=1,
        event_heads=2, ball_centre="physics", serve_head=True)).eval()


def test_toward_the_sideline_is_the_distance_into_the_box_aimed_at():
    toward = serve_bias.toward_sideline_m(CONTACTS)
    centres = strike.serve_edges()[1]
    centres = 0.5 * (centres[1:] + centres[:-1])
    # The box diagonally opposite: the hitter's lateral sign times the contact's x and y
    # signs (the lateral is toward the hitter's left, `serve_wide`'s reading).
    for row, c in enumerate(CONTACTS):
        want = np.sign(c[0].item()) * np.sign(c[1].item()) * centres
        np.testing.assert_allclose(toward[row].numpy(), want, atol=1e-5)
        inside = (toward[row] >= 0) & (toward[row] <= SINGLES_HALF_WIDTH_M)
        wide = serve_bias.wide_bins(c[None])[0]
        assert not (inside & wide).any() and (inside | wide).all()
        assert int(inside.sum()) == 28          # the box's 4.115 m: 28 bins of 0.147 m


def test_the_aim_tilts_the_box_about_its_middle_and_leaves_the_rest():
    tilt = serve_bias.aim_tilt(CONTACTS)
    toward = serve_bias.toward_sideline_m(CONTACTS)
    inside = (toward >= 0) & (toward <= SINGLES_HALF_WIDTH_M)
    assert (tilt[~inside] == 0).all()
    torch.testing.assert_close(tilt[inside], toward[inside] - SINGLES_HALF_WIDTH_M / 2)
    # The box's bins sit symmetric about its middle: the tilt sums to zero over them.
    assert float((tilt * inside).sum(-1).abs().max()) < 1e-4


def test_the_aim_is_added_at_zero_and_read_per_server_and_serve():
    model = with_serve_bias(small_model())
    with pytest.raises(ValueError, match="serve_bias"):
        ModelConfig(serve_head=True, serve_aim=True)
    with pytest.raises(ValueError, match="serve head.s table"):
        with_serve_aim(small_model())
    before = model.serve_head_bias(torch.tensor([3]), torch.tensor([1]), CONTACTS[:1])
    model = with_serve_aim(model)
    assert model.serve_aim.shape == (6, 2) and (model.serve_aim == 0).all()
    torch.testing.assert_close(
        model.serve_head_bias(torch.tensor([3]), torch.tensor([1]), CONTACTS[:1]), before)
    model.serve_aim[3, 1] = 0.7
    b = model.serve_head_bias(torch.tensor([3, 3, 2]), torch.tensor([1, 0, 1]),
                              CONTACTS[[1, 1, 1]])
    torch.testing.assert_close(b[0, 1], 0.7 * serve_bias.aim_tilt(CONTACTS[1:2])[0])
    assert (b[1:] == 0).all()                   # another serve, another server: none
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.serve_aim, model.serve_aim)


def _states(model, seed=0):
    """First serves of two servers: server 2's recorded serves land at the box's outer edge
    (3.0-4.0 m toward the sideline), server 3's at the T (0.1-1.0 m), all in the box's depth,
    from all four places."""
    rng = np.random.default_rng(seed)
    n_per = 300
    sid = np.repeat([2, 3], n_per)
    contact = CONTACTS[rng.integers(4, size=2 * n_per)]
    toward = serve_bias.toward_sideline_m(contact).numpy()
    want = np.where(sid[:, None] == 2, (toward > 3.0) & (toward < 4.0),
                    (toward > 0.1) & (toward < 1.0))
    lateral = np.array([rng.choice(np.flatnonzero(w)) for w in want])
    frac = serve_bias.long_fraction()
    depth = rng.choice(np.flatnonzero(frac == 0)[-20:], 2 * n_per)
    bins = np.stack([depth, lateral, rng.integers(40, 60, 2 * n_per),
                     rng.integers(96, size=2 * n_per)], -1)
    return HeadStates(torch.randn(2 * n_per, model.cfg.d_model), torch.as_tensor(bins),
                      np.arange(2 * n_per), np.zeros(2 * n_per, dtype=np.int64),
                      contact.numpy(), np.zeros(2 * n_per, dtype=bool), sid.astype(np.int64))


def test_the_fit_meets_each_servers_aim_and_holds_his_wide_faults():
    model = with_serve_aim(with_serve_bias(small_model()))
    model.serve_bias[2, 0, serve_bias.WIDE] = -0.5
    st = _states(model)
    table = fit_serve_aim(model, st, prior_serves=0.0).set_index("server_id")
    for sid in (2, 3):
        r = table.loc[sid]
        assert r["toward_after_m"] == pytest.approx(r["toward_record_m"], abs=1e-3)
        assert r["wide_after"] == pytest.approx(r["wide_odds"], abs=1e-4)
        assert model.serve_bias[sid, 0, serve_bias.WIDE] == pytest.approx(r["wide_shift"])
    assert 3.0 < table.loc[2, "toward_record_m"] < 4.0
    assert 0.1 < table.loc[3, "toward_record_m"] < 1.0
    assert table.loc[3, "aim"] < 0 < table.loc[2, "aim"]
    assert model.serve_aim[2, 0] == pytest.approx(table.loc[2, "aim"])
    assert (model.serve_aim[:, 1] == 0).all() and (model.serve_aim[[0, 1, 4, 5]] == 0).all()
    # Pseudo-serves pull the aim toward the head's own.
    pulled = with_serve_aim(with_serve_bias(small_model()))
    p = fit_serve_aim(pulled, st, prior_serves=300.0).set_index("server_id")
    for sid in (2, 3):
        r = p.loc[sid]
        assert r["toward_after_m"] == pytest.approx(
            0.5 * (r["toward_record_m"] + r["toward_head_m"]), abs=1e-3)
    # Too few serves in the box: left at zero.
    fresh = with_serve_aim(with_serve_bias(small_model()))
    assert fit_serve_aim(fresh, st, min_serves=301).empty
    assert (fresh.serve_aim == 0).all()


def test_the_fitted_model_draws_each_servers_aim():
    model = with_serve_aim(with_serve_bias(small_model()))
    st = _states(model, seed=1)
    table = fit_serve_aim(model, st, prior_serves=0.0).set_index("server_id")
    contact = torch.as_tensor(st.contact_m)
    bias = model.serve_head_bias(torch.as_tensor(st.server_id), torch.as_tensor(st.serve),
                                 contact)
    toward = serve_bias.toward_sideline_m(contact)
    got = {2: [], 3: []}
    for k in range(20):
        draws = model.serve_head.sample(st.h, 1.0, torch.Generator().manual_seed(k),
                                        dim_bias=bias)
        t = toward[torch.arange(len(draws)), draws[:, 1]]
        inside = (t >= 0) & (t <= SINGLES_HALF_WIDTH_M)
        for sid in (2, 3):
            sel = inside & torch.as_tensor(st.server_id == sid)
            got[sid].append(t[sel])
    for sid in (2, 3):
        # The draws' depth is the head's own, not the record's: the aim holds at every depth
        # of the box to within a few centimetres here.
        mean = float(torch.cat(got[sid]).mean())
        assert mean == pytest.approx(table.loc[sid, "toward_record_m"], abs=0.15), (sid, mean)
