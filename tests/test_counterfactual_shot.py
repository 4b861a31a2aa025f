"""A counterfactual's shot is the one the model plays: with a strike (or serve) head the head's
landing point is judged and drawn again until it goes as asked (`ShotConstraint.judge_strikes`,
`strike_heads.place_strikes`'s veto), and every rule of the rollout keeps its own number of
tries beside the shot's (`AllOf.asks`)."""

from pathlib import Path

import numpy as np
import pytest
import torch

from sportsngen.model.inputs import BALL
from sportsngen.sim.constraints import AllOf
from sportsngen.sim.frame_draws import redraw_rejected
from sportsngen.sim.whatif import LEAVE_WINDOW_FRAMES, ShotConstraint
from tests.test_head_fit import small_model

BUNDLED = Path(__file__).resolve().parents[1] / "sportsngen" / "model" / "bundled" / \
    "sportsngen-small.pt"


class _Rejects:
    """A rule that rejects the rows `bad` on every draw; records whom it gives up on."""

    offset = 0

    def __init__(self, bad, max_tries):
        self.bad, self.max_tries, self.told = set(bad), max_tries, []

    def accept(self, rows, frame, pos_m, next_pos_m, vel_mps=None):
        return torch.as_tensor([int(r) not in self.bad for r in rows])

    def give_up(self, rows):
        self.told += [int(r) for r in rows]


class _SameDraw:
    def sample_next(self, h, pos_m, *args, **kwargs):
        return pos_m.clone()


def test_each_rule_keeps_its_own_tries_beside_a_patient_one():
    few, many = _Rejects([0], max_tries=1), _Rejects([1], max_tries=5)
    pos = torch.zeros(3, 3, 3)
    _, drawn, _ = redraw_rejected(_SameDraw(), AllOf(few, many), np.arange(3), 10,
                                  torch.zeros(3, 1), pos, pos, pos, pos.clone(), 1.0, 1.0, None)
    # Alone the impatient rule gets 2 redraws of its row; beside the patient one, still 2.
    assert drawn.tolist() == [2, 10, 0]
    assert few.told == [0] and many.told == [1]
    # A new frame starts every row's count again.
    con = AllOf(few, many)
    for frame in (11, 12):
        _, drawn, _ = redraw_rejected(_SameDraw(), con, np.arange(3), frame, torch.zeros(3, 1),
                                      pos, pos, pos, pos.clone(), 1.0, 1.0, None)
        assert drawn.tolist() == [2, 10, 0]


def _receiver_forehand(option, max_tries=3):
    # The receiver strikes from the +x end, standing in the left third (y < 0 from the net):
    # down the line keeps to y < 0, cross court crosses to y > 0.
    return ShotConstraint(option, hitter=1, hitter_end=1, handedness="right", stroke="forehand",
                          serve_side="deuce", start_frame=10, max_tries=max_tries, by_head=True)


def _frames(n):
    pos = torch.zeros(n, 3, 3)
    pos[:, 0] = torch.tensor([-11.0, 0.0, 0.0])           # the server
    pos[:, 1] = torch.tensor([11.0, -2.5, 0.0])           # the receiver, left third
    pos[:, BALL] = torch.tensor([10.5, -2.0, 1.0])        # the contact, on his end
    return pos


def test_the_heads_landing_is_judged_and_given_up_after_its_tries():
    con = _receiver_forehand("down_the_line")
    pos = _frames(2)
    line, cross = np.array([-8.0, -3.0]), np.array([-8.0, 3.0])
    assert con.judges_strikes
    # The sampled frame is not judged: the head replaces the ball of a strike.
    assert con.accept(np.arange(2), 11, pos, pos.clone(), torch.zeros(2, 3, 3)).all()
    ok = con.judge_strikes(np.arange(2), 11, pos, np.stack([line, cross]), False)
    assert ok.tolist() == [True, False] and con.done == {0} and con.failed == set()
    # Row 0 is done: no longer judged. Row 1 gives up on its third rejected draw.
    for want in ([True, False], [True, True]):
        assert con.judge_strikes(np.arange(2), 12, pos, np.stack([cross, cross]),
                                 False).tolist() == want
    assert con.done == {0, 1} and con.failed == {1} and con.head_tries == {1: 3}
    # Not judged: a serve for a rally shot, a frame past the window, the other player's strike.
    fresh = _receiver_forehand("cross_court")
    assert fresh.judge_strikes(np.arange(2), 11, pos, np.stack([line, line]), True).all()
    assert fresh.judge_strikes(np.arange(2), 10 + LEAVE_WINDOW_FRAMES, pos,
                               np.stack([line, line]), False).all()
    other = pos.clone()
    other[:, BALL, 0] = -10.5
    assert fresh.judge_strikes(np.arange(2), 11, other, np.stack([line, line]), False).all()
    assert fresh.done == set() and fresh.head_tries == {}
    # Without a head the sampled frame's flight is judged, as before.
    plain = ShotConstraint("down_the_line", 1, 1, "right", "forehand", "deuce", 10)
    assert not plain.judges_strikes


