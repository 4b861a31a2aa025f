"""Decoder f, mask, KV cache, bins, heads, top-p sampling, event classifier, export."""

import math

import numpy as np
import pytest
import torch

from sportsngen.model import (
    EventClassifier,
    ModelConfig,
    SportsNGEN,
    baller2vec_mask,
    load_model,
    sample_top_p,
    save_model,
    top_p_filter,
)
from sportsngen.model.bins import Bins, flat_index, unflat_index
from sportsngen.model.heads import FactorisedHead, JointHead
from sportsngen.model.inputs import N_FEATURES

torch.set_num_threads(1)


def tiny_cfg(**kw) -> ModelConfig:
    base = dict(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
                embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
                head_hidden=16, window_s=0.4, fps=25.0, n_ids=5, n_tournaments=3,
                event_d_model=16, event_layers=1, event_heads=2)
    base.update(kw)
    return ModelConfig(**base)


def inputs(cfg: ModelConfig, b: int = 2, t: int = 6, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    feats = torch.randn(b, t, 3, N_FEATURES, generator=g)
    ident = torch.tensor([[2, 3, 0], [4, 1, 0], [3, 4, 0]])[:b]
    ctx = (torch.tensor([0, 2, 1])[:b], torch.tensor([1, 0, 1])[:b], torch.tensor([0, 1, 1])[:b],
           torch.rand(b, 7, generator=g))
    return feats, ident, ctx


def make_model(**kw) -> SportsNGEN:
    torch.manual_seed(0)
    return SportsNGEN(tiny_cfg(**kw)).eval()


def test_mask_small_case_exact():
    m = baller2vec_mask(n_ctx=1, n_frames=2, n_objects=2)
    expected = torch.tensor([[1, 0, 0, 0, 0],
                             [1, 1, 1, 0, 0],
                             [1, 1, 1, 0, 0],
                             [1, 1, 1, 1, 1],
                             [1, 1, 1, 1, 1]], dtype=torch.bool)
    assert torch.equal(m, expected)


@pytest.mark.parametrize("head", ["joint", "factorised"])
def test_mask_hides_the_future(head):
    model = make_model(head=head)
    feats, ident, ctx = inputs(model.cfg)
    c = model.context_tokens(*ctx)
    with torch.no_grad():
        h = model(feats, ident, c)
        changed = feats.clone()
        changed[:, 3] += 5.0  # a later frame
        h2 = model(changed, ident, c)
    assert torch.equal(h[:, :3], h2[:, :3])  # earlier frames exactly unchanged
    assert (h[:, 3:] - h2[:, 3:]).abs().max() > 1e-3


@pytest.mark.parametrize("spacing", ["uniform", "nonuniform"])
def test_bins_round_trip_within_half_a_bin(spacing):
    bins = Bins((0.4, 0.4, 1.6), 61, spacing)
    g = torch.Generator().manual_seed(1)
    off = (torch.rand(5000, 3, generator=g) * 2 - 1) * torch.tensor([0.4, 0.4, 1.6]) * 0.999
    idx = bins.index(off)
    assert idx.min() >= 0 and idx.max() <= 60
    back = bins.value(idx)
    assert ((back - off).abs() <= bins.width(idx) / 2 + 1e-7).all()
    assert torch.equal(bins.index(torch.zeros(1, 3)), torch.full((1, 3), 30))  # 0 in the middle
    far = bins.index(torch.tensor([[9.0, -9.0, 0.0]]))  # beyond the range: outer bins
    assert far.tolist() == [[60, 0, 30]]
    flat = flat_index(idx, 61)
    assert torch.equal(unflat_index(flat, 61, 3), idx) and flat.max() < 61 ** 3


def test_nonuniform_bins_are_finer_near_zero():
    w = Bins((1.0,), 21, "nonuniform").width(torch.arange(21)[:, None])[:, 0]
    assert w[10] < w[5] < w[0]
    assert w.sum().item() == pytest.approx(2.0, rel=1e-6)


@pytest.mark.parametrize("head", ["joint", "factorised"])
def test_heads_are_normalised_distributions(head):
    torch.manual_seed(0)
    n = 5
    h = torch.randn(4, 16)
    m = JointHead(16, n, 3) if head == "joint" else FactorisedHead(16, n, 3, hidden=8)
    grid = torch.cartesian_prod(torch.arange(n), torch.arange(n), torch.arange(n))
    with torch.no_grad():
        nll = m.nll(h[:, None].expand(4, len(grid), 16), grid[None].expand(4, -1, -1))
    total = torch.exp(-nll).sum(dim=1)
    torch.testing.assert_close(total, torch.ones(4), atol=1e-5, rtol=0)


def test_top_p_keeps_only_the_nucleus():
    probs = torch.tensor([0.05, 0.5, 0.15, 0.3])
    logits = probs.log()
    keep = lambda p: torch.isfinite(top_p_filter(logits, p)).nonzero().flatten().tolist()  # noqa: E731
    assert keep(0.5) == [1]
    assert keep(0.8) == [1, 3]
    assert keep(0.81) == [1, 2, 3]
    assert keep(1.0) == [0, 1, 2, 3]
    g = torch.Generator().manual_seed(0)
    draws = sample_top_p(logits.expand(4000, 4), 0.8, g)
    assert set(draws.tolist()) == {1, 3}
    assert (draws == 1).float().mean().item() == pytest.approx(0.5 / 0.8, abs=0.03)
    again = sample_top_p(logits.expand(4000, 4), 0.8, torch.Generator().manual_seed(0))
    assert torch.equal(draws, again)  # seeded
    with pytest.raises(ValueError, match="top_p"):
        top_p_filter(logits, 0.0)


def test_factorised_sampling_tiny_nucleus_is_greedy():
    torch.manual_seed(0)
    m = FactorisedHead(16, 7, 3, hidden=8)
    h = torch.randn(10, 16)
    with torch.no_grad():
        assert torch.equal(m.sample(h, 1e-6, torch.Generator().manual_seed(0)), m.top1(h))


@pytest.mark.parametrize("head", ["joint", "factorised"])
def test_cache_step_equals_full_window(head):
    model = make_model(head=head)
    cfg = model.cfg
    t = cfg.window_frames  # 10 frames
    feats, ident, ctx = inputs(cfg, t=t)
    c = model.context_tokens(*ctx)
    with torch.no_grad():
        full = model(feats, ident, c)
        cache = model.init_cache(ident, c)
        for k in range(t):
            h, cache = model.forward_step(feats[:, k], cache)
            assert (h - full[:, k]).abs().max().item() < 1e-4
        # Prefill half the window, then step: the same again.
        _, cache = model(feats[:, :4], ident, c, return_cache=True)
        for k in range(4, t):
            h, cache = model.forward_step(feats[:, k], cache)
            assert (h - full[:, k]).abs().max().item() < 1e-4
        if head == "joint":
            lg = model.ball_head.logits(h[:, 2])
            assert (lg - model.ball_head.logits(full[:, -1, 2])).abs().max().item() < 1e-4
    assert cache.n_frames == t


@pytest.mark.parametrize("prefill", [0, 7, 13])
def test_ring_cache_equals_band_recompute_beyond_the_window(prefill):
    """Past the window, stepping the ring cache equals `forward` on the whole rally with the
    band mask (every layer sees at most window_frames frames), for a deep model."""
    model = make_model(n_layers=3)
    w = model.cfg.window_frames
    t = 2 * w + 5
    feats, ident, ctx = inputs(model.cfg, t=t)
    c = model.context_tokens(*ctx)
    with torch.no_grad():
        full = model(feats, ident, c)
        if prefill:
            _, cache = model(feats[:, :prefill], ident, c, return_cache=True)
        else:
            cache = model.init_cache(ident, c)
        for k in range(prefill, t):
            h, cache = model.forward_step(feats[:, k], cache)
            assert (h - full[:, k]).abs().max().item() < 1e-4
    assert cache.n_frames == t and cache.n_keys == 4 + 3 * w


@pytest.mark.parametrize("forecast", [False, True])
def test_compiled_step_equals_the_eager_step_past_the_window(forecast):
    """`compile_step` changes how the cached step runs, not what it computes: through the ring's
    wrap-around and a batch compaction, the traced step's states equal the eager ones. The
    graphs are run as traced (a backend that counts them), not through inductor: its C++ code
    generation is torch's to test and took a minute of this suite on a cold cache. With the
    ball forecast, whose compiled numba loop the graph calls out to."""
    model = make_model(ball_forecast=forecast)
    w = model.cfg.window_frames
    feats, ident, ctx = inputs(model.cfg, b=3, t=w + 4)
    c = model.context_tokens(*ctx)
    graphs = []

    def traced(gm, example_inputs):
        graphs.append(gm)
        return gm.forward

    def run():
        _, cache = model(feats[:, :2], ident, c, return_cache=True)
        states, rows = [], torch.arange(3)
        for k in range(2, w + 4):
            if k == w:      # a rally ends: the batch drops row 1
                rows = torch.tensor([0, 2])
                cache = cache.select(torch.tensor([0, 2]))
            h, cache = model.forward_step(feats[rows, k], cache)
            states.append(h)
        return states, cache

    with torch.inference_mode():            # as rollouts run
        eager, eager_cache = run()
        model.compile_step(backend=traced)
        compiled, compiled_cache = run()
    assert model._compiled_step is not None and len(graphs) >= 1, graphs
    assert max((a - b).abs().max().item() for a, b in zip(eager, compiled)) < 1e-5
    assert all(torch.allclose(a, b, atol=1e-5) for a, b in zip(eager_cache.k, compiled_cache.k))
    model.compile_step(False)
    assert model._compiled_step is None


def test_band_mask_hides_frames_older_than_the_window():
    m = baller2vec_mask(n_ctx=1, n_frames=4, n_objects=1, window_frames=2)
    assert m[:, 0].all()                                   # context visible to all
    assert m[3, 3] and m[3, 2] and not m[3, 1]             # frame 2 sees frames 1, 2 only
    assert torch.equal(baller2vec_mask(1, 4, 1, window_frames=4), baller2vec_mask(1, 4, 1))


def test_cache_select_keeps_rows():
    model = make_model()
    feats, ident, ctx = inputs(model.cfg, b=3, t=5)
    c = model.context_tokens(*ctx)
    with torch.no_grad():
        full = model(feats, ident, c)
        _, cache = model(feats[:, :3], ident, c, return_cache=True)
        cache = cache.select(torch.tensor([2, 0]))
        h, _ = model.forward_step(feats[[2, 0], 3], cache)
    assert (h - full[[2, 0], 3]).abs().max().item() < 1e-4


def test_generic_identity_shares_one_embedding():
    model = make_model(generic_identity=True)
    feats, _, ctx = inputs(model.cfg, b=1)
    c = model.context_tokens(*(x[:1] for x in ctx))
    with torch.no_grad():
        a = model(feats, torch.tensor([[2, 3, 0]]), c)
        b = model(feats, torch.tensor([[4, 2, 0]]), c)
    assert torch.equal(a, b)
    with pytest.raises(ValueError, match="identity index out of range"):
        make_model()(feats, torch.tensor([[9, 3, 0]]), c)


@pytest.mark.parametrize("ball_centre", ["velocity", "physics"])
def test_sample_next_players_on_ground_and_reproducible(ball_centre):
    model = make_model(bin_centre="cv", ball_centre=ball_centre)
    feats, ident, ctx = inputs(model.cfg)
    pos = torch.rand(2, 6, 3, 3) + torch.tensor([0.0, 0.0, 1.0])
    pos[..., :2, 2] = 0
    vel = torch.randn(2, 6, 3, 3)
    vel[..., 2, :] += torch.tensor([25.0, 0.0, 3.0])   # a rally ball
    prev = vel + 0.1 * torch.randn(2, 6, 3, 3)
    # The ball's track: gravity and drag plus a lift Magnus could give at 25 m/s.
    from sportsngen.model.centre import flight_acceleration_mps2
    prev[..., 2, :] = vel[..., 2, :] - (flight_acceleration_mps2(vel[..., 2, :])
                                        + 3.0 * torch.rand(2, 6, 3)) / 25.0
    with torch.no_grad():
        h = model(feats, ident, model.context_tokens(*ctx))
        a = model.sample_next(h, pos, vel, 0.9, 0.9, torch.Generator().manual_seed(3), prev)
        b = model.sample_next(h, pos, vel, 0.9, 0.9, torch.Generator().manual_seed(3), prev)
    assert torch.equal(a, b)
    assert (a[..., :2, 2] == 0).all()
    centre = pos + vel / 25.0
    if ball_centre == "physics":  # gravity and drag, plus the track's lift turned, one step
        from sportsngen.model.centre import flight_acceleration_mps2 as base
        from sportsngen.model.centre import turned_lift_mps2
        v, pv = vel[..., 2, :], prev[..., 2, :]
        acc = base(1.5 * v - 0.5 * pv) + turned_lift_mps2(
            (v - pv) * 25.0 - base(0.5 * (v + pv)), pv, v)
        centre[..., 2, :] += acc / 625.0
    assert torch.allclose(model.centres(pos, vel, prev), centre, atol=1e-6)
    lim = torch.tensor([80.0, 40.0, 40.0]) / 25.0
    assert ((a[..., 2, :] - centre[..., 2, :]).abs() <= lim + 1e-6).all()


def test_event_classifier_sees_the_whole_window():
    torch.manual_seed(0)
    cfg = tiny_cfg()
    ec = EventClassifier(cfg).eval()
    feats, _, _ = inputs(cfg)
    with torch.no_grad():
        out = ec(feats)
        changed = feats.clone()
        changed[:, 5] += 3.0
        out2 = ec(changed)
    assert {k: v.shape[-1] for k, v in out.items()} == {
        "stroke": 7, "direction": 9, "outcome": 4, "error_kind": 4}
    assert (out["stroke"][:, 0] - out2["stroke"][:, 0]).abs().max() > 1e-4  # no causal mask


@pytest.mark.parametrize("head", ["joint", "factorised"])
def test_export_reload_identical(tmp_path, head):
    from sportsngen.data.tokens import Vocab

    model = make_model(head=head)
    torch.manual_seed(1)
    ec = EventClassifier(model.cfg).eval()
    vocab = Vocab(("A", "B", "C"), tournaments=("X", "Y"))
    path = save_model(tmp_path / "m.pt", model, vocab, ec)
    m2, ec2, v2, cfg2 = load_model(path)
    assert v2 == vocab and cfg2 == model.cfg
    feats, ident, ctx = inputs(model.cfg)
    with torch.no_grad():
        a = model(feats, ident, model.context_tokens(*ctx))
        b = m2(feats, ident, m2.context_tokens(*ctx))
        assert torch.equal(a, b)
        idx = torch.zeros(2, 6, 3, dtype=torch.long)
        assert torch.equal(model.ball_head.nll(a[..., 2, :], idx), m2.ball_head.nll(b[..., 2, :],
                                                                                  idx))
        assert torch.equal(ec(feats)["outcome"], ec2(feats)["outcome"])
    with pytest.raises(ValueError, match="not a sportsngen model file"):
        torch.save({"state_dict": {}}, tmp_path / "x.pt")
        load_model(tmp_path / "x.pt")


def test_attention_dropout_is_its_own_setting():
    """attn_dropout drops attention probabilities in training only; dropout=0 with
    attn_dropout=0 is deterministic in training mode too."""
    feats, ident, ctx = inputs(tiny_cfg())
    for p, random in ((0.0, False), (0.5, True)):
        model = make_model(attn_dropout=p).train()
        c = model.context_tokens(*ctx)
        with torch.no_grad():
            a, b = model(feats, ident, c), model(feats, ident, c)
            assert torch.equal(a, b) != random
            model.eval()
            assert torch.equal(model(feats, ident, c), model(feats, ident, c))
    with pytest.raises(ValueError, match="model.attn_dropout"):
        tiny_cfg(attn_dropout=1.0)


def test_config_errors():
    with pytest.raises(ValueError, match="model.head"):
        tiny_cfg(head="huge")
    with pytest.raises(ValueError, match="unknown model config keys"):
        ModelConfig.from_dict({"d_model": 8, "bogus": 1})
    with pytest.raises(ValueError, match="n_bins"):
        tiny_cfg(n_bins=10)


def test_paper_joint_heads_size():
    """The paper's joint heads: 61^2 player and 61^3 ball classes (checked on a narrow d)."""
    m = SportsNGEN(tiny_cfg(head="joint", n_bins=61, d_model=8, n_heads=2))
    assert m.player_head.proj.out_features == 61 ** 2
    assert m.ball_head.proj.out_features == 61 ** 3 == 226981
    assert math.isclose(m.ball_bins.edges[0, -1].item(), 80.0 / 25.0, rel_tol=1e-6)


@pytest.mark.parametrize("ball_centre", ["velocity", "physics"])
def test_physics_centred_ball_in_the_centre_bin_stays_on_the_step(ball_centre, monkeypatch):
    # Uniform noise inside the centre bin would be integrated three times by a step that
    # reads the acceleration from the track: with the physics centre the ball takes the step.
    model = make_model(bin_centre="cv", ball_centre=ball_centre)
    n = model.cfg.n_bins
    monkeypatch.setattr(model.ball_head, "sample",
                        lambda h, top_p, gen, regions=None, top_p_regions=None:
                        torch.full((*h.shape[:-1], 3), n // 2))
    pos = torch.tensor([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [-5.0, 1.0, 2.0]]])
    vel = torch.tensor([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [20.0, 0.0, 3.0]]])
    h = torch.zeros(1, 3, model.cfg.d_model)
    nxt = model.sample_next(h, pos, vel, generator=torch.Generator().manual_seed(0),
                            prev_vel_mps=vel)
    off = nxt[0, 2] - model.centres(pos, vel, vel)[0, 2]
    half = model.ball_bins.width(torch.full((3,), n // 2)) / 2
    if ball_centre == "physics":
        assert torch.equal(off, torch.zeros(3))
    else:
        assert (off != 0).all() and (off.abs() <= half).all()


def test_ball_target_bins_sample_back_inside_their_bins(monkeypatch):
    # The target bins of a next position, sampled back, land in the same bins.
    model = make_model(bin_centre="cv", n_bins=61, bin_spacing="nonuniform")
    pos = torch.tensor([[[0.0, -11.0, 0.0], [1.0, 11.0, 0.0], [10.0, 0.5, 2.6]]])
    vel = torch.tensor([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-30.0, -6.0, -4.0]]])
    prev = torch.tensor([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -1.5]]])
    nxt = pos + vel / 25.0 + 0.8 * (vel - prev) / 25.0   # the contact's offset again, scaled
    _, b_idx = model.target_bins(pos, vel, nxt, prev)
    assert (b_idx[0] != model.cfg.n_bins // 2).all()
    monkeypatch.setattr(model.ball_head, "sample",
                        lambda h, top_p, gen, regions=None, top_p_regions=None: b_idx)
    h = torch.zeros(1, 3, model.cfg.d_model)
    again = model.sample_next(h, pos, vel, generator=torch.Generator().manual_seed(0),
                              prev_vel_mps=prev)
    _, b_again = model.target_bins(pos, vel, again, prev)
    assert torch.equal(b_again, b_idx)
    assert (again[0, 2] - nxt[0, 2]).norm() < 0.05


def test_nucleus_in_regions_keeps_the_regions_odds():
    from sportsngen.model.sampling import sample_top_p_in_regions

    # Two contact bins hold 0.30 between them, the no-contact bin 0.70: a plain nucleus of
    # 0.6 never draws a contact; inside regions it does at the model's 0.30, and inside each
    # region the nucleus still trims (bin 3's 0.01 inside the contact side's 0.30 never).
    probs = torch.tensor([0.70, 0.20, 0.09, 0.01])
    logits = probs.log().expand(200_000, 4)
    regions = torch.tensor([False, True, True, True])
    gen = torch.Generator().manual_seed(0)
    plain = sample_top_p(logits, 0.6, gen)
    split = sample_top_p_in_regions(logits, regions, 0.6, gen)
    assert (plain == 0).all()
    share = torch.bincount(split, minlength=4).double() / len(split)
    assert abs(share[0].item() - 0.70) < 0.005
    assert abs(share[1:].sum().item() - 0.30) < 0.005
    assert share[3].item() == 0.0
    assert torch.equal(sample_top_p_in_regions(logits[:50], regions, 1.0,
                                               torch.Generator().manual_seed(1)),
                       sample_top_p(logits[:50], 1.0, torch.Generator().manual_seed(1)))


def test_nucleus_per_row_and_a_wider_nucleus_inside_the_regions():
    from sportsngen.model.sampling import sample_top_p_in_regions

    probs = torch.tensor([0.70, 0.20, 0.09, 0.01])
    logits = probs.log().expand(200_000, 4)
    # One top-p per row: rows at 0.6 keep only bin 0, rows at 0.95 bins 0-2 at their odds.
    row_p = torch.where(torch.arange(len(logits)) % 2 == 0, 0.6, 0.95)
    draws = sample_top_p(logits, row_p, torch.Generator().manual_seed(0))
    assert (draws[::2] == 0).all()
    odd = torch.bincount(draws[1::2], minlength=4).double() / len(draws[1::2])
    assert odd[3].item() == 0.0
    assert abs(odd[0].item() - 0.70 / 0.99) < 0.005
    # A float top-p and the same value on every row draw the same classes.
    same = sample_top_p(logits[:100], torch.full((100,), 0.8), torch.Generator().manual_seed(3))
    assert torch.equal(same, sample_top_p(logits[:100], 0.8, torch.Generator().manual_seed(3)))
    # Inside the regions a nucleus of 1 keeps bin 3 (0.01 of 0.30); outside 0.6 still trims.
    regions = torch.tensor([False, True, True, True])
    split = sample_top_p_in_regions(logits, regions, 0.6, torch.Generator().manual_seed(1),
                                    top_p_inside=1.0)
    share = torch.bincount(split, minlength=4).double() / len(split)
    assert abs(share[0].item() - 0.70) < 0.005
    assert abs(share[3].item() - 0.01) < 0.002
    with pytest.raises(ValueError, match="top_p"):
        sample_top_p(logits[:2], torch.tensor([0.5, 0.0]))


def test_factorised_head_samples_a_struck_row_at_its_own_nucleus():
    torch.manual_seed(0)
    m = FactorisedHead(16, 7, 3, hidden=8)
    h = torch.randn(4000, 16)
    regions = torch.zeros(7, dtype=torch.bool)
    regions[5:] = True

    def greedy_given_x(chosen):
        out = chosen.clone()
        for k in (1, 2):
            out[:, k] = m.dim_logits(h, out, k).argmax(-1)
        return out

    with torch.no_grad():
        p_in = m.dim_logits(h, None, 0).softmax(-1)[:, regions].sum(-1)
        tight = m.sample(h, 1e-6, torch.Generator().manual_seed(0), regions)
        wide = m.sample(h, 1e-6, torch.Generator().manual_seed(0), regions, top_p_regions=1.0)
        g_tight, g_wide = greedy_given_x(tight), greedy_given_x(wide)
    # The side is drawn at the model's odds with the same draws in both; outside the regions
    # x, y and z are greedy in both; inside, y and z are greedy only with the tight nucleus.
    inside = regions[wide[:, 0]]
    assert torch.equal(inside, regions[tight[:, 0]])
    assert abs(inside.float().mean().item() - p_in.mean().item()) < 0.03
    assert inside.sum() > 200
    assert torch.equal(tight, g_tight)
    assert torch.equal(wide[~inside], g_wide[~inside])
    assert (wide[inside] != g_wide[inside]).any(-1).float().mean() > 0.2



def _turned(x: torch.Tensor) -> torch.Tensor:
    return torch.cat([-x[..., :2], x[..., 2:]], dim=-1)


def _rally_frames(server_x_m: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Two rallies of 6 frames: positions, velocities, velocities a frame earlier."""
    g = torch.Generator().manual_seed(4)
    pos = torch.rand(2, 6, 3, 3, generator=g)
    pos[..., 0, 0] += server_x_m
    pos[..., 1, 0] -= server_x_m
    pos[..., 2, 2] += 1.0
    pos[..., :2, 2] = 0
    vel = torch.randn(2, 6, 3, 3, generator=g)
    vel[..., 2, :] += torch.tensor([25.0, 3.0, 3.0])
    prev = vel + 0.1 * torch.randn(2, 6, 3, 3, generator=g)
    return pos, vel, prev


@pytest.mark.parametrize("server_x_m", [-11.0, 11.0])
def test_server_frame_plays_both_ends_alike(server_x_m):
    # Turned 180 degrees about the net's centre, a rally gives the model the same output
    # states, the same target bins and, drawn with the same stream, the turned next frame.
    from sportsngen.model.inputs import object_features

    model = make_model(bin_centre="cv", ball_centre="physics", frame="server")
    world = make_model(bin_centre="cv", ball_centre="physics")
    _, ident, ctx = inputs(model.cfg)
    pos, vel, prev = _rally_frames(server_x_m)
    t = torch.arange(6, dtype=torch.float32).expand(2, -1) / 25.0
    noise = torch.randn(2, 6, 3, 3, generator=torch.Generator().manual_seed(1))
    nxt = pos + vel / 25.0 + 0.05 * noise
    outs = {}
    with torch.no_grad():
        for key, (p, v, pv, n) in {"as is": (pos, vel, prev, nxt),
                                   "turned": tuple(map(_turned, (pos, vel, prev, nxt)))}.items():
            feats = object_features(p, v, t)
            h = model(feats, ident, model.context_tokens(*ctx))
            outs[key] = (h, model.target_bins(p, v, n, pv),
                         model.sample_next(h, p, v, 0.9, 0.9, torch.Generator().manual_seed(3), pv),
                         world(feats, ident, world.context_tokens(*ctx)))
    (h0, bins0, next0, w0), (h1, bins1, next1, w1) = outs["as is"], outs["turned"]
    assert torch.allclose(h0, h1, atol=1e-5)
    assert all(torch.equal(a, b) for a, b in zip(bins0, bins1))
    assert torch.allclose(_turned(next0), next1, atol=1e-5)
    assert not torch.allclose(w0, w1, atol=1e-3)     # the world frame tells the ends apart
    # The server's end is read from his side of the net: the turn is its own inverse.
    sign = model.frame_sign(pos[:, 0])
    assert torch.equal(sign, torch.full_like(sign, math.copysign(1.0, server_x_m)))
    off = torch.randn(2, 3, 3)
    assert torch.equal(model.to_model_frame(model.to_model_frame(off, pos[:, 0]), pos[:, 0]), off)
    assert world.frame_sign(pos[:, 0]) is None


def test_frame_config_is_checked():
    with pytest.raises(ValueError, match="model.frame"):
        tiny_cfg(frame="receiver")
    assert ModelConfig.from_dict({k: v for k, v in tiny_cfg().to_dict().items()
                                  if k != "frame"}).frame == "world"


def test_sub_index_splits_a_bin_into_equal_parts():
    bins = Bins((1.0,), 5, "uniform")        # edges -1, -0.6, -0.2, 0.2, 0.6, 1.0
    off = torch.tensor([[-0.59], [-0.21], [0.0], [0.19], [0.61], [0.99], [1.7], [-3.0]])
    idx = bins.index(off)
    assert idx[:, 0].tolist() == [1, 1, 2, 2, 4, 4, 4, 0]
    # Bin 1 is [-0.6, -0.2): -0.59 in its first quarter, -0.21 in its last; beyond the outer
    # edges the outermost part.
    assert bins.sub_index(off, idx, 4)[:, 0].tolist() == [0, 3, 2, 3, 0, 3, 3, 0]


def test_sub_bin_head_is_a_normalised_distribution_and_samples_its_mass():
    from sportsngen.model.heads import SubBinHead

    torch.manual_seed(0)
    m = 3
    head = SubBinHead(16, 5, 3, m, hidden=8)
    h = torch.randn(2, 16)
    bins = torch.tensor([[0, 4, 2], [1, 1, 3]])
    grid = torch.cartesian_prod(torch.arange(m), torch.arange(m), torch.arange(m))
    with torch.no_grad():
        nll = head.nll(h[:, None].expand(2, len(grid), 16), bins[:, None].expand(2, len(grid), 3),
                       grid[None].expand(2, -1, -1))
    torch.testing.assert_close(torch.exp(-nll).sum(dim=1), torch.ones(2), atol=1e-5, rtol=0)
    # All the mass on part 2 of every dimension: that is what it samples.
    with torch.no_grad():
        for cond in head.cond:
            cond[-1].weight.zero_()
            cond[-1].bias.copy_(torch.tensor([-50.0, -50.0, 50.0]))
    got = head.sample(h, bins, torch.Generator().manual_seed(1))
    assert torch.equal(got, torch.full((2, 3), 2))


def test_sampled_ball_lies_in_its_chosen_sub_bin(monkeypatch):
    model = make_model(bin_centre="cv", n_bins=61, bin_spacing="nonuniform", ball_sub_bins=8)
    n = model.cfg.n_bins
    chosen = torch.tensor([[n // 2 + 20, n // 2 - 7, n // 2 + 3]])
    monkeypatch.setattr(model.ball_head, "sample",
                        lambda h, top_p, gen, regions=None, top_p_regions=None: chosen)
    monkeypatch.setattr(model.ball_sub_head, "sample",
                        lambda h, bins, gen: torch.tensor([[0, 7, 5]]))
    pos = torch.tensor([[[0.0, -11.0, 0.0], [1.0, 11.0, 0.0], [10.0, 0.5, 1.0]]])
    vel = torch.tensor([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-30.0, -6.0, 4.0]]])
    h = torch.zeros(1, 3, model.cfg.d_model)
    nxt = model.sample_next(h, pos, vel, generator=torch.Generator().manual_seed(0),
                            prev_vel_mps=vel)
    off = nxt[0, 2] - model.centres(pos, vel, vel)[0, 2]
    lo = model.ball_bins.value(chosen[0], torch.zeros(3))
    width = model.ball_bins.width(chosen[0])
    frac = (off - lo) / width
    assert (frac >= torch.tensor([0.0, 7 / 8, 5 / 8]) - 1e-5).all()
    assert (frac <= torch.tensor([1 / 8, 1.0, 6 / 8]) + 1e-5).all()
    # Its target parts are the ones it was drawn in, and they cost the sub-bin head's NLL.
    _, b_idx = model.target_bins(pos, vel, nxt, vel)
    assert torch.equal(b_idx, chosen)
    sub = model.ball_bins.sub_index(off[None], b_idx, 8)
    assert sub[0].tolist() == [0, 7, 5]
    hs = torch.zeros(1, 3, model.cfg.d_model)
    direct = model.ball_sub_head.nll(hs[:, 2], b_idx, sub)
    off_all = model.target_offsets(pos, vel, nxt, vel)
    torch.testing.assert_close(model.ball_sub_nll(hs, off_all, b_idx), direct)
    assert make_model().ball_sub_nll(hs, off_all, b_idx).item() == 0.0


def test_sub_bin_config_is_checked():
    with pytest.raises(ValueError, match="ball_sub_bins"):
        tiny_cfg(ball_sub_bins=1)
    assert tiny_cfg().ball_sub_bins == 0 and make_model().ball_sub_head is None


def test_physics_centre_asks_the_sub_bin_head_only_off_the_centre_bin(monkeypatch):
    model = make_model(bin_centre="cv", n_bins=61, bin_spacing="nonuniform", ball_sub_bins=8,
                       ball_centre="physics")
    c = model.cfg.n_bins // 2
    chosen = torch.tensor([[c, c, c], [c + 20, c, c - 3]])   # free flight; a strike
    monkeypatch.setattr(model.ball_head, "sample",
                        lambda h, top_p, gen, regions=None, top_p_regions=None: chosen)
    asked = []

    def parts(h, bins, gen):
        asked.append(bins.clone())
        return torch.full_like(bins, 7)

    monkeypatch.setattr(model.ball_sub_head, "sample", parts)
    pos = torch.tensor([[0.0, -11.0, 0.0], [1.0, 11.0, 0.0], [10.0, 0.5, 1.0]]).repeat(2, 1, 1)
    vel = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-30.0, -6.0, 4.0]]).repeat(2, 1, 1)
    h = torch.zeros(2, 3, model.cfg.d_model)
    nxt = model.sample_next(h, pos, vel, generator=torch.Generator().manual_seed(0),
                            prev_vel_mps=vel)
    assert len(asked) == 1 and torch.equal(asked[0], chosen[1:])
    centre = model.centres(pos, vel, vel)
    assert torch.equal(nxt[0, 2], centre[0, 2])             # the step itself
    off = nxt[1, 2] - centre[1, 2]
    frac = (off - model.ball_bins.value(chosen[1], torch.zeros(3))) / \
        model.ball_bins.width(chosen[1])
    assert frac[0] >= 7 / 8 - 1e-5 and frac[2] >= 7 / 8 - 1e-5   # off-centre axes: part 7
    assert off[1] == 0.0                                    # its centre-bin axis: the step


@pytest.mark.parametrize("top_p", [0.5, 0.9, 1.0])
def test_the_compiled_nucleus_draw_is_the_torch_one(top_p):
    from sportsngen.model.sampling import _nucleus_rows, _nucleus_torch

    g = torch.Generator().manual_seed(11)
    logits = torch.randn(3000, 61, generator=g) * 3
    logits[::4, ::3] = float("-inf")           # masked classes (regions) never drawn
    p = torch.full((3000, 1), top_p)
    p[::7] = 0.3                                # per-row nuclei
    u = torch.rand(3000, 1, generator=g)
    want = _nucleus_torch(logits, p, u)
    got = np.empty(3000, dtype=np.int64)
    _nucleus_rows(logits.numpy(), p.reshape(-1).numpy(), u.reshape(-1).numpy(), got)
    assert torch.equal(torch.from_numpy(got), want)
    assert not torch.isinf(logits[::4].gather(-1, want[::4, None])).any()


def _torch_draw(monkeypatch, head, *args, **kw):
    from sportsngen.model import heads
    with monkeypatch.context() as m:
        m.setattr(heads, "_compiled_draw", lambda h: False)
        return head.sample(*args, **kw)


@pytest.mark.parametrize("dims,top_p,split,top_p_regions", [
    (2, 1.0, False, None), (2, 0.8, False, None), (3, 0.9, True, 0.97), (3, 1.0, True, None),
    (4, 0.7, True, 0.7)])
def test_the_compiled_head_draw_is_the_torch_one(monkeypatch, dims, top_p, split,
                                                 top_p_regions):
    """The fused kernel reads the generator's stream as the torch path does (the same state
    after) and draws the same bins from the same uniforms, regions, nuclei and biases."""
    from sportsngen.model import head_kernel, heads

    monkeypatch.setattr(heads, "HEAD_KERNEL_ROWS", 10 ** 6)    # every row through the kernel
    calls = []
    real = head_kernel.factorised_rows
    monkeypatch.setattr(head_kernel, "factorised_rows", lambda *a: (calls.append(1), real(*a)))
    torch.manual_seed(5)
    head = FactorisedHead(32, 15, dims, hidden=24).eval()
    for p in head.parameters():             # logits spread over a few units, as a model's do
        p.data.mul_(4.0)
    h = torch.randn(2000, 32)
    bias = torch.randn(2000, dims, 15)
    regions = (torch.arange(15) % 4 == 0) if split else None
    g_fast, g_ref = torch.Generator().manual_seed(9), torch.Generator().manual_seed(9)
    with torch.inference_mode():
        fast = head.sample(h, top_p, g_fast, regions, top_p_regions, dim_bias=bias)
        ref = _torch_draw(monkeypatch, head, h, top_p, g_ref, regions, top_p_regions,
                          dim_bias=bias)
    assert calls == [1]
    assert torch.equal(g_fast.get_state(), g_ref.get_state())
    assert (fast == ref).all(-1).float().mean() >= 0.999       # float32 rounding at an edge
    assert len(torch.unique(fast[:, 0])) > 5                     # a real spread was drawn
    if split and top_p < 1.0:
        # a nucleus under 1 cuts classes, so the draws cannot all be the full distribution's
        assert not torch.equal(fast, _torch_draw(monkeypatch, head, h, 1.0,
                                                 torch.Generator().manual_seed(9)))


def test_the_compiled_head_draw_follows_changed_weights(monkeypatch):
    """The packed weights are packed again after an in-place update (fine-tuning)."""
    from sportsngen.model import heads

    monkeypatch.setattr(heads, "HEAD_KERNEL_ROWS", 10 ** 6)
    torch.manual_seed(0)
    head = FactorisedHead(8, 11, 2, hidden=8).eval()
    h = torch.randn(30, 8)
    with torch.inference_mode():
        before = head.sample(h, 1.0, torch.Generator().manual_seed(1))
    with torch.no_grad():
        head.first.bias.fill_(-1e4)
        head.first.bias[3] = 0.0            # every first bin must now be 3
    with torch.inference_mode():
        after = head.sample(h, 1.0, torch.Generator().manual_seed(1))
    assert (after[:, 0] == 3).all() and not (before[:, 0] == 3).all()


def test_the_compiled_head_draw_rejects_a_bad_nucleus():
    head = FactorisedHead(8, 11, 2, hidden=8).eval()
    with torch.inference_mode(), pytest.raises(ValueError, match="top_p"):
        head.sample(torch.randn(3, 8), 0.0)
    with torch.inference_mode(), pytest.raises(ValueError, match="top_p_regions"):
        head.sample(torch.randn(3, 8), 0.9, None, torch.ones(11, dtype=torch.bool), 1.5)


@pytest.mark.parametrize("b", [1, 2])
def test_the_compiled_step_is_the_torch_step(monkeypatch, b):
    """The compiled blocks (`step_kernel`, used up to STEP_KERNEL_ROWS rallies) give the torch
    step's states and write the same keys and values into the rings, past the window too."""
    from sportsngen.model import decoder, step_kernel

    model = make_model(n_layers=3)
    t = 2 * model.cfg.window_frames + 3
    feats, ident, ctx = inputs(model.cfg, b=b, t=t)
    c = model.context_tokens(*ctx)
    calls = []
    real = step_kernel.blocks_rows
    monkeypatch.setattr(step_kernel, "blocks_rows", lambda *a: (calls.append(1), real(*a)))
    with torch.inference_mode():
        fast = model.init_cache(ident, c)
        slow = model.init_cache(ident, c)
        for k in range(t):
            h_fast, fast = model.forward_step(feats[:, k], fast)
            with monkeypatch.context() as m:
                m.setattr(decoder, "STEP_KERNEL_ROWS", 0)
                h_slow, slow = model.forward_step(feats[:, k], slow)
            assert (h_fast - h_slow).abs().max() < 1e-5
        for a, s in zip(fast.k + fast.v, slow.k + slow.v):
            assert (a - s).abs().max() < 1e-5
    assert len(calls) == t


def test_the_compiled_step_follows_changed_weights():
    model = make_model()
    feats, ident, ctx = inputs(model.cfg, b=1, t=2)
    c = model.context_tokens(*ctx)
    with torch.inference_mode():
        before, _ = model.forward_step(feats[:, 0], model.init_cache(ident, c))
    with torch.no_grad():
        model.ln_f.bias.add_(1.0)
    with torch.inference_mode():
        after, _ = model.forward_step(feats[:, 0], model.init_cache(ident, c))
    assert torch.allclose(after - before, torch.ones_like(after), atol=1e-5)
