"""The bundled model file loads without Hydra and knows the named players."""

from pathlib import Path

import numpy as np
import pytest
import torch

from sportsngen.model.export import load_model
from sportsngen.synth.profiles import named_profiles

BUNDLED = Path(__file__).resolve().parents[1] / "sportsngen/model/bundled/sportsngen-small.pt"


def test_bundled_model_loads_with_event_classifier_and_named_players():
    assert BUNDLED.stat().st_size < 40 * 1024 * 1024
    model, events, vocab, cfg = load_model(BUNDLED)
    assert events is not None
    assert set(named_profiles()) <= set(vocab.players)
    assert cfg.head == "factorised" and cfg.n_bins == 61
    assert all(torch.isfinite(p).all() for p in model.parameters())


def test_bundled_model_simulates_service_points():
    """The bundled file carries its serve starts; a few short rallies roll and get judged."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained(max_duration_s=4.0)
    assert "Roger Federer" in sim.initial.servers
    data = sim.simulate_points("Roger Federer", "Rafael Nadal", "hard", 4, seed=0,
                               serve_number=1)
    r = data.rallies
    assert len(r) == 4 and set(r["server"]) == {"Roger Federer"}
    assert r["end_reason"].isin(["fault", "ace", "winner", "forced_error", "unforced_error",
                                 "double_fault", "none"]).all()
    # Every rally starts from a real serve start: the server behind his baseline.
    f0 = data.frames[(data.frames["frame"] == 0) & (data.frames["object"] == "Roger Federer")]
    assert (f0["x"].abs() > 11.0).all()


def test_bundled_model_rolls_out_with_the_net_in_the_balls_step():
    """The bundled file was trained without the net in the ball's physics step and plays with
    it (its sampling defaults; docs/evaluation.md, thirty-fourth part); asked, it plays without."""
    from sportsngen.sim import Simulator

    _, _, _, cfg = load_model(BUNDLED)
    assert cfg.ball_net is False and cfg.ball_centre == "physics"
    sim = Simulator.from_pretrained()
    assert sim.model.cfg.ball_net is True and sim.contact_reach_m == 1.8
    assert Simulator.from_pretrained(ball_net=False).model.cfg.ball_net is False


def test_bundled_model_gives_the_return_its_reach_and_its_own_error_shifts():
    """The bundled file's returns: a contact within 1.5 m, every good serve within 1.5 m
    struck (1.2 m before its players' acceleration was limited; docs/evaluation.md,
    thirty-seventh part), and the receivers' own shifts of a return's errors, which lower the
    named players' odds of a return long (their record's returns err less than the head drew;
    thirty-fifth part)."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    assert sim.return_reach_m == 1.5 and sim.strike_in_reach_return_m == 1.5
    model, vocab = sim.model, sim.vocab
    assert model.cfg.strike_return and model.strike_return.shape == model.strike_bias[:, 0].shape
    named = torch.tensor([vocab.player_index(p) for p in
                          ("Roger Federer", "Serena Williams", "Maria Sharapova", "John Isner")])
    assert (model.strike_return[named, 0] < 0).all()
    # As fitted (`scripts/fit_strike_bias.py --pressure --view 8 --draws 4`, which refits the
    # returns' table on top of the players' rows at the head's own draws; model card):
    # Sharapova's long, wide and net shifts on her returns (refitted on generator version
    # 6.4's round robins, seventy-second part).
    torch.testing.assert_close(model.strike_return[vocab.player_index("Maria Sharapova")],
                               torch.tensor([-1.136, -1.732, -3.681]), atol=1e-3, rtol=0)
    assert Simulator.from_pretrained(return_reach_m=1.8).return_reach_m == 1.8


