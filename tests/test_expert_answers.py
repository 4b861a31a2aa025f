"""The generator's kernel on a rally's own states, the strike read from a track, the expert's
flight read, and the hitter's run after his shot (teacher-forced and rolled out)."""

from __future__ import annotations

import numpy as np
import pytest

from sportsngen.data.tokens import Vocab
from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points
from sportsngen.eval.expert_answers import (
    expert_shots,
    lands_in,
    simulated_expert_arrays,
    summarise_expert_shots,
)
from sportsngen.eval.shot_profile import first_strike
from sportsngen.model.inputs import BALL
from sportsngen.synth import physics
from sportsngen.synth.profiles import get_profile
from sportsngen.synth.rally import play_rally
from sportsngen.train.expert import rally_state
from tests.conftest import tiny_sim

FPS = 25.0


def _played(seed: int, min_shots: int = 4):
    fed, nad = get_profile("Roger Federer"), get_profile("Rafael Nadal")
    rng = np.random.default_rng(seed)
    while True:
        r = play_rally(fed, nad, 1, "deuce", 1, "hard", rng)
        if len(r.shots) >= min_shots:
            pos = np.zeros((r.n_frames, 3, 3))
            pos[:, BALL] = r.ball_m
            pos[:, :BALL, :2] = np.transpose(r.players_m, (1, 0, 2))
            return r, pos


def test_lands_in_by_the_lines_and_the_net():
    labels = np.array([[5.0, 0.0, 1.2, 0.0],       # deep enough, central, over the net
                       [12.0, 0.0, 1.2, 0.0],      # long
                       [5.0, -4.2, 1.2, 0.0],      # wide
                       [5.0, 0.0, 0.93, 0.0],      # into the net (centre 0.914 + radius)
                       [-0.5, 0.0, 1.2, 0.0],      # never crossed
                       [11.885, 4.115, 0.95, 0.0],  # on both lines: in
                       [np.nan, 0.0, 1.2, 0.0]])
    assert lands_in(labels).tolist() == [True, False, False, False, False, True, False]


def test_first_strike_finds_the_return_where_it_landed():
    errors = []
    for seed in range(6):
        r, pos = _played(seed)
        serve = int(round(r.shots[0].t_s * FPS))
        got = first_strike(pos[:, BALL], serve + 2, FPS)
        assert got is not None
        frame, lab = got
        assert -2.0 <= frame - r.shots[1].t_s * FPS <= 1.0   # the contact lies in [t, t + 2]
        if r.shots[1].bounce_xy is not None:
            side = np.sign(pos[frame, BALL, 0])
            land = np.array([-side * lab[0], -side * lab[1]])   # back to the court's frame
            errors.append(np.hypot(*(land - np.asarray(r.shots[1].bounce_xy))))
    assert len(errors) >= 4 and max(errors) < 0.4
    assert first_strike(pos[:, BALL], len(pos), FPS) is None
    assert first_strike(pos[:, BALL], serve + 2, FPS, last_frame=serve + 3) is None


def test_a_flight_handed_over_early_is_read_after_its_contact_frame():
    # The contact frame before the racket (the rules' nearer frame may be): a fit through it
    # put a rally ball's bounce metres off; read from the frames after it, within 0.3 m.
    errors = []
    for seed in range(8):
        r, pos = _played(seed)
        for si in range(1, len(r.shots) - 1):
            if r.shots[si].bounce_xy is None:
                continue
            c = int(np.floor(r.shots[si].t_s * FPS))        # the last frame before the racket
            state = rally_state(pos, c + 5, c, r.shots[si].hitter, si + 1, FPS)
            if state is None or state.bounces:
                continue
            flight = physics.fly(state.ball_m, state.ball_vel_mps, state.ball_spin_mps, "hard",
                                 3.0, max_bounces=1, net=False)
            b = flight.first_bounce()
            errors.append(np.hypot(*(b.pos_m[:2] - np.asarray(r.shots[si].bounce_xy))))
    assert len(errors) >= 10
    assert max(errors) < 0.3


@pytest.fixture(scope="module")
def generated(truth_data):
    return truth_data(80, 6)


def test_expert_shots_on_the_record_agree_with_it(generated):
    rows = expert_shots(generated, shot=2, seed=0)
    rally, expert = rows[rows["who"] == "rally"], rows[rows["who"] == "expert"]
    assert len(rally) == len(expert) > 15
    assert rally["struck"].all()                         # only rallies that played shot 2
    assert expert["struck"].mean() > 0.8                 # the kernel answers the record's states
    assert (expert.loc[~expert["struck"], "expert_end"] != "").all()
    assert (rally["expert_end"] == "").all()
    assert (rows.loc[~rows["struck"], "in_play"] == False).all()  # noqa: E712
    table = summarise_expert_shots(rows)
    assert set(table["who"]) == {"rally", "expert"}
    assert table["n"].sum() == len(rows)
    with pytest.raises(ValueError, match=">= 2"):
        expert_shots(generated, shot=1)
    with pytest.raises(ValueError, match="after_frames"):
        expert_shots(generated, shot=2, after_frames=2)


