"""The ball's flight forecast (`sportsngen.model.forecast`) and a model given it."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir

from sportsngen.model import SportsNGEN, load_model
from sportsngen.model.centre import GRAVITY_MPS2
from sportsngen.model.forecast import (
    BOUNCE_KEEP_XY,
    FORECAST_FEATURES,
    HORIZON_S,
    INTERCEPT_FEATURES,
    INTERCEPT_HORIZON_S,
    STEP_S,
    ball_forecast,
    ball_forecast_torch,
    forecast_columns,
    nearest_playable,
    random_flights,
)
from sportsngen.model.inputs import object_features
from sportsngen.tennis.court import BALL_RADIUS_M
from tests.conftest import REPO, init_runs
from tests.test_model import tiny_cfg


def _fine_flight(pos, vel, t_end, dt=1e-4, drag=True):
    """The same physics integrated finely (numpy reference)."""
    from sportsngen.model.centre import DRAG_PER_M
    p, v = np.array(pos, float), np.array(vel, float)
    t = 0.0
    while t < t_end - 1e-12:
        a = -DRAG_PER_M * np.linalg.norm(v) * v if drag else np.zeros(3)
        a[2] -= GRAVITY_MPS2
        v = v + a * dt
        p = p + v * dt
        t += dt
    return p


def test_forecast_matches_a_fine_integration_before_the_bounce():
    # A lob rising at 9 m/s from 1 m: in the air after 1.2 s. Its steps against a fine
    # integration of the same gravity and drag: within 3 cm after 0.4 and 0.8 s.
    pos, vel = [-11.0, 1.0, 1.0], [14.0, -1.0, 9.0]
    out = ball_forecast(torch.tensor([pos]), torch.tensor([vel]))[0].numpy()
    assert out.shape == (FORECAST_FEATURES,)
    for i, t in enumerate((0.4, 0.8)):
        ref = _fine_flight(pos, vel, t)
        assert np.abs(out[3 * i:3 * i + 3] - ref).max() < 0.03, (t, out, ref)
    assert out[8] == pytest.approx(1.2)        # no bounce within the horizon: the horizon
    ref = _fine_flight(pos, vel, 1.2)
    assert np.abs(out[6:8] - ref[:2]).max() < 0.05


def test_forecast_bounce_without_drag_is_the_parabola():
    # Without drag (a slow ball: drag is tiny) the bounce is where the parabola reaches one
    # ball radius, within a frame's travel.
    pos, vel = [0.0, 0.0, 2.0], [3.0, 0.5, 0.0]
    t_b = math.sqrt(2 * (2.0 - BALL_RADIUS_M) / GRAVITY_MPS2)          # 0.63 s
    out = ball_forecast(torch.tensor([pos]), torch.tensor([vel]))[0].numpy()
    assert abs(out[8] - t_b) <= 1 / 25 + 1e-6
    assert abs(out[6] - 3.0 * t_b) < 3.0 / 25 + 0.05 and abs(out[7] - 0.5 * t_b) < 0.05
    # After the bounce the ball keeps 0.7 of its horizontal speed: 0.8 s on it is short of
    # where a ball flying on unbounced would be.
    assert 3.0 * t_b + BOUNCE_KEEP_XY * 3.0 * (0.8 - t_b) - 0.15 < out[3] < 3.0 * 0.8 - 0.1
    assert out[5] >= BALL_RADIUS_M - 1e-6


def test_forecast_is_batched_and_the_same_at_either_end():
    # Turned 180 degrees about the net's vertical, the forecast turns with it.
    pos = torch.tensor([[-11.0, 2.0, 1.0], [11.0, -2.0, 1.0]])
    vel = torch.tensor([[25.0, -2.0, 3.0], [-25.0, 2.0, 3.0]])
    a, b = ball_forecast(pos, vel)
    turned = b.clone()
    turned[[0, 1, 3, 4, 6, 7]] *= -1
    torch.testing.assert_close(a, turned)
    assert 0 < a[8] < 1.2 and 0 < a[6] < 11.9      # a groundstroke lands in the far half
    # Each row is forecast as it would be alone, whatever the others do: the loop skips the
    # lift's turning and the bounce's bookkeeping only on steps where no row needs them.
    pos = torch.tensor([[-11.0, 2.0, 1.0], [5.0, 0.0, 6.0], [0.0, 1.0, 0.9], [-3.0, 0.0, 3.0]])
    vel = torch.tensor([[25.0, -2.0, 3.0], [1.0, 0.0, 0.0], [-20.0, 3.0, -4.0], [8, 0, 12.0]])
    prev = vel + torch.tensor([[0.1, 0.0, 0.35], [float("nan")] * 3, [0.0, 0.0, 0.4],
                               [0.0, 0.0, 0.39]])
    together = ball_forecast(pos, vel, prev)
    for i in range(len(pos)):
        assert torch.equal(together[i], ball_forecast(pos[i:i + 1], vel[i:i + 1],
                                                      prev[i:i + 1])[0])


def test_a_model_given_the_forecast_starts_from_the_same_function():
    torch.manual_seed(0)
    base = SportsNGEN(tiny_cfg()).eval()
    wide = SportsNGEN(tiny_cfg(ball_forecast=True)).eval()
    from sportsngen.model.embedding import widen_for_extra
    wide.load_state_dict(widen_for_extra(base.state_dict(), "embed.", FORECAST_FEATURES))
    gen = torch.Generator().manual_seed(1)
    pos = torch.randn(2, 6, 3, 3, generator=gen) * 3
    vel = torch.randn(2, 6, 3, 3, generator=gen) * 5
    t = torch.arange(6.0)[None].expand(2, -1) / 25
    feats = object_features(pos, vel, t)
    ident = torch.tensor([[2, 3, 1], [3, 4, 1]])
    ctx = base.context_tokens(torch.tensor([0, 1]), torch.tensor([0, 1]), torch.tensor([0, 1]),
                              torch.zeros(2, 7))
    torch.testing.assert_close(wide(feats, ident, ctx), base(feats, ident, ctx))
    # The new columns are read: a non-zero weight on them changes the output.
    with torch.no_grad():
        wide.embed.mlp[0].weight[:, -FORECAST_FEATURES:] = 0.5
    assert not torch.allclose(wide(feats, ident, ctx), base(feats, ident, ctx))
    # The players' tokens see the forecast from where they stand; the ball's token none.
    extra = forecast_columns(feats, None, 25.0)
    assert extra.shape == (2, 6, 3, FORECAST_FEATURES)
    assert torch.equal(extra[..., 2, :], torch.zeros_like(extra[..., 2, :]))
    torch.testing.assert_close(extra[..., 0, :8] - extra[..., 1, :8],
                               (feats[..., 1, [0, 1, 2, 0, 1, 2, 0, 1]]
                                - feats[..., 0, [0, 1, 2, 0, 1, 2, 0, 1]]))
    # The cached step computes the same forecast as the full window.
    h_full = wide(feats, ident, ctx)
    cache = wide.init_cache(ident, ctx)
    for k in range(6):
        h, cache = wide.forward_step(feats[:, k], cache)
    torch.testing.assert_close(h, h_full[:, -1], atol=1e-4, rtol=1e-4)


def test_init_ball_forecast_widens_a_trained_model(tmp_path, tiny_model_file):
    from sportsngen.train.run import train_from_config
    over = ["experiment=tiny", "data=toy", "data.n_rallies=16", "trainer.val_check_interval=3",
            "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
            "events.enabled=false", f"init={tiny_model_file}", "init_ball_forecast=true"]
    base = load_model(tiny_model_file)[0].state_dict()
    runs = init_runs(tmp_path, tiny_model_file, "init_ball_forecast=true")
    m0, cfg0 = runs[0][0].state_dict(), runs[0][3]
    assert cfg0.ball_forecast
    w = m0["embed.mlp.0.weight"]
    assert w.shape[1] == base["embed.mlp.0.weight"].shape[1] + FORECAST_FEATURES
    assert torch.equal(w[:, :-FORECAST_FEATURES], base["embed.mlp.0.weight"])
    assert torch.equal(w[:, -FORECAST_FEATURES:], torch.zeros_like(w[:, -FORECAST_FEATURES:]))
    # Trained, the forecast's weights move off zero.
    w3 = runs[3][0].state_dict()["embed.mlp.0.weight"]
    assert w3[:, -FORECAST_FEATURES:].abs().sum() > 0
    # train_only=forecast: those weights alone learn (with the players' head: it too); the
    # rest of the model as it was.
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        cfg = compose(config_name="train", overrides=[*over, "trainer.max_steps=3",
                                                      "train_only=forecast+player_head",
                                                      "optim.weight_decay=0.0"])
    only = load_model(train_from_config(cfg, tmp_path / "only")["model_file"])[0].state_dict()
    for k, v in m0.items():
        if k != "embed.mlp.0.weight" and not k.startswith("player_head."):
            assert torch.equal(v, only[k]), k
    assert not all(torch.equal(v, only[k]) for k, v in m0.items() if k.startswith("player_head."))
    w = only["embed.mlp.0.weight"]
    assert torch.equal(w[:, :-FORECAST_FEATURES], m0["embed.mlp.0.weight"][:, :-FORECAST_FEATURES])
    assert w[:, -FORECAST_FEATURES:].abs().sum() > 0


def test_the_spin_read_from_the_track_brings_the_bounce_to_the_generators():
    # The generator's rally balls carry heavy topspin: flown on without it the forecast lands
    # them metres long; with the lift read from the last three frames, within about a metre.
    from sportsngen.synth import generate_matches

    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points=40, seed=3,
                            workers=1)
    balls = data.frames[data.frames["object"] == "ball"].sort_values(["rally_id", "frame"])
    tracks = {rid: g[["x", "y", "z"]].to_numpy() for rid, g in balls.groupby("rally_id")}
    pos, vel, prev, bounce = [], [], [], []
    for row in data.shots[data.shots["shot_index"] > 0].itertuples():
        b, t = tracks[row.rally_id], int(row.frame) + 10
        if not np.isfinite(row.bounce_x) or t + 1 >= len(b) or \
                abs(b[t, 0] - row.contact_x) > abs(row.bounce_x - row.contact_x):
            continue                                  # no bounce, or bounced by then
        pos.append(b[t])
        vel.append((b[t] - b[t - 1]) * 25.0)
        prev.append((b[t - 1] - b[t - 2]) * 25.0)
        bounce.append((row.bounce_x, row.bounce_y))
    assert len(pos) > 40
    pos, vel, prev = (torch.tensor(np.array(a)) for a in (pos, vel, prev))
    err = {}
    for name, pv in (("spin", prev), ("none", None)):
        out = ball_forecast(pos, vel, pv).numpy()
        err[name] = np.median(np.hypot(*(out[:, 6:8] - np.array(bounce)).T))
    assert err["spin"] < 1.0 and err["spin"] < 0.5 * err["none"], err


def test_graft_strike_head_joins_two_heads_trained_apart():
    """The strike head of one fine-tune joins the forecast of another (`graft_strike_head`):
    the result computes each part as its own file did; another decoder's head is refused."""
    from sportsngen.model.embedding import widen_for_extra
    from sportsngen.train.finetune import graft_strike_head
    torch.manual_seed(0)
    base = SportsNGEN(tiny_cfg(ball_centre="physics")).eval()
    forecast = SportsNGEN(tiny_cfg(ball_centre="physics", ball_forecast=True)).eval()
    forecast.load_state_dict(widen_for_extra(base.state_dict(), "embed.", FORECAST_FEATURES))
    with torch.no_grad():
        forecast.embed.mlp[0].weight[:, -FORECAST_FEATURES:] = 0.3
    striker = SportsNGEN(tiny_cfg(ball_centre="physics", strike_head=True)).eval()
    striker.load_state_dict({**striker.state_dict(), **base.state_dict()})
    both = graft_strike_head(forecast, striker)
    assert both.cfg.ball_forecast and both.cfg.strike_head and not forecast.cfg.strike_head
    got, fc, st = both.state_dict(), forecast.state_dict(), striker.state_dict()
    for k, v in got.items():
        want = st[k] if k.startswith("strike_head.") else fc[k]
        assert torch.equal(v, want), k
    assert any(k.startswith("strike_head.") for k in got)
    with pytest.raises(ValueError, match="no strike head"):
        graft_strike_head(striker, forecast)
    other = SportsNGEN(tiny_cfg(ball_centre="physics", strike_head=True)).eval()
    with pytest.raises(ValueError, match="transformer blocks differ"):
        graft_strike_head(forecast, other)