def test_bundled_model_reads_whom_a_player_answers():
    """The bundled file's opponents' table (`model.strike_pressure`, docs/evaluation.md,
    thirty-eighth part): in the generator a receiver's rally balls take the server's serve
    initiative times his rally pressure (Isner's 3.59 x 1.04, Djokovic's 1.59 x 0.91), and the
    fitted table has the receivers err wide more often against Isner than against Djokovic, the
    other way on the servers' rally balls too by their own opponents' pressure, and leaves the
    return to its own table. Refitted after the players' shifts (forty-sixth part), which carry
    part of whom a player answers, the gap was 0.87 (1.15 before); refitted at the head's own
    draws on the states a rollout reads (fifty-second part), 0.91; on version 6.4's round
    robins (seventy-second part), 1.00."""
    from sportsngen.model import strike_bias
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    model, vocab = sim.model, sim.vocab
    assert model.cfg.strike_pressure
    isner, djokovic = (vocab.player_index(p) for p in ("John Isner", "Novak Djokovic"))
    wide = strike_bias.WIDE
    assert model.strike_pressure[isner, 1, wide] - model.strike_pressure[djokovic, 1, wide] > 0.8
    torch.testing.assert_close(model.strike_pressure[djokovic, 1],
                               torch.tensor([-0.099, -0.427, -0.783]), atol=1e-3, rtol=0)
    receiver = torch.tensor([True, True])
    rally = model.strike_head_bias(torch.tensor([djokovic] * 2), receiver,
                                   torch.tensor([True, False]), torch.tensor([isner] * 2))
    masks = torch.as_tensor(strike_bias.error_bins())
    gap = rally[1, wide][masks[wide]] - rally[0, wide][masks[wide]]
    torch.testing.assert_close(gap, torch.full_like(gap, float(
        model.strike_pressure[isner, 1, wide] - model.strike_return[djokovic, wide])))


def test_bundled_model_bounces_the_ball_by_the_surfaces_physics():
    """The bundled file's rollouts take a bounce from the surface's physics, not the model's
    draw (its sampling defaults; docs/evaluation.md, thirty-sixth part); asked, they do not."""
    from sportsngen.sim import Simulator

    assert Simulator.from_pretrained().physical_bounce is True
    assert Simulator.from_pretrained(physical_bounce=False).physical_bounce is False


def test_bundled_model_runs_its_players_to_high_balls_at_a_comfortable_height():
    """The bundled file's late players run to where a high-bouncing ball is at a comfortable
    height (its sampling defaults; docs/evaluation.md, thirty-ninth part); asked, they do not."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    assert sim.keep_chasing is True and sim.chase_high_balls is True
    assert Simulator.from_pretrained(chase_high_balls=False).chase_high_balls is False


def test_bundled_model_limits_its_players_acceleration_to_the_generators():
    """The bundled file's rollouts change a player's velocity by at most 6 m/s² a frame, the
    generator's players' largest (its sampling defaults; docs/evaluation.md, thirty-seventh
    part); asked, they change it as drawn."""
    from sportsngen.sim import Simulator

    assert Simulator.from_pretrained().player_accel_mps2 == 6.0
    assert Simulator.from_pretrained(player_accel_mps2=None).player_accel_mps2 is None


def test_bundled_model_reads_the_shot_and_the_players_and_holds_short_second_serves():
    """The forty-sixth part's file: the strike head's input shifted by the strike's number and
    by the hitter and his opponent (`model.strike_shots`, `model.strike_players`), and the serve
    head's short serves held per server (`model.serve_short`): Williams' second serves, drawn
    short of 3.9 m 0.131 of the time against her record's 0.040, get the largest cut; Sharapova's,
    drawn short too rarely, a rise."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    model, vocab = sim.model, sim.vocab
    assert model.cfg.strike_shots and model.cfg.strike_players and model.cfg.serve_short
    assert (model.strike_shot.weight.norm(dim=1) > 1.0).all()
    djokovic = vocab.player_index("Novak Djokovic")
    assert (model.strike_player[djokovic].norm(dim=-1) > 1.0).all()
    short = {p: model.serve_short[vocab.player_index(p), 1].item()
             for p in ("Serena Williams", "Maria Sharapova", "Roger Federer")}
    assert short["Serena Williams"] == pytest.approx(-1.232, abs=1e-3)
    assert short["Maria Sharapova"] > 0.3
    assert short["Serena Williams"] < short["Roger Federer"] < 0


