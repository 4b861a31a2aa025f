"""The shift of the ball's odds of a racket contact by where the ball is from its hitter
(`sportsngen.model.contact_reach`, `sportsngen.train.contact_reach`)."""

import numpy as np
import pytest
import torch

from sportsngen.model import contact_reach as cr
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.contact_reach import (
    ContactStates,
    cell_table,
    collect_contact_states,
    fit_contact_reach,
    with_contact_reach,
)
from tests.test_serve_bias import small_model as serve_small_model

FPS = 25.0


def small_model(**kw) -> SportsNGEN:
    return serve_small_model(**{"bin_centre": "cv", **kw})


def frame(ball=(13.0, 1.0, 1.0), ball_v=(25.0, 0.0, 0.0), server=(-12.0, 0.5),
          receiver=(15.0, -1.0)):
    """Server at -x, receiver at +x; the ball at `ball` moving `ball_v`."""
    pos = torch.zeros(3, 3)
    pos[0, :2] = torch.tensor(server)
    pos[1, :2] = torch.tensor(receiver)
    pos[2] = torch.tensor(ball)
    vel = torch.zeros(3, 3)
    vel[2] = torch.tensor(ball_v)
    return pos, vel


@pytest.mark.parametrize("kw, frames, aside, incoming", [
    # 2 m short of the receiver's line at 25 m/s: 2 frames; 2 m beside him.
    ({}, 2.0, 2.0, True),
    ({"ball": (16.0, -1.5, 1.0)}, -1.0, 0.5, True),            # a metre past his line
    ({"ball_v": (-25.0, 0.0, 0.0)}, 2.0, 2.0, False),           # flying back to the net
    ({"ball_v": (1.5, 0.0, 0.0)}, 2.0 * 25 / 2.0, 2.0, False),  # slower than 2 m/s
    # On the server's end (mirrored): he is the hitter, 1.5 m away along x at 30 m/s.
    ({"ball": (-10.5, 0.0, 1.0), "ball_v": (-30.0, 0.0, 0.0)}, 1.25, 0.5, True),
])
def test_the_geometry_reads_the_player_on_the_balls_end(kw, frames, aside, incoming):
    pos, vel = frame(**kw)
    f, a, inc = cr.reach_geometry(pos, vel, FPS)
    assert float(f) == pytest.approx(frames)
    assert float(a) == pytest.approx(aside)
    assert bool(inc) is incoming
    cell = int(cr.reach_cells(pos, vel, FPS))
    if not incoming:
        assert cell == -1
    else:
        fi = int(np.searchsorted(cr.FRAMES_EDGES, frames, side="right"))
        ai = int(np.searchsorted(cr.ASIDE_EDGES_M, aside, side="right"))
        assert cell == fi * cr.N_ASIDE_CELLS + ai


def test_the_cells_cover_the_table_and_batch():
    pos, vel = frame()
    p = pos.expand(5, 3, 3).clone()
    p[:, 2, 0] = torch.tensor([-20.0, 5.0, 14.0, 15.0, 17.0])       # the far end: server's
    p[0, 2, 0] = 14.99                                               # a hair short of him
    cells = cr.reach_cells(p, vel.expand(5, 3, 3), FPS)
    # 14.99: 0.01 m short at 1 m a frame; 5 m: 10 m short, 10 frames (the last edge: >10
    # cell); 14, 15 and 17: 1, 0 and -2 frames.
    fi = cells // cr.N_ASIDE_CELLS
    assert fi.tolist() == [3, 10, 5, 3, 0]
    assert (cells % cr.N_ASIDE_CELLS == 5).all()           # 2 m aside: the 2-2.5 m cell
    assert cells.max() < cr.N_CELLS


def test_strike_and_jolt_bins_follow_the_frame_the_bin_puts_down():
    pos, _ = frame()
    step = torch.tensor(1.0)                                # 25 m/s toward the receiver
    bin_x = torch.tensor([-2.4, -1.2, -0.6, 0.0, 0.3, 0.8])
    contact = bin_x.abs() > 0.5
    strike, jolt = cr.bin_kinds(pos, step, bin_x, contact, FPS)
    # -2.4: back at 35 m/s; -1.2: back at 5 m/s; -0.6: on at 10 m/s (braked); 0.8: on faster.
    assert strike.tolist() == [True, True, False, False, False, False]
    assert jolt.tolist() == [False, False, True, False, False, True]
    # Mirrored at the other end.
    pos2, _ = frame(ball=(-13.0, 1.0, 1.0))
    strike2, _ = cr.bin_kinds(pos2, -step, -bin_x, contact, FPS)
    assert strike2.tolist() == strike.tolist()