def test_the_flight_flown_on_keeps_the_columns_and_follows_the_same_physics():
    pos = torch.tensor([[-11.0, 1.0, 1.0], [11.0, -2.0, 1.0]])
    vel = torch.tensor([[14.0, -1.0, 9.0], [-25.0, 2.0, 3.0]])
    prev = vel + torch.tensor([[0.0, 0.0, 0.39], [0.1, 0.0, 0.35]])
    columns, track = ball_forecast(pos, vel, prev, path=True)
    assert torch.equal(columns, ball_forecast(pos, vel, prev))
    assert track.shape == (2, round(INTERCEPT_HORIZON_S / STEP_S), 3)
    # Its rows at 0.4 and 0.8 s are the columns' positions; the lob (no bounce in 1.6 s) is
    # within 10 cm of a fine integration 1.6 s on (the 0.04 s steps' own error: 8 cm).
    for i, t in enumerate((0.4, 0.8)):
        torch.testing.assert_close(track[:, round(t / STEP_S) - 1], columns[:, 3 * i:3 * i + 3])
    lob = ball_forecast(pos[:1], vel[:1], path=True)[1][0, -1].numpy()
    assert np.abs(lob - _fine_flight(pos[0].tolist(), vel[0].tolist(), 1.6)).max() < 0.1
    assert (track[..., 2] >= BALL_RADIUS_M - 1e-5).all()