def test_simulated_expert_arrays_keep_the_point_up_to_the_hand_over(generated):
    vocab = Vocab.from_data(generated)
    arr, counts = simulated_expert_arrays(generated, vocab, (2, 3), keep_frames=20)
    assert counts["answered"] == len(arr.length) > 15
    assert counts["states"] >= counts["answered"]
    from sportsngen.data.tokens import rally_arrays

    src = rally_arrays(generated, vocab, unknown="generic")
    for i in range(len(arr.length)):
        h = int(arr.learn_from[i])
        track = arr.pos_m[arr.start[i]:arr.start[i] + arr.length[i]]
        assert arr.length[i] <= h + 1 + 20
        # The context is one of the point's own tracks up to the hand-over.
        matches = [k for k in range(len(src.length)) if src.length[k] > h
                   and np.allclose(src.pos_m[src.start[k]:src.start[k] + h + 1], track[:h + 1])]
        assert matches


def test_recovery_curves_read_the_record_exactly_and_branch_the_model(tiny_model_file,
                                                                     truth_data):
    from sportsngen.eval.movement import _hitter_tracks, recovery_curves, teacher_forced_recovery
    from sportsngen.eval.rules import analyse_rally_data
    sim = tiny_sim(tiny_model_file)
    truth = truth_data(30, 3)
    rules = analyse_rally_data(truth)
    tf = teacher_forced_recovery(sim.model, sim.vocab, truth, shot=2, frames=10, draws=2,
                                 rules=rules)
    rec = _hitter_tracks(truth, rules, 2, 10).merge(tf, on=["rally_id", "k"])
    assert rec["rally_id"].nunique() >= 5 and np.isfinite(rec["dv_model"]).all()
    # The record's change of speed is the next step's speed less this one's, both read from
    # the server's own track (the model's input velocity is the backward difference).
    for _, g in rec.groupby("rally_id"):
        g = g.sort_values("k")
        np.testing.assert_allclose(g["dv_record"].to_numpy()[1:],
                                   np.diff(g["speed_mps"].to_numpy()), atol=2e-3)
    table = recovery_curves(sim, truth, shot=2, frames=10, bin_frames=5, draws=2)
    assert table["frames_after"].tolist() == [0, 5]
    assert (table["n"] == rec["rally_id"].nunique()).all()
    # The tiny model's branches seldom reach a shot of their own: its columns are there, empty
    # where no branch struck shot 2, and never disagree with their count.
    assert {"n_branch", "branch_behind_m", "branch_speed_mps"} <= set(table.columns)
    assert (table["n_branch"].isna() == table["branch_behind_m"].isna()).all()
    np.testing.assert_allclose(table["behind_m"].iloc[0],
                               rec.loc[rec["k"] < 5, "behind_m"].mean(), rtol=1e-9)
    # Shot 0 is the server's run back from his serve, read in the branches rolled out from 3
    # frames after it: every branch keeps its recorded serve, so every one is read.
    serve = recovery_curves(sim, truth, shot=0, frames=10, bin_frames=5, draws=2)
    assert serve["frames_after"].tolist() == [0, 5]
    assert (serve["n_branch"] >= 0.8 * serve["n"]).all()
    first = _hitter_tracks(truth, rules, 0, 10)
    np.testing.assert_allclose(serve["behind_m"].iloc[0],
                               first.loc[first["k"] < 5, "behind_m"].mean(), rtol=1e-9)
    with pytest.raises(ValueError, match="from the serve"):
        recovery_curves(sim, truth, shot=-1)