def test_the_bias_puts_each_cells_shifts_on_its_strike_and_jolt_bins():
    table = torch.zeros(cr.N_KINDS, cr.N_FRAMES_CELLS, cr.N_ASIDE_CELLS)
    pos, vel = frame()                                      # cell (frames 2-3, 2-2.5 m)
    fi, ai = divmod(int(cr.reach_cells(pos, vel, FPS)), cr.N_ASIDE_CELLS)
    table[cr.STRIKE, fi, ai] = -3.0
    table[cr.JOLT, fi, ai] = 1.5
    strike = torch.tensor([[True, False, False, False]])
    jolt = torch.tensor([[False, True, False, False]])
    p = torch.stack([pos, frame(ball_v=(-25.0, 0.0, 0.0))[0]])
    v = torch.stack([vel, -vel])                            # the second flies away: no shift
    got = cr.ball_dim_bias(table, p, v, strike.expand(2, 4), jolt.expand(2, 4), FPS)
    want = torch.zeros(2, 3, 4)
    want[0, 0, 0], want[0, 0, 1] = -3.0, 1.5
    torch.testing.assert_close(got, want)


def test_kind_probabilities_are_the_shifted_softmax():
    logits = torch.log(torch.tensor([[0.2, 0.1, 0.7]]))
    got = cr.kind_probabilities(logits, torch.tensor([[float(np.log(3.0)), 0.0]]))
    torch.testing.assert_close(got, torch.tensor([[0.6, 0.1, 0.7]]) / 1.4)


def _states(n=(600, 300), seed=0):
    """Two cells: 40 (the head says 0.3 strike, 0.05 jolt; the record strikes 60 %) and 70
    (the head 0.1 and 0.1; the record 0 and 2 %), with the head's odds varying by frame."""
    rng = np.random.default_rng(seed)
    parts = []
    for cell, k, ps, pj, rs, rj in ((40, n[0], 0.3, 0.05, 0.6, 0.0),
                                    (70, n[1], 0.1, 0.1, 0.0, 0.02)):
        base = np.log(np.array([ps, pj, 1 - ps - pj]))
        logits = torch.tensor(base + rng.normal(0, 0.3, (k, 3)), dtype=torch.float32)
        u = rng.random(k)
        kind = np.where(u < rs, 0, np.where(u < rs + rj, 1, 2))
        parts.append(ContactStates(np.full(k, cell), logits, kind, np.arange(k)))
    return ContactStates.concat(parts)


def test_the_fit_matches_each_cells_shares_pulled_toward_the_head():
    model = with_contact_reach(small_model())
    st = _states()
    fit = fit_contact_reach(model, st, prior_frames=0.0, min_frames=50).set_index("cell")
    for c in (40, 70):
        assert fit.loc[c, "after"] == pytest.approx(fit.loc[c, "record"], abs=1e-4)
        assert fit.loc[c, "after_jolt"] == pytest.approx(fit.loc[c, "record_jolt"], abs=1e-4)
    assert fit.loc[40, "shift"] > 1.0 and fit.loc[70, "shift"] == pytest.approx(-8.0, abs=1e-3)
    flat = model.contact_reach.view(cr.N_KINDS, -1)
    assert flat[cr.STRIKE, 40] == pytest.approx(fit.loc[40, "shift"])
    assert flat[cr.JOLT, 70] == pytest.approx(fit.loc[70, "shift_jolt"])
    assert int((flat != 0).sum()) == 4                      # two cells, two kinds
    # The table applied to the states gives the same odds.
    tab = cell_table(st, model.contact_reach).set_index("cell")
    assert tab.loc[40, "shifted"] == pytest.approx(tab.loc[40, "record"], abs=1e-4)
    assert tab.loc[40, "head"] == pytest.approx(fit.loc[40, "head"], abs=1e-6)
    # A prior pulls toward the head; a cell under min_frames keeps 0.
    pulled = fit_contact_reach(model, st, prior_frames=200.0, min_frames=400).set_index("cell")
    assert list(pulled.index) == [40]
    w = 600 / 800
    want = w * pulled.loc[40, "record"] + (1 - w) * pulled.loc[40, "head"]
    assert pulled.loc[40, "after"] == pytest.approx(want, abs=1e-4)
    assert model.contact_reach.view(cr.N_KINDS, -1)[:, 70].abs().sum() == 0
    with pytest.raises(ValueError, match="with_contact_reach"):
        fit_contact_reach(small_model(), st)


