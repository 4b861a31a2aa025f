"""The library behind the check, diagnosis and rendering commands of `scripts/`: the shared
command-line helpers, the markdown table, and the pieces each command's report is built from."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pandas as pd
import pytest

from sportsngen.errors import ArgumentError


def test_command_line_builds_the_simulator_the_flags_ask_for(monkeypatch):
    from sportsngen.eval import command_line

    got = {}

    class FakeSimulator:
        @staticmethod
        def from_pretrained(model, **kw):
            got.update(model=model, **kw)
            return "sim"

    monkeypatch.setattr(command_line, "Simulator", FakeSimulator)
    ap = argparse.ArgumentParser()
    command_line.add_simulator_options(ap)
    command_line.add_points_seed(ap, points=150, seed=2)
    args = ap.parse_args(["--top-p-ball", "0.5", "--no-contact-odds", "--top-p-player", "0.9"])
    assert (args.points, args.seed, args.model, args.threads) == (150, 2, None, None)
    assert command_line.simulator_from_args(ap, args, physical_limits=False) == "sim"
    assert got == {"model": None, "physical_limits": False, "top_p_ball": 0.5,
                   "contact_odds": False, "top_p_player": 0.9}
    with pytest.raises(SystemExit):   # a nucleus out of (0, 1] is the parser's error
        command_line.simulator_from_args(ap, ap.parse_args(["--top-p-ball", "1.5"]))


def test_markdown_table():
    from sportsngen.eval.markdown import markdown_table

    assert markdown_table(["a", "b"], [("x", 0.12345), (3, "y")]) == [
        "| a | b |", "|---|---|", "| x | 0.123 |", "| 3 | y |"]
    assert markdown_table(["a"], [], float_format="{:.1f}") == ["| a |", "|---|"]


def test_leak_report_compare_tables_two_runs(tmp_path):
    from sportsngen.eval.leak_report import MATCHUPS, compare, matchup_name

    assert matchup_name(("Roger Federer", "Rafael Nadal"), "hard") == "federer_nadal_hard"
    for run, auc in (("before", 0.7), ("now", 0.5)):
        for players, surface in MATCHUPS:
            pd.DataFrame({"pair": ["fault_vs_in"], "role": ["hitter"], "feature": ["speed_mps"],
                          "k": [6], "auc": [auc], "lo": [auc - 0.1], "hi": [auc + 0.1]}).to_csv(
                tmp_path / f"{run}_{matchup_name(players, surface)}.csv", index=False)
    lines = compare(tmp_path / "before", tmp_path / "now").splitlines()
    assert lines[0] == "| pair | role | feature | Federer v Nadal k=6 | Djokovic v Murray k=6 |"
    assert lines[1] == "|---|---|---|---|---|"
    assert lines[2] == ("| fault_vs_in | hitter | speed | **0.70 [0.60, 0.80]** → 0.50 [0.40, "
                        "0.60] | **0.70 [0.60, 0.80]** → 0.50 [0.40, 0.60] |")


def test_read_noise_runs_refuses_a_run_without_noise(tmp_path):
    from sportsngen.eval.check_noise import pooled_report, read_noise_runs

    rows = [{"server": "A", "statistic": "ace", "gap": 0.01, "se": 0.02}]
    (tmp_path / "new.json").write_text(json.dumps({"noise": rows}))
    (tmp_path / "old.json").write_text(json.dumps({"stats": []}))
    [noise] = read_noise_runs([str(tmp_path / "new.json")])
    assert noise.to_dict(orient="records") == rows
    with pytest.raises(ArgumentError, match="old.json holds no noise rows"):
        read_noise_runs([str(tmp_path / "new.json"), str(tmp_path / "old.json")])
    report = pooled_report([str(tmp_path / "new.json")] * 2).splitlines()
    assert report[0].startswith("2 runs; mean gap") and report[2].startswith("A ")
    assert "+1.00±1.41" in report[2]   # ace in percent: mean gap 1, se sqrt(2 * 2²) / 2


def test_leak_fixture_refuses_other_points_and_versions(tmp_path, truth_data):
    from sportsngen.eval.leak_fixture import fixture_points
    from sportsngen.synth.dataset import GENERATOR_VERSION

    if GENERATOR_VERSION != "5":
        with pytest.raises(ArgumentError, match="records generator version 5"):
            fixture_points()
    truth_data(40, 5).save(tmp_path / "points")
    with pytest.raises(ArgumentError, match="is not"):
        fixture_points(tmp_path / "points")


def test_rules_check_noise_and_bounce_errors(truth_data):
    from sportsngen.eval.rules import analyse_rally_data
    from sportsngen.eval.rules_check import add_noise, bounce_errors

    data = truth_data(40, 5)
    clean = data.frames[["x", "y", "z"]].to_numpy().copy()
    ball = (data.frames["object"] == "ball").to_numpy()
    add_noise(data, 0.1, seed=0)
    moved = np.abs(data.frames[["x", "y", "z"]].to_numpy() - clean)
    assert (moved[:, 0] <= 0.1 + 1e-9).all() and (moved[ball, 1:] <= 0.05 + 1e-9).all()
    assert (moved[~ball, 2] == 0).all() and (data.frames.loc[ball, "z"] >= 0).all()
    err = bounce_errors(analyse_rally_data(truth_data(40, 5)), data.shots)
    assert err.shape[1] == 2 and len(err) > 20
    assert np.abs(err).max() < 0.5   # the rules find the generator's bounces within centimetres


def test_gallery_picks_the_first_rally_of_each_kind():
    from types import SimpleNamespace

    from sportsngen.viz.gallery import gallery_rallies

    rallies = pd.DataFrame({"rally_id": [10, 11, 12, 13],
                            "end_reason": ["ace", "forced_error", "forced_error", "ace"],
                            "rally_length": [1, 3, 7, 1]})
    shots = pd.DataFrame({"rally_id": [12, 12, 11], "stroke": ["forehand", "backhand_volley",
                                                               "forehand_volley"]})
    kinds = gallery_rallies(SimpleNamespace(rallies=rallies, shots=shots))
    assert {k: v.tolist() for k, v in kinds.items()} == {
        "ace": [10, 13], "long_rally": [12], "net_play": [12, 11], "forced_error": [12]}


def test_opponent_speed_by_fate(truth_data):
    from sportsngen.eval.leak_causes import opponent_speed_by_fate

    table = opponent_speed_by_fate(truth_data(60, 1), k=12)
    assert set(table.index) <= {"in", "net", "long", "wide"} and "in" in table.index
    assert list(table.columns) == ["count", "mean", "median"]
    assert (table["count"] > 0).all() and (table["mean"] >= 0).all()


def test_compare_style_graphs_of_a_sample_with_itself(truth_data):
    from sportsngen.eval.style_graph import compare_style_graphs, shot_cycles

    cycles = shot_cycles(truth_data(60, 3))
    rows, ref, on = compare_style_graphs({"truth": cycles, "truth2": cycles, "sim": cycles},
                                         ["Roger Federer"], threshold_m=1.5, seed=0)
    [row] = rows
    assert row["similarity_sim"] == pytest.approx(1.0)
    assert row["similarity_truth2"] == pytest.approx(1.0)
    assert row["skill_index_sim"] == row["skill_index_truth"] == ref[0].skill_index
    assert row["cycles_sim"] == row["cycles_truth"] == int(on[0].node_counts.sum())


def test_synth_physics_line():
    from sportsngen.eval.synth_physics import check

    line = check("clay", n_points=20, seed=1)
    assert line.startswith("clay: 20 points; serve contact z median ")
    assert "0 below the cord" in line