def test_chase_curves_read_the_run_to_the_strike_from_the_record(tiny_model_file):
    from sportsngen.eval.movement import (
        _chase_tracks,
        _teacher_forced_speed_change,
        chase_curves,
    )
    from sportsngen.eval.rules import analyse_rally_data
    sim = tiny_sim(tiny_model_file)
    truth = truth_points(DiagnosticsSetup(n_points=40, seed=3))
    rules = analyse_rally_data(truth)
    # Along a fixed direction, the record's change of speed is the next frame's speed less
    # this one's, read from the player's own track.
    tf = _teacher_forced_speed_change(sim.model, sim.vocab, truth, rules, 1, 10, 0,
                                      lambda rid, track, contacts: np.array([0.6, 0.8]), 2, 0,
                                      16)
    assert tf["rally_id"].nunique() >= 5 and np.isfinite(tf["dv_model"]).all()
    for _, g in tf.groupby("rally_id"):
        g = g.sort_values("k")
        np.testing.assert_allclose(g["dv_record"].to_numpy()[:-1],
                                   np.diff(g["speed_mps"].to_numpy()), atol=2e-3)
    # A run's speeds along the line to the strike add up to its length by the strike.
    runs = _chase_tracks(truth, rules, 1, 80)
    assert runs["rally_id"].nunique() >= 5
    for rid, g in runs.groupby("rally_id"):
        c0, c1 = (int(c) for c in list(rules.loc[rid, "contact_frames"])[1:3])
        moved = g.loc[g["k"] < c1 - c0, "speed_mps"].sum() / truth.fps
        assert moved == pytest.approx(g["need_m"].iloc[0], abs=1e-6)
    table = chase_curves(sim, truth, shot=1, frames=20, bin_frames=5, draws=2)
    assert set(table["frames_after"]) <= {0, 5, 10, 15}
    assert set(table["need"].astype(str)) <= {"<2 m", "2-4 m", ">4 m"}
    # The generator's server runs towards where he strikes the return: his speed that way is
    # positive on average from a few frames after the return on, wherever he had to go.
    later = table[table["frames_after"] >= 5]
    assert (later["speed_mps"] > 0).all() and later["n"].sum() > 0
    # The branches' columns are there, empty where no branch's server reached the return.
    assert {"n_branch", "branch_speed_mps"} <= set(table.columns)
    assert (table["n_branch"].isna() == table["branch_speed_mps"].isna()).all()
    with pytest.raises(ValueError, match="from the serve"):
        chase_curves(sim, truth, shot=-1)


def test_the_command_line_refuses_bad_shots(tmp_path, capsys):
    from sportsngen.eval.__main__ import main

    assert main(["movement", "--shot", "-1"]) == 2
    assert "--shot" in capsys.readouterr().err
    assert main(["expert", str(tmp_path / "absent")]) == 2
    assert "no tracking folder" in capsys.readouterr().err
    assert main(["expert", "--points", "20", "--shot", "1"]) == 2
    assert ">= 2" in capsys.readouterr().err


def test_paired_expert_gaps_pair_by_rally_and_shot_and_count_only_both_struck():
    import pandas as pd

    from sportsngen.eval.expert_answers import paired_expert_gaps
    rows = []

    def pair(rid, shot, own_in, kernel_in, kernel_struck=True):
        hitter = "R" if shot % 2 else "S"
        base = {"rally_id": rid, "shot": shot, "server": "S", "receiver": "R", "hitter": hitter}
        rows.append({**base, "who": "rally", "struck": True, "in_play": own_in})
        rows.append({**base, "who": "expert", "struck": kernel_struck,
                     "in_play": kernel_in and kernel_struck})
    pair(1, 3, False, True)
    pair(2, 3, True, True)
    pair(3, 3, False, False)
    pair(4, 3, True, False, kernel_struck=False)     # the kernel never struck: left out
    pair(1, 2, True, False)
    pair(2, 2, True, True)
    got = paired_expert_gaps(pd.DataFrame(rows)).set_index("role")
    assert got.loc["receiver", "n"] == 3 and got.loc["server", "n"] == 2
    assert got.loc["receiver", "hitter"] == "R" and got.loc["server", "hitter"] == "S"
    assert got.loc["receiver", "rally_in"] == pytest.approx(1 / 3)
    assert got.loc["receiver", "kernel_in"] == pytest.approx(2 / 3)
    assert got.loc["receiver", "gap"] == pytest.approx(-1 / 3)
    assert got.loc["receiver", "gap_se"] == pytest.approx(np.std([-1, 0, 0], ddof=1) / np.sqrt(3))
    assert got.loc["server", "gap"] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="struck both"):
        paired_expert_gaps(pd.DataFrame(rows[6:8]))


def test_expert_shots_answer_several_shots_with_their_hitters(generated):
    rows = expert_shots(generated, shot=(2, 3), seed=0)
    assert set(rows["shot"]) == {2, 3}
    r = rows.iloc[0]
    assert set(rows.loc[rows["shot"] == 2, "hitter"]) <= set(generated.rallies["server"])
    odd = rows[rows["shot"] == 3]
    assert (odd["hitter"] == odd["receiver"]).all()
    even = rows[rows["shot"] == 2]
    assert (even["hitter"] == even["server"]).all()
    # One shot asked alone gives the same rows as within the pair.
    alone = expert_shots(generated, shot=2, seed=0)
    assert r["rally_id"] in set(alone["rally_id"])
    assert len(alone) == len(even)
