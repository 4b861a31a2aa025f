"""Whole points shot by shot (`sportsngen.eval.shot_profile`)."""

import numpy as np
import pytest

from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_branches import shot_outcomes
from sportsngen.eval.shot_profile import (
    PROFILE_COLUMNS,
    format_profiles,
    format_unanswered,
    shot_profile,
    unanswered_by_flight,
)


@pytest.fixture(scope="module")
def truth(truth_data):
    data = truth_data(300, 5)
    return data, analyse_rally_data(data)


def test_the_profile_counts_each_shot_as_the_outcomes_do(truth):
    data, rules = truth
    prof = shot_profile(data, max_shot=4, rules=rules)
    assert list(prof.index) == [1, 2, 3, 4] and list(prof.columns) == list(PROFILE_COLUMNS)
    for shot in (1, 3):
        o = shot_outcomes(data, shot, rules)
        o = o[o["struck"]]
        assert prof.loc[shot, "n"] == len(o)
        assert prof.loc[shot, "in_play"] == pytest.approx(o["in_play"].mean())
        assert prof.loc[shot, "answered"] == pytest.approx(o.loc[o["in_play"], "answered"].mean())
    # Fewer rallies reach each later shot.
    assert (np.diff(prof["n"].to_numpy()) < 0).all()


def test_the_profile_reads_the_generators_strikes(truth):
    data, rules = truth
    prof = shot_profile(data, max_shot=3, rules=rules)
    # Returns are slower than the server's rally balls; every strike clears the net on the
    # median and lands between the service line and the baseline.
    assert prof.loc[1, "speed_mps"] < prof.loc[2, "speed_mps"]
    assert (prof["net_height_m"] > 1.0).all() and (prof["net_height_m"] < 2.5).all()
    assert (prof["depth_m"] > 6.4).all() and (prof["depth_m"] < 11.885).all()
    assert (prof["side_m"] > 0.5).all() and (prof["side_m"] < 3.0).all()
    # Nadal returns far behind the baseline (Hawk-Eye: 3.9 m on clay); the server strikes his
    # first rally ball near it (he serves 0.5 m inside and recovers 0.3 m behind).
    assert 1.5 < prof.loc[1, "hitter_behind_m"] < 4.0
    assert abs(prof.loc[2, "hitter_behind_m"]) < 0.6
    # The generator's own recorded shot table says the same speeds, to a few m/s.
    shots = data.shots[data.shots["shot_index"] == 1]
    assert prof.loc[1, "speed_mps"] == pytest.approx(shots["speed_mps"].median(), abs=3.0)


def test_two_profiles_print_side_by_side(truth):
    data, rules = truth
    prof = shot_profile(data, max_shot=2, rules=rules)
    text = format_profiles(prof, prof).splitlines()
    assert len(text) == 3 and text[0].split()[0] == "shot"
    assert text[1].split()[:4] == ["1", f"{prof.loc[1, 'n']:.0f}", "/", f"{prof.loc[1, 'n']:.0f}"]
    with pytest.raises(ValueError, match="max_shot"):
        shot_profile(data, max_shot=0, rules=rules)


def test_the_unanswered_balls_split_by_flight(truth):
    data, rules = truth
    got = unanswered_by_flight(data, rules)
    assert list(got.index) == ["all", "slow", "other"]
    # Every ball in play after the serve, shot by shot, as the outcomes count them.
    n_live, n_missed, slow, slow_missed = 0, 0, 0, 0
    for shot in range(1, 60):
        o = shot_outcomes(data, shot, rules)
        o = o[o["in_play"]]
        n_live += len(o)
        n_missed += int((~o["answered"]).sum())
        for rid, c, answered in zip(o.index, o["contact_frame"], o["answered"]):
            b = [f for f in rules.at[rid, "bounce_frames"] if f > c]
            if b and b[0] - c >= 1.32 * data.fps:
                slow += 1
                slow_missed += int(not answered)
    assert got.loc["all", "n"] == n_live and got.loc["slow", "n"] == slow
    assert got.loc["slow", "n"] + got.loc["other", "n"] == n_live
    assert got.loc["all", "unanswered"] == pytest.approx(n_missed / n_live)
    assert got.loc["slow", "unanswered"] == pytest.approx(slow_missed / slow)
    assert got.loc["slow", "share"] == pytest.approx(slow / n_live)
    p = n_missed / n_live
    assert got.loc["all", "se"] == pytest.approx(np.sqrt(p * (1 - p) / n_live))
    # The generator's players answer most balls, and a few are slow.
    assert 0.01 < got.loc["slow", "share"] < 0.3 and got.loc["all", "unanswered"] < 0.15
    # No ball flies 100 s: none slow, its share unknown.
    none = unanswered_by_flight(data, rules, slow_s=100.0)
    assert none.loc["slow", "n"] == 0 and np.isnan(none.loc["slow", "unanswered"])
    text = format_unanswered(got, got).splitlines()
    assert len(text) == 4 and text[2].split()[:4] == ["slow", str(slow), "/", str(slow)]
    with pytest.raises(ValueError, match="slow_s"):
        unanswered_by_flight(data, rules, slow_s=0.0)