def test_nearest_playable_ball_for_each_player():
    # A ball flying from x = 10 to x = -10 along y = 0, a step a row, at 1 m except rows too
    # high (2.5 m) near x = -6.
    x = torch.linspace(10.0, -10.0, 41)
    z = torch.where((x < -5.5) & (x > -6.5), torch.tensor(2.5), torch.tensor(1.0))
    track = torch.stack([x, torch.zeros_like(x), z], dim=-1)[None]           # (1, 41, 3)
    players = torch.tensor([[[-8.0, 1.5], [-6.0, 0.4], [9.0, 0.0], [-12.0, -3.0]]])
    out = nearest_playable(track, players)[0]
    # Beside the flight: the point level with him, its time the row's (from one step on).
    k = int(torch.argmin((x + 8.0).abs()))
    torch.testing.assert_close(out[0], torch.tensor([0.0, -1.5, (k + 1) * STEP_S]))
    # Where the ball flies too high to strike, the nearest playable point either side.
    assert out[1, 0].abs().item() == pytest.approx(0.5, abs=1e-5)
    assert out[1, 1].item() == pytest.approx(-0.4)
    # The hitter's own ball going away offers him nothing.
    torch.testing.assert_close(out[2], torch.tensor([0.0, 0.0, -1.0]))
    # Behind the flight's end: its last point, 2 m in front of him and 3 m across.
    torch.testing.assert_close(out[3], torch.tensor([2.0, 3.0, 41 * STEP_S]))
    # A band of heights: only the rows too high for the default are in (2, 3), and none
    # in (0.2, 0.9).
    band = nearest_playable(track, players, (2.0, 3.0))[0]
    assert band[1, 0].abs().item() <= 0.5 + 1e-5 and band[1, 1].item() == pytest.approx(-0.4)
    assert band[0, 0].item() == pytest.approx(2.0, abs=0.26)
    torch.testing.assert_close(nearest_playable(track, players, (0.2, 0.9))[0, :, 2],
                               torch.full((4,), -1.0))