def test_bundled_model_draws_each_receivers_reach_and_each_servers_lateral_bands():
    """The fifty-third part's file: each serve's return reach drawn from its receiver's row
    (`sim.reach_table`, fitted on the training split and the named players' round robins:
    half of Nadal's good serves passing 1.48 m from him returned, Isner's 1.62 m), and the serve
    head's lateral bands per server (`model.serve_lateral`): Federer's first serves moved off the
    body (bands 2-3 cut) to the T and out wide, his wide odds held."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    assert sim.return_reach_draw and sim.return_reach is not None
    assert Simulator.from_pretrained(return_reach_draw=False).return_reach_draw is False
    reach = sim.return_reach
    assert reach.pooled[0] == pytest.approx(1.500, abs=1e-3)
    # Refitted on generator version 6.4's tracks (seventy-second part; 1.480 and 1.616 before).
    assert reach.players["Rafael Nadal"][0] == pytest.approx(1.463, abs=1e-3)
    assert reach.players["John Isner"][0] == pytest.approx(1.619, abs=1e-3)
    assert reach.players["Rafael Nadal"][1] == pytest.approx(0.0248, abs=1e-4)
    model, vocab = sim.model, sim.vocab
    assert model.cfg.serve_lateral and model.serve_lateral.shape[1:] == (2, 7)
    torch.testing.assert_close(model.serve_lateral[vocab.player_index("Roger Federer"), 0],
                               torch.tensor([0.369, 0.241, -0.302, -1.075, 0.039, 0.291, 0.436]),
                               atol=1e-3, rtol=0)


def test_bundled_model_bounds_each_player_by_his_records_top_speed():
    """The fifty-fourth part's file: each player's top speed read from the training split and
    the named players' round robins (`sim.top_speed`: the 99.9th percentile of his frame
    speeds, the generator's own 6.0 m/s for Sharapova and Isner, 7.0 for Nadal), which bounds
    every rollout frame of his by default; the rally balls' drawn reach stays off."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    assert sim.player_top_speed and sim.top_speeds is not None
    assert not sim.rally_reach_draw and sim.rally_reach is None
    assert Simulator.from_pretrained(player_top_speed=False).player_top_speed is False
    speeds = sim.top_speeds
    assert speeds.pooled_mps == pytest.approx(6.484, abs=1e-3)
    got = speeds.speeds_mps(["Maria Sharapova", "Serena Williams", "Rafael Nadal",
                             "Novak Djokovic", "Somebody Else"])
    assert got.tolist() == pytest.approx([6.0, 6.3, 7.0, 6.952, 6.484], abs=1e-3)


def test_bundled_model_lets_nadal_return_on_hard_as_his_record_does():
    """The seventy-second part's file: the hitters' surfaces table (`model.strike_surface`,
    `scripts/fit_strike_bias.py --pressure --view 8 --draws 4 --surface` on generator version
    6.4's round robins). Nadal's real returns run the other way between surfaces from everyone
    else's, and the generator's Nadal errs more returning on hard than on clay (composure 3.1
    against 2.3 under a rushed return); his rows pooled over surfaces drew 0.146 errors on his
    hard returns in rollouts against the truth's 0.318. His hard returns' shifts now raise all
    three errors, each above his clay returns'."""
    from sportsngen.model import strike_bias
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    model, vocab = sim.model, sim.vocab
    assert model.cfg.strike_surface
    nadal = vocab.player_index("Rafael Nadal")
    hard, clay = vocab.surfaces.index("hard"), vocab.surfaces.index("clay")
    returns = model.strike_surface[nadal, :, strike_bias.STROKE_RETURN]
    torch.testing.assert_close(returns[hard], torch.tensor([0.303, 0.219, 0.705]), atol=1e-3,
                               rtol=0)
    assert (returns[hard] > 0).all() and (returns[hard] > returns[clay]).all()
    # A return's shifts on hard carry the row; the same return on clay its own.
    bias = model.strike_head_bias(torch.tensor([nadal] * 2), torch.tensor([True, True]),
                                  torch.tensor([True, True]), torch.tensor([nadal] * 2),
                                  serve=torch.tensor([0, 0]), surface=torch.tensor([hard, clay]))
    long = torch.as_tensor(strike_bias.error_bins()[strike_bias.LONG])
    gap = bias[0, 0][long] - bias[1, 0][long]
    want = float(returns[hard, 0] - returns[clay, 0])
    torch.testing.assert_close(gap, torch.full_like(gap, want))


def test_bundled_model_places_players_draws_inside_their_bins_as_the_record():
    """The seventy-sixth part's file: per dimension and bin of the player head, the quantiles of
    the training offsets inside it (`model.bin_quantiles`), on by default. The bin that holds
    the generator's flat-out start (6 m/s², 0.0096 m a frame from constant velocity) holds the
    record's offsets at its cap, not spread to 0.0130 m."""
    from sportsngen.sim import Simulator

    sim = Simulator.from_pretrained()
    table = sim.player_quantiles_used()
    assert table is not None and tuple(table.shape) == (2, 61, 17)
    edges = sim.model.player_bins.edges
    k = int(torch.searchsorted(edges[1], torch.tensor(0.0096))) - 1
    assert edges[1, k] < 0.0096 < edges[1, k + 1] and edges[1, k + 1] > 0.0125
    np.testing.assert_allclose(table[1, k, [8, 12, 16]].numpy(), [0.0094, 0.0096, 0.0096],
                               atol=5e-5)
    assert Simulator.from_pretrained(player_bin_quantiles=False).player_quantiles_used() is None