def test_a_vetoed_launch_is_drawn_again_from_the_head():
    model = small_model()
    pos = _frames(2)
    h = torch.zeros(2, 3, 32)
    forced = torch.tensor([True, True])
    gen = torch.Generator().manual_seed(3)
    free = model.place_strikes(h, pos, torch.zeros(2, 3, 3), pos.clone(), gen, forced=forced)
    # No veto: the same draws as before the veto existed (the generator read the same way).
    again = model.place_strikes(h, pos, torch.zeros(2, 3, 3), pos.clone(),
                                torch.Generator().manual_seed(3), forced=forced)
    assert all(torch.equal(a, b) for a, b in zip(free, again))
    offered = {0: 0, 1: 0}

    def veto(rows, land_xy, serve):
        assert not serve and land_xy.shape == (len(rows), 2)
        assert (land_xy[:, 0] < 0).all()            # struck from +x, landing beyond the net
        for r in rows:
            offered[int(r)] += 1
        return np.array([offered[int(r)] > 3 for r in rows])

    nxt, plan = model.place_strikes(h, pos, torch.zeros(2, 3, 3), pos.clone(),
                                    torch.Generator().manual_seed(3), forced=forced, veto=veto)
    assert offered == {0: 4, 1: 4}                   # three rejected, the fourth stands
    assert torch.isfinite(plan).all() and not torch.equal(nxt[:, BALL], pos[:, BALL])


@pytest.mark.skipif(not BUNDLED.exists(), reason="the bundled model file is not in this checkout")
def test_the_bundled_models_counterfactual_plays_the_asked_side():
    """The bundled file has a strike head: each option's branches send the shot where asked
    (before the head's landing was judged, none of 100 "down the line" branches did)."""
    from sportsngen.sim import Simulator
    from sportsngen.synth.generate import generate_matches

    sim = Simulator.from_pretrained()
    real = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 30, seed=3)
    shots = real.shots[real.shots["shot_index"] == 2]
    rid = int(shots["rally_id"].iat[0])
    from sportsngen.sim.whatif import counterfactual

    table, branches = counterfactual(sim, real, rid, 2, n=8, seed=0, return_branches=True)
    assert table["n_forced_failed"].tolist() == [0, 0]
    side = {}
    for opt, out in branches.items():
        s = out.shots[out.shots["shot_index"] == 2]
        # Nadal strikes from the +x end standing in the y < 0 third.
        assert (s["contact_x"] > 0).all() and (s["contact_y"] < -1.372).all()
        side[opt] = np.sign(s["bounce_y"].to_numpy())
    assert (side["cross_court"] > 0).all() and (side["down_the_line"] < 0).all()


@pytest.mark.skipif(not BUNDLED.exists(), reason="the bundled model file is not in this checkout")
def test_the_bundled_models_serve_counterfactual_lands_in_the_asked_zone():
    """The serve head's landing is judged the same way: every branch's serve that bounces
    bounces in the asked third of the box (before, 13 of 29 "wide" branches served wide)."""
    from sportsngen.sim import Simulator
    from sportsngen.sim.whatif import counterfactual
    from sportsngen.synth.generate import generate_matches

    sim = Simulator.from_pretrained()
    real = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 30, seed=3)
    rid = int(real.shots[real.shots["shot_index"] == 2]["rally_id"].iat[0])
    table, branches = counterfactual(sim, real, rid, 0, options=("wide", "T"), n=6, seed=0,
                                     return_branches=True)
    assert table["n_forced_failed"].tolist() == [0, 0]
    for opt, out in branches.items():
        serves = out.shots[(out.shots["shot_index"] == 0) & out.shots["bounce_y"].notna()]
        assert len(serves) >= 5 and (serves["direction"] == opt).all()