def test_a_model_given_the_nearest_playable_ball_starts_from_the_same_function():
    from sportsngen.model.embedding import widen_for_extra
    torch.manual_seed(0)
    base = SportsNGEN(tiny_cfg(ball_forecast=True)).eval()
    wide = SportsNGEN(tiny_cfg(ball_forecast=True, ball_intercept=True)).eval()
    wide.load_state_dict(widen_for_extra(base.state_dict(), "embed.", INTERCEPT_FEATURES))
    gen = torch.Generator().manual_seed(1)
    pos = torch.randn(2, 6, 3, 3, generator=gen) * 3
    vel = torch.randn(2, 6, 3, 3, generator=gen) * 5
    feats = object_features(pos, vel, torch.arange(6.0)[None].expand(2, -1) / 25)
    ident = torch.tensor([[2, 3, 1], [3, 4, 1]])
    ctx = base.context_tokens(torch.tensor([0, 1]), torch.tensor([0, 1]), torch.tensor([0, 1]),
                              torch.zeros(2, 7))
    torch.testing.assert_close(wide(feats, ident, ctx), base(feats, ident, ctx))
    extra = forecast_columns(feats, None, 25.0, intercept=True)
    assert extra.shape == (2, 6, 3, FORECAST_FEATURES + INTERCEPT_FEATURES)
    assert torch.equal(extra[..., :FORECAST_FEATURES], forecast_columns(feats, None, 25.0))
    assert torch.equal(extra[..., 2, :], torch.zeros_like(extra[..., 2, :]))
    with torch.no_grad():
        wide.embed.mlp[0].weight[:, -INTERCEPT_FEATURES:] = 0.5
    h_full = wide(feats, ident, ctx)
    assert not torch.allclose(h_full, base(feats, ident, ctx))
    cache = wide.init_cache(ident, ctx)
    for k in range(6):
        h, cache = wide.forward_step(feats[:, k], cache)
    torch.testing.assert_close(h, h_full[:, -1], atol=1e-4, rtol=1e-4)
    with pytest.raises(ValueError, match="needs ball_forecast"):
        tiny_cfg(ball_intercept=True)


