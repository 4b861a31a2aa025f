"""The clock column (`ModelConfig.clock_s`, `forecast.clock_columns`): the rally's elapsed time on
a second's scale, clipped, as one more input column; a model given it starts from the function
it had, and `init_clock_s` adds it to a trained model."""

from __future__ import annotations

import pytest
import torch

from sportsngen.model import SportsNGEN, load_model
from sportsngen.model.embedding import widen_for_extra
from sportsngen.model.forecast import FORECAST_FEATURES, clock_columns, extra_columns
from sportsngen.model.inputs import object_features
from tests.conftest import init_runs
from tests.test_model import tiny_cfg


def _inputs(model: SportsNGEN, t_s: torch.Tensor):
    gen = torch.Generator().manual_seed(1)
    pos = torch.randn(2, len(t_s), 3, 3, generator=gen) * 3
    vel = torch.randn(2, len(t_s), 3, 3, generator=gen) * 5
    feats = object_features(pos, vel, t_s[None].expand(2, -1))
    ident = torch.tensor([[2, 3, 1], [3, 4, 1]])
    ctx = model.context_tokens(torch.tensor([0, 1]), torch.tensor([0, 1]), torch.tensor([0, 1]),
                               torch.zeros(2, 7))
    return feats, ident, ctx


def test_clock_columns_read_the_elapsed_time_in_seconds_clipped():
    t_s = torch.tensor([0.0, 0.04, 1.08, 1.44, 2.0, 3.5, 60.0])
    feats = object_features(torch.zeros(7, 3, 3), torch.zeros(7, 3, 3), t_s)
    clock = clock_columns(feats, 2.0)
    assert clock.shape == (7, 3, 1)
    expected = torch.tensor([0.0, 0.04, 1.08, 1.44, 2.0, 2.0, 2.0])
    torch.testing.assert_close(clock[..., 0], expected[:, None].expand(-1, 3))
    # Nine frames (0.36 s) are 0.36 on the clock, ten times their step in the features' time.
    assert (clock[3, 0, 0] - clock[2, 0, 0]).item() == pytest.approx(0.36, abs=1e-6)
    assert (feats[3, 0, 7] - feats[2, 0, 7]).item() == pytest.approx(0.036, abs=1e-6)


def test_extra_columns_count_the_clock_last():
    assert extra_columns(tiny_cfg()) == 0
    assert extra_columns(tiny_cfg(clock_s=2.0)) == 1
    assert extra_columns(tiny_cfg(ball_forecast=True, clock_s=2.0)) == FORECAST_FEATURES + 1
    with pytest.raises(ValueError, match="clock_s"):
        tiny_cfg(clock_s=-1.0)


@pytest.mark.parametrize("forecast", [False, True])
def test_a_model_given_the_clock_starts_from_the_same_function(forecast):
    torch.manual_seed(0)
    base = SportsNGEN(tiny_cfg(ball_forecast=forecast)).eval()
    wide = SportsNGEN(tiny_cfg(ball_forecast=forecast, clock_s=2.0)).eval()
    wide.load_state_dict(widen_for_extra(base.state_dict(), "embed.", 1))
    t_s = torch.arange(6.0) / 25 + 1.0
    feats, ident, ctx = _inputs(base, t_s)
    torch.testing.assert_close(wide(feats, ident, ctx), base(feats, ident, ctx))
    # The clock is read: a weight on its column (the last) changes the output.
    with torch.no_grad():
        wide.embed.mlp[0].weight[:, -1] = 0.5
    h_full = wide(feats, ident, ctx)
    assert not torch.allclose(h_full, base(feats, ident, ctx))
    # The cached step computes the same clock as the full window.
    cache = wide.init_cache(ident, ctx)
    for k in range(len(t_s)):
        h, cache = wide.forward_step(feats[:, k], cache)
    torch.testing.assert_close(h, h_full[:, -1], atol=1e-4, rtol=1e-4)


def test_init_clock_s_widens_a_trained_model(tmp_path, tiny_model_file):
    base = load_model(tiny_model_file)[0].state_dict()
    runs = init_runs(tmp_path, tiny_model_file, "init_clock_s=2.0")
    m0, cfg0 = runs[0][0].state_dict(), runs[0][3]
    assert cfg0.clock_s == 2.0
    w = m0["embed.mlp.0.weight"]
    assert w.shape[1] == base["embed.mlp.0.weight"].shape[1] + 1
    assert torch.equal(w[:, :-1], base["embed.mlp.0.weight"])
    assert torch.equal(w[:, -1], torch.zeros_like(w[:, -1]))
    # Trained, the clock's weights move off zero.
    assert runs[3][0].state_dict()["embed.mlp.0.weight"][:, -1].abs().sum() > 0