def test_strike_endings_count_each_hitters_strikes_by_role_and_stage():
    from types import SimpleNamespace

    import pandas as pd

    from sportsngen.eval.shot_profile import format_strike_endings, strike_endings

    rallies = pd.DataFrame({"rally_id": [0, 1, 2], "server": ["A", "B", "A"],
                            "realistic": [True, True, False]})
    # Rally 0: A serves, B returns in, A's ball in, B's error at shot 3. Rally 1: B serves, A's
    # return a winner. Rally 2 is non-realistic and left out.
    shots = pd.DataFrame({
        "rally_id": [0, 0, 0, 0, 1, 1, 2, 2],
        "shot_index": [0, 1, 2, 3, 0, 1, 0, 1],
        "hitter": ["A", "B", "A", "B", "B", "A", "A", "B"],
        "outcome": ["in_play", "in_play", "in_play", "error", "in_play", "winner",
                    "in_play", "error"]})
    data = SimpleNamespace(rallies=rallies, shots=shots)
    got = strike_endings(data)
    assert list(got.index) == [("A", "receiver", "return"), ("A", "server", "shots 2-4"),
                               ("B", "receiver", "return"), ("B", "receiver", "shots 2-4")]
    assert got["n"].tolist() == [1, 1, 1, 1]
    assert got["error"].tolist() == [0.0, 0.0, 0.0, 1.0]
    assert got["winner"].tolist() == [1.0, 0.0, 0.0, 0.0]
    # With the non-realistic rally: B's return is an error too.
    every = strike_endings(data, realistic_only=False)
    assert every.loc[("B", "receiver", "return"), "n"] == 2
    assert every.loc[("B", "receiver", "return"), "error"] == 0.5
    assert every.loc[("B", "receiver", "return"), "error_se"] == pytest.approx(0.5 / np.sqrt(2))
    # Shot 5 and later fall in the last stage.
    long = SimpleNamespace(rallies=rallies.iloc[:1], shots=pd.DataFrame({
        "rally_id": [0] * 7, "shot_index": list(range(7)),
        "hitter": ["A", "B"] * 3 + ["A"], "outcome": ["in_play"] * 6 + ["error"]}))
    stages = strike_endings(long).reset_index()
    assert stages[stages["stage"] == "shots 5+"]["n"].sum() == 2
    text = format_strike_endings(got, every).splitlines()
    assert len(text) == 5 and "0.000 / 0.500" in text[3]
    # Split by the point's serve: rally 0 a second serve, rally 1 a first.
    served = SimpleNamespace(rallies=rallies.assign(serve_number=[2, 1, 1]), shots=shots)
    split = strike_endings(served, by_serve=True)
    assert list(split.index) == [("A", "receiver", 1, "return"), ("A", "server", 2, "shots 2-4"),
                                 ("B", "receiver", 2, "return"),
                                 ("B", "receiver", 2, "shots 2-4")]
    assert split["error"].tolist() == got["error"].tolist()
    lines = format_strike_endings(split, split).splitlines()
    assert "serve" in lines[0] and lines[4].split()[:5] == ["B", "receiver", "2", "shots", "2-4"]
