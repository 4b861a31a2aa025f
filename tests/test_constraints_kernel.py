"""The compiled judgements of the sampling constraints (`sim.constraint_kernel`) against their
torch reference, on frames drawn around every threshold they read."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sportsngen.sim import constraints
from sportsngen.sim.constraints import PhysicalLimits, StrikeInReach


def _frames(n: int, seed: int):
    """(pos, next, vel) (n, 3, 3) float32: balls near the net, the ground and the players,
    struck back, jolted, braked and falling; players within a few metres of them."""
    g = torch.Generator().manual_seed(seed)
    ball = torch.stack([torch.empty(n).uniform_(-14, 14, generator=g),
                        torch.empty(n).uniform_(-7, 7, generator=g),
                        torch.empty(n).uniform_(-0.1, 2.6, generator=g)], -1)
    ball[::5, 0] = torch.empty(len(ball[::5])).uniform_(-0.8, 0.8, generator=g)   # at the net
    vel = torch.randn(n, 3, generator=g) * torch.tensor([20.0, 4.0, 5.0])
    step = vel / 25.0
    kick = torch.randn(n, 3, generator=g) * 0.4 * (torch.rand(n, 1, generator=g) < 0.4)
    nxt_ball = ball + step + kick
    back = torch.rand(n, generator=g) < 0.2                 # struck back along x
    nxt_ball[back, 0] = ball[back, 0] - step[back, 0]
    players = ball[:, None, :2] + torch.randn(n, 2, 2, generator=g) * 1.6
    pos = torch.zeros(n, 3, 3)
    pos[:, :2, :2], pos[:, 2] = players, ball
    nxt = pos.clone()
    nxt[:, :2, :2] += torch.randn(n, 2, 2, generator=g) * 0.2
    nxt[:, 2] = nxt_ball
    v = torch.zeros(n, 3, 3)
    v[:, 2] = vel
    return pos, nxt, v


def _reference(monkeypatch, fn, *args):
    with monkeypatch.context() as m:
        m.setattr(constraints, "kernel_inputs", lambda *t: False)
        return fn(*args)


@pytest.mark.parametrize("reach_m", [None, 1.8])
def test_the_compiled_physical_limits_judge_as_torch_does(monkeypatch, reach_m):
    pos, nxt, vel = _frames(20000, 1)
    lim = PhysicalLimits(fps=25.0, reach_m=reach_m)
    rows = np.arange(len(pos))
    got = lim.accept(rows, 0, pos, nxt, vel)
    want = _reference(monkeypatch, lim.accept, rows, 0, pos, nxt, vel)
    assert (got != want).sum() <= 2                  # float32 rounding at a threshold
    assert 0.05 < (~want).float().mean() < 0.95     # the frames do cross the thresholds
    assert torch.equal(lim.accept(rows, 0, pos, nxt, None),
                       _reference(monkeypatch, lim.accept, rows, 0, pos, nxt, None))


@pytest.mark.parametrize("min_z_m,behind_m,with_vel", [(None, None, False), (0.34, None, True),
                                                        (0.34, 1.1, True)])
def test_the_compiled_pass_judges_as_torch_does(monkeypatch, min_z_m, behind_m, with_vel):
    pos, nxt, vel = _frames(20000, 2)
    con = StrikeInReach(tracker=None, reach_m=1.2, fps=25.0, min_z_m=min_z_m,
                        behind_m=behind_m)
    g = torch.Generator().manual_seed(3)
    role = torch.randint(0, 2, (len(pos),), generator=g)
    end = torch.where(torch.rand(len(pos), generator=g) < 0.5, 1.0, -1.0)
    reach = torch.empty(len(pos)).uniform_(0.8, 1.6, generator=g)
    v = vel if with_vel else None
    for r in (None, reach):
        got = con.passes(pos, nxt, role, end, v, r)
        want = _reference(monkeypatch, con.passes, pos, nxt, role, end, v, r)
        assert (got != want).sum() <= 2
        assert 0.02 < want.float().mean() < 0.9
