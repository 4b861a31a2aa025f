"""simulate.py's engine glue: a whole Markov match through the Hydra config."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from sportsngen.baselines.serve_model import serve_model
from sportsngen.cli.simulate import run_simulation
from sportsngen.tennis.scoring import MatchFormat, MatchState

CONF = str(Path(__file__).resolve().parents[1] / "conf")


def _cfg(tmp_path, *overrides):
    with initialize_config_dir(config_dir=CONF, version_base=None):
        return compose("simulate", overrides=[f"output_dir={tmp_path}", "engine=markov",
                                              *overrides])


def test_markov_match_replays_to_a_finished_match(tmp_path, capsys):
    points = run_simulation(_cfg(tmp_path, "seed=3"))
    # The points table must itself be a legal match: replaying its winners ends it exactly.
    names = ("Roger Federer", "Rafael Nadal")
    state = MatchState.new(MatchFormat(best_of=3), first_server=0)
    for server, winner in zip(points["server"], points["winner"]):
        assert names[state.server] == server
        state = state.point_won(names.index(winner))
    assert state.is_over
    assert (tmp_path / "points.parquet").exists() and (tmp_path / "win_probability.png").exists()
    out = capsys.readouterr().out
    assert "Roger Federer" in out and "1st in" in out


def test_same_seed_same_match(tmp_path):
    a = run_simulation(_cfg(tmp_path / "a", "seed=5"))
    b = run_simulation(_cfg(tmp_path / "b", "seed=5"))
    assert a.equals(b)


def test_unknown_player_lists_known_ones():
    with pytest.raises(ValueError, match="known players: .*Novak Djokovic"):
        serve_model("Nobody Atall")


def test_bad_engine_and_format(tmp_path):
    with pytest.raises(ValueError, match="engine must be one of"):
        run_simulation(_cfg(tmp_path, "engine=magic"))
    with pytest.raises(ValueError):
        run_simulation(_cfg(tmp_path, "format.best_of=4"))


def test_report_written_by_default_and_can_be_turned_off(tmp_path, capsys):
    run_simulation(_cfg(tmp_path / "on", "seed=3"))
    assert f"report: {tmp_path / 'on' / 'report.html'}" in capsys.readouterr().out
    html = (tmp_path / "on" / "report.html").read_text()
    assert 'id="match-data"' in html and "Roger Federer" in html
    run_simulation(_cfg(tmp_path / "off", "seed=3", "report=false"))
    assert not (tmp_path / "off" / "report.html").exists()
    assert "report:" not in capsys.readouterr().out


def test_the_learned_engine_forwards_each_sampling_option_of_the_config(tmp_path, monkeypatch):
    """Every sampling key set in the config reaches the Simulator, of its kind, the rest left
    to the model file; `top_p` sets both nuclei over their own."""
    from sportsngen.sim.simulator import Simulator

    seen = {}

    class Stop(Exception):
        pass

    def load(path=None, **kw):
        seen.update(kw, path=path)
        raise Stop

    monkeypatch.setattr(Simulator, "from_pretrained", staticmethod(load))
    with pytest.raises(Stop):
        run_simulation(_cfg(tmp_path, "engine=sportsngen", "top_p_ball=0.3",
                            "player_keep_heading_deg=20", "strike_in_reach_from=2",
                            "ball_net=false", "refresh_frames=8"))
    assert seen == {"path": None, "top_p_ball": 0.3, "player_keep_heading_deg": 20.0,
                    "strike_in_reach_from": 2, "ball_net": False, "refresh_frames": 8}
    assert type(seen["player_keep_heading_deg"]) is float
    seen.clear()
    with pytest.raises(Stop):
        run_simulation(_cfg(tmp_path, "engine=sportsngen", "top_p=0.5", "top_p_ball=0.3"))
    assert seen == {"path": None, "top_p_player": 0.5, "top_p_ball": 0.5}


def test_the_demos_extras_are_off_unless_asked_for():
    from omegaconf import OmegaConf

    from sportsngen.cli.simulate import _extra, _gif_frames
    from sportsngen.errors import ArgumentError

    base = {"animation_max_frames": None, "report_whatif_shots": None}
    off = OmegaConf.create({**base, "extras": False})
    on = OmegaConf.create({**base, "extras": True})
    assert _gif_frames(off) == 0 and _extra(off, "report_whatif_shots", 2) == 0
    assert _gif_frames(on) == 150 and _extra(on, "report_whatif_shots", 2) == 2
    given = OmegaConf.create({"extras": False, "animation_max_frames": 40,
                              "report_whatif_shots": 1})
    assert _gif_frames(given) == 40 and _extra(given, "report_whatif_shots", 2) == 1
    with pytest.raises(ArgumentError, match="animation_max_frames"):
        _gif_frames(OmegaConf.create({"animation_max_frames": -1}))


def test_lookahead_auto_takes_one_worker_for_one_match_on_two_cores_or_more():
    from sportsngen.errors import ArgumentError
    from sportsngen.sim.lookahead import lookahead_workers

    assert lookahead_workers("auto", 1, cores=2) == 1
    assert lookahead_workers("auto", 1, cores=16) == 1
    assert lookahead_workers("auto", 1, cores=1) == 0
    assert lookahead_workers("auto", 4, cores=16) == 0      # several matches: batched instead
    assert lookahead_workers(0, 1) == 0 and lookahead_workers(3, 1) == 3
    assert lookahead_workers(3, 2) == 0
    assert lookahead_workers("auto", 1) in (0, 1)           # this machine's cores
    for bad in ("x", -1, 1.5):
        for n_matches in (1, 2):
            with pytest.raises(ArgumentError, match="lookahead"):
                lookahead_workers(bad, n_matches)
