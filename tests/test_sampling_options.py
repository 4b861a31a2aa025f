"""The sampling flags the command lines share (`sportsngen.eval.sampling_options`)."""

import argparse

import pytest

from sportsngen.errors import ArgumentError
from sportsngen.eval.sampling_options import add_sampling_options, sampling_kwargs


def _parse(*argv):
    ap = argparse.ArgumentParser()
    add_sampling_options(ap)
    return ap.parse_args(list(argv))


def test_flags_left_out_keep_the_model_files_defaults():
    assert sampling_kwargs(_parse()) == {}


def test_each_flag_becomes_its_simulator_argument():
    args = _parse("--top-p-ball", "0.45", "--no-contact-odds", "--top-p-contact", "0.7",
                  "--top-p-serve", "0.9", "--strike-in-reach", "--strike-in-reach-from", "2",
                  "--strike-in-reach-force", "--strike-in-reach-m", "1.5", "--ball-net",
                  "--contact-reach-m", "1.8")
    assert sampling_kwargs(args) == {
        "top_p_ball": 0.45, "top_p_contact": 0.7, "top_p_serve": 0.9, "contact_odds": False,
        "strike_in_reach": True, "strike_in_reach_from": 2, "strike_in_reach_force": True,
        "strike_in_reach_m": 1.5, "ball_net": True, "contact_reach_m": 1.8}
    assert sampling_kwargs(_parse("--no-ball-net")) == {"ball_net": False}
    assert sampling_kwargs(_parse("--physical-bounce")) == {"physical_bounce": True}
    assert sampling_kwargs(_parse("--no-physical-bounce")) == {"physical_bounce": False}
    assert sampling_kwargs(_parse("--keep-chasing", "--chase-high-balls")) == {
        "keep_chasing": True, "chase_high_balls": True}
    assert sampling_kwargs(_parse("--player-accel-mps2", "6", "--player-accel-full-frac", "0.9",
                                  "--player-keep-heading-deg", "30")) == {
        "player_accel_mps2": 6.0, "player_accel_full_frac": 0.9, "player_keep_heading_deg": 30.0}


@pytest.mark.parametrize("argv, match", [
    (("--top-p-ball", "0"), "--top-p-ball"), (("--top-p-serve", "1.5"), "--top-p-serve"),
    (("--top-p-contact", "-0.1"), "--top-p-contact"),
    (("--strike-in-reach-from", "0"), "counts contacts"),
    (("--strike-in-reach-m", "0"), "--strike-in-reach-m"),
    (("--contact-reach-m", "-1"), "--contact-reach-m"),
    (("--player-accel-full-frac", "0"), "--player-accel-full-frac"),
    (("--player-keep-heading-deg", "180"), "--player-keep-heading-deg"),
    (("--player-keep-heading-deg", "0"), "--player-keep-heading-deg")])
def test_a_flag_out_of_its_range_is_refused(argv, match):
    with pytest.raises(ArgumentError, match=match):
        sampling_kwargs(_parse(*argv))


def test_every_sampling_option_is_a_simulator_keyword_a_config_key_and_a_flag_of_its_kind():
    """One table (`sim.simulator.SAMPLING_OPTIONS`) says what a config or a command line may
    set: each a `Simulator` keyword, each in `conf/simulate.yaml` (`simulate.py` forwards them
    by the table), and the shared flags a part of it, parsed to the table's kind."""
    import inspect
    from pathlib import Path

    from omegaconf import OmegaConf

    from sportsngen.eval.sampling_options import _FLAGS, _NUCLEI
    from sportsngen.sim.simulator import SAMPLING_OPTIONS, Simulator

    params = inspect.signature(Simulator.__init__).parameters
    conf = OmegaConf.load(Path(__file__).resolve().parents[1] / "conf" / "simulate.yaml")
    assert [k for k in SAMPLING_OPTIONS if k not in params] == []
    assert [k for k in SAMPLING_OPTIONS if k not in conf] == []
    # A Simulator keyword in the config that the table left out would be read and dropped.
    assert [k for k in conf if k in params and k not in SAMPLING_OPTIONS] == []
    assert [k for k in (*_NUCLEI, *_FLAGS) if k not in SAMPLING_OPTIONS] == []
    args = _parse("--strike-in-reach-from", "2", "--player-accel-mps2", "6", "--ball-net")
    for key, value in sampling_kwargs(args).items():
        assert type(value) is SAMPLING_OPTIONS[key], key
