"""What the table-fitting scripts share (`sportsngen.train.table_cli`), the strike fits'
options (`train.strike_fits.StrikeFit`), the calibration's starting profiles and the pooled
truth's matchup: the library the scripts call, without running a fit."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest

from sportsngen.data.tokens import Vocab
from sportsngen.errors import ArgumentError
from sportsngen.model.inputs import N_SPECIAL_IDS
from sportsngen.train.strike_fits import FIT_NAMES, StrikeFit, fit_strike_tables_file
from sportsngen.train.table_cli import named_players, parse_value, player_names, set_sim_defaults


def test_sampling_defaults_are_read_from_key_value_words(tiny_model_file, tmp_path):
    assert parse_value("TRUE") is True and parse_value("false") is False
    assert parse_value("1.5") == 1.5
    with pytest.raises(ArgumentError, match="true, false or a number"):
        parse_value("maybe")
    path = shutil.copy(tiny_model_file, tmp_path / "defaults.pt")
    got = set_sim_defaults(path, ["strike_in_reach_force=true", "strike_in_reach_m=1.5"])
    assert got["strike_in_reach_force"] is True and got["strike_in_reach_m"] == 1.5
    assert set_sim_defaults(path, ["top_p_ball=0.4"])["strike_in_reach_m"] == 1.5   # kept
    with pytest.raises(ArgumentError, match="not a Simulator sampling argument"):
        set_sim_defaults(path, ["no_such_default=1"])


def test_players_are_named_by_token_id_and_by_the_files_data():
    vocab = Vocab(players=("A", "B"))
    assert player_names(vocab) == {N_SPECIAL_IDS: "A", N_SPECIAL_IDS + 1: "B"}
    extra = {"split": {"data": {"players": {"named": ["A", "B"]}}}}
    assert named_players(None, extra) == ["A", "B"]
    assert named_players(" C, D ,", extra) == ["C", "D"]
    with pytest.raises(SystemExit, match="no players"):
        named_players(None, {})


def test_the_strike_fits_refuse_options_that_do_not_go_together_before_reading():
    assert StrikeFit().which is None and "return_surface" in FIT_NAMES
    with pytest.raises(ArgumentError, match="--late-only goes with --late"):
        StrikeFit(which="pressure", late_only=True)
    with pytest.raises(ArgumentError, match="--draws goes with"):
        StrikeFit(which="width", draws=2)
    assert StrikeFit(which=None, surface=True, draws=2).draws == 2
    # Refused before the (missing) model file is read.
    with pytest.raises(ArgumentError, match="one fit at a time"):
        fit_strike_tables_file("no-such-file.pt", "out.pt", width=True, shape=True)
    with pytest.raises(ArgumentError, match="--more-data-only goes with --more-data"):
        fit_strike_tables_file("no-such-file.pt", "out.pt", more_data_only=True)


def test_a_calibration_starts_from_the_seeds_or_from_its_file(tmp_path):
    from sportsngen.synth.calibrate import starting_profiles, write_profiles
    from sportsngen.synth.profiles import profile_seeds, read_profiles
    from sportsngen.synth.targets import load_targets

    targets = load_targets()
    out = tmp_path / "profiles.json"
    seeded = starting_profiles(out, init=False, targets=targets)      # no file yet: the seeds
    assert list(seeded) == list(profile_seeds())
    federer = seeded["Roger Federer"]
    assert federer.first_serve_kmh == float(targets.loc["Roger Federer",
                                                        "first_serve_kmh_median"])
    write_profiles({"Roger Federer": federer}, out)
    assert list(starting_profiles(out, init=False, targets=targets)) == ["Roger Federer"]
    assert read_profiles(out)["Roger Federer"].first_serve_kmh == federer.first_serve_kmh
    assert list(starting_profiles(out, init=True, targets=targets)) == list(seeded)


def test_a_run_is_one_matchup_on_one_surface(tmp_path):
    from types import SimpleNamespace

    from sportsngen.eval.pooled_truth import matchup

    rallies = pd.DataFrame({"server": ["A", "B", "A"], "receiver": ["B", "A", "B"],
                            "surface": ["clay"] * 3})
    assert matchup(SimpleNamespace(rallies=rallies), tmp_path) == (("A", "B"), "clay")
    with pytest.raises(SystemExit, match="more than one matchup"):
        matchup(SimpleNamespace(rallies=rallies.assign(receiver=["B", "C", "B"])), tmp_path)
    with pytest.raises(SystemExit, match="2 surfaces"):
        matchup(SimpleNamespace(rallies=rallies.assign(surface=["clay", "hard", "clay"])),
                tmp_path)