def test_init_ball_intercept_widens_a_model_with_the_forecast(tmp_path, tiny_model_file):
    from sportsngen.train.run import train_from_config
    over = ["experiment=tiny", "data=toy", "data.n_rallies=16", "trainer.val_check_interval=3",
            "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
            "events.enabled=false", f"init={tiny_model_file}", "trainer.max_steps=0"]
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        cfg = compose(config_name="train", overrides=[*over, "init_ball_intercept=true"])
    with pytest.raises(ValueError, match="init_ball_forecast"):
        train_from_config(cfg, tmp_path / "refused")
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
        cfg = compose(config_name="train", overrides=[*over, "init_ball_forecast=true",
                                                      "init_ball_intercept=true"])
    model, _, _, mcfg = load_model(train_from_config(cfg, tmp_path / "both")["model_file"])
    base = load_model(tiny_model_file)[0].state_dict()["embed.mlp.0.weight"]
    w = model.state_dict()["embed.mlp.0.weight"]
    n = FORECAST_FEATURES + INTERCEPT_FEATURES
    assert mcfg.ball_forecast and mcfg.ball_intercept
    assert w.shape[1] == base.shape[1] + n
    assert torch.equal(w[:, :-n], base) and torch.equal(w[:, -n:], torch.zeros_like(w[:, -n:]))


@pytest.mark.parametrize("with_prev", [True, False])
def test_the_compiled_forecast_is_the_torch_loop_to_float32_rounding(with_prev):
    pos, vel, prev = random_flights(4000, 3)
    prev = prev if with_prev else None
    want, want_path = ball_forecast_torch(pos, vel, prev, 25.0, path=True)
    got, got_path = ball_forecast(pos, vel, prev, 25.0, path=True)
    assert got.dtype == torch.float32 and got_path.shape == want_path.shape == (4000, 40, 3)
    # Positions of 1-30 m agree to a few float32 steps; the bounce's time to the step.
    assert (got - want).abs().max().item() < 2e-5
    assert (got_path - want_path).abs().max().item() < 2e-5
    assert torch.equal(got[:, 8], want[:, 8])
    assert 0.2 < (got[:, 8] < HORIZON_S).float().mean().item() < 0.95   # both kinds occur
    assert torch.equal(ball_forecast(pos, vel, prev, 25.0), got)       # path changes nothing


def test_the_compiled_forecast_keeps_shapes_dtype_and_device():
    pos, vel, prev = random_flights(60, 4)
    grid = [x.reshape(3, 4, 5, 3).double() for x in (pos, vel, prev)]
    out, track = ball_forecast(*grid, fps=25.0, path=True)
    assert out.shape == (3, 4, 5, 9) and track.shape == (3, 4, 5, 40, 3)
    assert out.dtype == torch.float64
    flat = ball_forecast(pos, vel, prev, 25.0)
    assert torch.allclose(out.reshape(60, 9).float(), flat, atol=1e-5)
    assert ball_forecast(pos[:0], vel[:0], prev[:0]).shape == (0, 9)