def test_the_table_is_added_at_zero_saved_and_read_by_the_sampler():
    plain = small_model(n_bins=61)
    assert plain.contact_reach is None
    pos, vel = frame(ball=(14.5, 1.0, 1.0))                 # half a frame from his line
    assert plain.contact_reach_bias(pos, vel, plain.centres(pos, vel)) is None
    model = with_contact_reach(plain)
    assert model.contact_reach.shape == (cr.N_KINDS, cr.N_FRAMES_CELLS, cr.N_ASIDE_CELLS)
    assert (model.contact_reach == 0).all() and with_contact_reach(model) is model
    n = 400
    p, v = pos.expand(n, 3, 3).clone(), vel.expand(n, 3, 3).clone()
    h = torch.randn(n, 3, model.cfg.d_model, generator=torch.Generator().manual_seed(1))

    centre = model.centres(p, v, v)
    strike_bins, _ = model.contact_bin_kinds(p, centre)

    def struck(contact_odds):
        """Rows whose sampled ball lies in a strike bin (the bins read back from the offset)."""
        nxt = model.sample_next(h, p, v, 1.0, 1.0, torch.Generator().manual_seed(0), v,
                                contact_odds=contact_odds)
        _, bins = model.offset_bins(model.to_model_frame(nxt - centre, p))
        return strike_bins[torch.arange(n), bins[:, 0]]

    base = struck(False).float().mean()
    assert 0.0 < base < 1.0                                  # the untrained head: some
    model.contact_reach[cr.STRIKE] = 30.0
    assert struck(False).all() and struck(True).all()
    model.contact_reach[cr.STRIKE] = -30.0
    assert not struck(False).any() and not struck(True).any()
    again = SportsNGEN(model.cfg)
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again.contact_reach, model.contact_reach)
    # A ball flying away from the receiver is not shifted.
    away = v.clone()
    away[:, 2, 0] = -25.0
    assert (model.contact_reach_bias(p, away, model.centres(p, away)) == 0).all()
    with pytest.raises(ValueError, match="factorised"):
        ModelConfig(contact_reach=True, head="joint")


def test_states_are_read_from_generated_rallies():
    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.synth.generate import generate_matches

    data = generate_matches([("Serena Williams", "Maria Sharapova")], "hard", 4, seed=0,
                            workers=1)
    vocab = Vocab.from_data(data)
    model = with_contact_reach(small_model(n_ids=vocab.n_ids, n_bins=61))
    st = collect_contact_states(model, rally_arrays(data, vocab), progress=False)
    assert len(st) == len(st.logits) == len(st.kind) and st.logits.shape[1] == 3
    assert ((st.cell >= 0) & (st.cell < cr.N_CELLS)).all()
    # Log-probabilities of strike, jolt and rest: they sum to one.
    torch.testing.assert_close(st.logits.logsumexp(-1), torch.zeros(len(st)), atol=1e-4,
                               rtol=0)
    # Every returned serve and rally ball is struck from a ball coming to the hitter: about
    # one strike for each shot after the serve, where the ball is near him.
    shots_after_serve = int((data.shots["shot_index"] >= 1).sum())
    n_strikes = int((st.kind == 0).sum())
    assert 0.8 * shots_after_serve <= n_strikes <= shots_after_serve
    near = st.cell // cr.N_ASIDE_CELLS
    assert np.median(near[st.kind == 0]) <= 5                # within 1.5 frames of his line
    assert (st.kind == 0).mean() < 0.1                       # most frames: flight


@pytest.mark.parametrize("frame_kind", ["world", "server"])
def test_the_compiled_shifts_are_the_torch_ones(monkeypatch, frame_kind):
    """`reach_kernel.reach_bias_rows` against `contact_bin_kinds` + `ball_dim_bias`, on balls
    coming to and going from either player at either end, in either model frame."""
    from sportsngen.model import decoder

    model = with_contact_reach(small_model(n_bins=61, frame=frame_kind))
    g = torch.Generator().manual_seed(2)
    model.contact_reach.copy_(torch.randn(model.contact_reach.shape, generator=g))
    n = 5000
    end = torch.where(torch.rand(n, generator=g) < 0.5, -1.0, 1.0)
    pos = torch.zeros(n, 3, 3)
    pos[:, 0, 0] = -12.0 * end
    pos[:, 1, 0] = 12.0 * end + torch.randn(n, generator=g)
    pos[:, :2, 1] = torch.randn(n, 2, generator=g) * 2
    pos[:, 2, 0] = torch.empty(n).uniform_(-16, 16, generator=g)
    pos[:, 2, 1] = torch.randn(n, generator=g) * 2
    pos[:, 2, 2] = torch.empty(n).uniform_(0.2, 2.5, generator=g)
    vel = torch.zeros(n, 3, 3)
    vel[:, 2] = torch.randn(n, 3, generator=g) * torch.tensor([25.0, 3.0, 4.0])
    centre = model.centres(pos, vel, vel)
    got = model.contact_reach_bias(pos, vel, centre)
    with monkeypatch.context() as m:
        m.setattr(decoder, "kernel_inputs", lambda *t: False)
        want = model.contact_reach_bias(pos, vel, centre)
    assert torch.equal(got, want)
    assert (want[:, 0] != 0).any(-1).float().mean() > 0.2          # shifted rows
    assert (want[:, 1:] == 0).all()
