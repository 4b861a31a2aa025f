"""Where a player's draw lands inside its bin (`sportsngen.model.bin_quantiles`)."""

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.model.bin_quantiles import fit_bin_quantiles, place_in_bins, player_offsets
from sportsngen.model.bins import Bins

EDGES = np.array([[-1.0, 0.0, 1.0, 3.0]])          # one dimension, three bins


def test_a_bins_quantiles_are_its_offsets_and_a_sparse_bin_keeps_the_uniform_spread():
    # Bin 1 holds 60 offsets at 0.5 and 40 spread over [0.1, 0.9]; bin 2 only 3; bin 0 none.
    rng = np.random.default_rng(0)
    inside = np.r_[np.full(60, 0.5), rng.uniform(0.1, 0.9, 40)]
    off = np.r_[inside, [2.0, 2.5, 2.9], [np.nan, 7.0, -4.0]][:, None]   # NaN, beyond edges
    table = fit_bin_quantiles(off, EDGES, n_quantiles=4, min_offsets=50)
    assert table.shape == (1, 3, 5)
    np.testing.assert_allclose(table[0, 0], [-1.0, -0.75, -0.5, -0.25, 0.0])
    np.testing.assert_allclose(table[0, 1], np.quantile(inside, [0, 0.25, 0.5, 0.75, 1.0]))
    assert table[0, 1, 2] == 0.5                      # the atom holds the median
    np.testing.assert_allclose(table[0, 2], [1.0, 1.5, 2.0, 2.5, 3.0])