def _net_and_ground_balls(n: int, seed: int):
    """Random flights, every third one low and a frame from the net, flying into it, every
    fifth about to land: the step's three branches (flight, net, bounce) all occur."""
    pos, vel, prev = random_flights(n, seed)
    prev = torch.nan_to_num(prev, nan=0.0)
    side = torch.sign(pos[::3, 0])
    pos[::3, 0], pos[::3, 2], vel[::3, 0] = 0.3 * side, 0.5, -30.0 * side
    pos[::5, 2], vel[::5, 2] = 0.05, -8.0
    return pos, vel, prev


@pytest.mark.parametrize("net", [True, False])
@pytest.mark.parametrize("with_prev", [True, False])
def test_the_compiled_physics_step_is_the_torch_one_to_float32_rounding(net, with_prev):
    from sportsngen.model.centre import (
        ball_acceleration_mps2,
        ball_acceleration_mps2_torch,
        physics_step_m,
        physics_step_m_torch,
    )

    pos, vel, prev = _net_and_ground_balls(3000, 7)
    prev = prev if with_prev else None
    got, want = physics_step_m(pos, vel, prev, 50.0, net), physics_step_m_torch(pos, vel, prev,
                                                                                50.0, net)
    assert got.shape == want.shape == (3000, 3) and got.dtype == torch.float32
    assert (got - want).abs().max().item() < 1e-5
    # The net stopped some balls and the ground bounced some, in both.
    free = physics_step_m_torch(pos, vel, prev, 50.0, False)
    if net:
        stopped = (free - want).abs().amax(-1) > 1e-3
        assert 100 < int(stopped.sum()) and torch.equal(stopped, (free - got).abs().amax(-1) > 1e-3)
    assert int((want[:, 2] > pos[:, 2]).logical_and(vel[:, 2] < -5).sum()) > 100
    acc = ball_acceleration_mps2(vel, prev, 50.0)
    assert (acc - ball_acceleration_mps2_torch(vel, prev, 50.0)).abs().max().item() < 1e-4
    # Any leading shape, broadcast, and float64 or autograd through torch.
    grid = physics_step_m(pos[:60].reshape(3, 20, 3), vel[:60].reshape(3, 20, 3),
                          None if prev is None else prev[:1], 50.0, net)
    assert grid.shape == (3, 20, 3)
    want_grid = physics_step_m_torch(pos[:60].reshape(3, 20, 3), vel[:60].reshape(3, 20, 3),
                                     None if prev is None else prev[:1], 50.0, net)
    assert (grid - want_grid).abs().max().item() < 1e-5
    wide = physics_step_m(pos.double(), vel.double(), None if prev is None else prev.double(),
                          50.0, net)
    assert wide.dtype == torch.float64 and (wide - want).abs().max().item() < 1e-4


def test_the_compiled_forecast_columns_are_the_torch_ones(monkeypatch):
    """`forecast_columns`' one compiled call (CPU float32, no intercept) against its torch
    operations, over random flights with and without a frame before: equal to the bit."""
    from sportsngen.model import forecast
    from sportsngen.model.inputs import N_FEATURES, POS_SCALE_M, VEL_SCALE_MPS

    pos, vel, prev = forecast.random_flights(600, seed=4)
    scale = torch.as_tensor(POS_SCALE_M, dtype=torch.float32)
    feats = torch.randn(2, 300, 3, N_FEATURES, generator=torch.Generator().manual_seed(1))
    feats[..., 2, 0:3] = (pos / scale).reshape(2, 300, 3)
    feats[..., 2, 3:6] = (vel / VEL_SCALE_MPS).reshape(2, 300, 3)
    before = torch.full_like(feats, float("nan"))
    before[..., 2, 3:6] = (prev / VEL_SCALE_MPS).reshape(2, 300, 3)   # every 7th NaN: no spin
    got = forecast.forecast_columns(feats, before, 25.0)
    with monkeypatch.context() as m:
        m.setattr(forecast, "_forecast_columns_compiled",
                  lambda *a: pytest.fail("the torch path was asked for"))
        m.setattr(forecast, "kernel_inputs", lambda *t: False)      # the torch path
        want = forecast.forecast_columns(feats, before, 25.0)
    assert torch.equal(got, want)
    assert got.shape == (2, 300, 3, forecast.FORECAST_FEATURES)
    assert (got[..., 2, :] == 0).all() and got[..., :2, :].abs().max() > 1.0