def test_offsets_on_an_edge_count_in_the_bin_above_as_the_heads_targets_do():
    off = np.full((60, 1), 1.0)
    table = fit_bin_quantiles(off, EDGES, n_quantiles=2, min_offsets=50)
    np.testing.assert_allclose(table[0, 2], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(table[0, 1], [0.0, 0.5, 1.0])
    bins = Bins((1.0,), 2, "uniform")                 # edges -1, 0, 1: bucketize agrees
    assert bins.index(torch.tensor([[0.0]])).item() == 1


def test_fit_refuses_offsets_and_edges_that_disagree():
    with pytest.raises(ValueError, match="must agree"):
        fit_bin_quantiles(np.zeros((5, 2)), EDGES)
    with pytest.raises(ValueError, match="n_quantiles"):
        fit_bin_quantiles(np.zeros((5, 1)), EDGES, n_quantiles=0)


def test_a_draw_lands_at_its_quantile_linearly_between_the_stored_ones():
    table = torch.tensor([[[0.0, 0.1, 0.5, 0.9, 1.0], [1.0, 1.2, 1.2, 1.2, 1.3]]])   # (1, 2, 5)
    idx = torch.tensor([[0], [0], [1], [1], [1]])
    u = torch.tensor([[0.0], [0.125], [0.5], [0.3], [0.875]])
    out = place_in_bins(table, idx, u)[:, 0]
    np.testing.assert_allclose(out.numpy(), [0.0, 0.05, 1.2, 1.2, 1.25], atol=1e-7)


def test_an_evenly_spread_table_places_draws_as_the_bins_do():
    bins = Bins((0.4, 0.4), 9, "nonuniform")
    edges = bins.edges.double().numpy()
    table = torch.as_tensor(fit_bin_quantiles(np.zeros((0, 2)), edges, 16), dtype=torch.float32)
    g = torch.Generator().manual_seed(0)
    idx = torch.randint(0, 9, (200, 2), generator=g)
    u = torch.rand(200, 2, generator=g)
    torch.testing.assert_close(place_in_bins(table, idx, u), bins.value(idx, u),
                               atol=1e-7, rtol=0)


def test_the_numpy_placement_is_the_torch_one_to_the_bit(monkeypatch):
    """`place_in_bins`' numpy lines (CPU float32) against its torch ones, on a fitted table's
    uneven quantiles, draws at a bin's ends included, in a rollout's (B, 2, 2) shape."""
    import sportsngen.model.bin_quantiles as bq

    g = np.random.default_rng(1)
    bins = Bins((0.4, 0.4), 9, "nonuniform")
    offsets = g.standard_t(3, size=(20000, 2)) * 0.05
    table = torch.as_tensor(fit_bin_quantiles(offsets, bins.edges.double().numpy(), 16),
                            dtype=torch.float32)
    idx = torch.as_tensor(g.integers(0, 9, (500, 2, 2)))
    u = torch.as_tensor(g.random((500, 2, 2)), dtype=torch.float32)
    u[0], u[1] = 0.0, float(np.nextafter(np.float32(1), np.float32(0)))
    fast = place_in_bins(table, idx, u)
    monkeypatch.setattr(bq, "kernel_inputs", lambda *t: False)
    ref = place_in_bins(table, idx, u)
    assert fast.dtype == ref.dtype == torch.float32 and fast.shape == ref.shape
    assert torch.equal(fast, ref)


def _frames(server_x0: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One rally of five frames: the server accelerating along y by 0.01 m a frame a frame,
    the receiver moving at constant velocity, frame 3 of the receiver missing."""
    rows = []
    for f in range(5):
        rows.append((1, f, "A", server_x0, 0.005 * f * f))
        if f != 3:
            rows.append((1, f, "B", -server_x0, 0.2 * f))
        rows.append((1, f, "ball", 0.0, 0.0))
    frames = pd.DataFrame(rows, columns=["rally_id", "frame", "object", "x", "y"])
    rallies = pd.DataFrame({"rally_id": [1], "server": ["A"], "receiver": ["B"]})
    return frames, rallies


def test_player_offsets_are_second_differences_turned_into_the_servers_frame():
    frames, rallies = _frames(12.0)
    off = player_offsets(frames, rallies)
    # The server's three inner frames (1-3); the receiver's only frame 1 has both neighbours.
    np.testing.assert_allclose(off, [[0.0, 0.01], [0.0, 0.01], [0.0, 0.01], [0.0, 0.0]],
                               atol=1e-12)
    frames, rallies = _frames(-12.0)                  # served from -x: the turn flips x and y
    np.testing.assert_allclose(player_offsets(frames, rallies),
                               [[0.0, -0.01], [0.0, -0.01], [0.0, -0.01], [0.0, 0.0]],
                               atol=1e-12)
    np.testing.assert_allclose(player_offsets(frames, rallies, server_frame=False),
                               [[0.0, 0.01], [0.0, 0.01], [0.0, 0.01], [0.0, 0.0]], atol=1e-12)


def test_sampled_players_land_where_the_table_puts_them():
    from sportsngen.model import SportsNGEN
    from tests.test_model import tiny_cfg

    torch.manual_seed(0)
    model = SportsNGEN(tiny_cfg()).eval()
    n_bins = model.player_bins.edges.shape[1] - 1
    table = torch.zeros(2, n_bins, 5)
    table[0], table[1] = 0.003, -0.002               # every bin, every quantile: one offset
    pos = torch.zeros(4, 3, 3)
    pos[:, 0, 0], pos[:, 1, 0], pos[:, 2] = 12.0, -12.0, torch.tensor([0.0, 0.0, 1.0])
    vel = torch.zeros_like(pos)
    h = torch.randn(4, 3, model.cfg.d_model)
    g = torch.Generator().manual_seed(1)
    nxt = model.sample_next(h, pos, vel, generator=g, player_quantiles=table)
    centre = model.centres(pos, vel, None)
    step = (nxt - centre)[:, :2, :2]
    torch.testing.assert_close(step, torch.tensor([0.003, -0.002]).expand(4, 2, 2))
    g = torch.Generator().manual_seed(1)
    plain = model.sample_next(h, pos, vel, generator=g)
    assert not torch.allclose((plain - centre)[:, :2, :2], step)


def test_the_simulator_refuses_a_table_that_does_not_fit_the_models_bins(tiny_model_file):
    from sportsngen.errors import ArgumentError
    from tests.conftest import tiny_sim

    sim = tiny_sim(tiny_model_file, player_bin_quantiles=True)
    assert sim.player_quantiles_used() is None          # no table in the file: uniform
    n_bins = sim.model.player_bins.edges.shape[1] - 1
    with pytest.raises(ArgumentError, match="must be"):
        sim.set_player_quantiles(np.zeros((2, n_bins + 1, 5)))
    sim.set_player_quantiles(np.zeros((2, n_bins, 5)))
    assert sim.player_quantiles_used().shape == (2, n_bins, 5)
    sim.player_bin_quantiles = False
    assert sim.player_quantiles_used() is None
