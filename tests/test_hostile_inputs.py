"""Hostile but realistic inputs (issue 20): each gives the right result or the library's own
error (`SportsNGENError`, a ValueError) whose message names the argument, or the file, table,
column and row; never a numpy / torch / pyarrow traceback, never a silently wrong table."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from sportsngen.cli.simulate import run_simulation
from sportsngen.data.toy import make_toy_rallies
from sportsngen.data.tracking import FRAME_COLUMNS, RALLY_COLUMNS, SHOT_COLUMNS, RallyData
from sportsngen.errors import ArgumentError, ModelFileError, SportsNGENError, TrackingDataError
from sportsngen.model.export import load_model
from sportsngen.sim import Simulator
from sportsngen.sim.simulator import model_path
from sportsngen.tennis.scoring import MatchFormat, MatchState
from sportsngen.train.datamodule import load_rally_data
from sportsngen.train.run import _check_resume, train_from_config

CONF = str(Path(__file__).resolve().parents[1] / "conf")


@pytest.fixture(scope="module")
def toy() -> RallyData:
    return make_toy_rallies(6, 0)


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator.from_pretrained(max_duration_s=1.0, max_retries=0)


def _tables(toy):
    return toy.frames.copy(), toy.rallies.copy(), toy.shots.copy()


# --- tracking tables ---------------------------------------------------------------------------

def _set(table: str, col: str, values):
    def edit(f, r, s):
        df = {"frames": f, "rallies": r, "shots": s}[table]
        df[col] = df[col].astype(object)
        df[col] = values(df) if callable(values) else values
        return f, r, s
    return edit


def _one(table: str, col: str, row: int, value):
    def edit(f, r, s):
        df = {"frames": f, "rallies": r, "shots": s}[table]
        df[col] = df[col].astype(object)
        df.loc[row, col] = value
        return f, r, s
    return edit


def _receiver_track_missing(f, r, s):
    rec = r.loc[r["rally_id"] == 1, "receiver"].iat[0]
    return f[~((f["rally_id"] == 1) & (f["object"] == rec))], r, s


def _stranger(f, r, s):
    f = f.copy()
    f["object"] = f["object"].astype(object)
    f.loc[(f["rally_id"] == 3) & (f["object"] == "ball"), "object"] = "Umpire"
    return f, r, s


def _one_step_off(f, r, s):
    i = f.index[(f["rally_id"] == 4) & (f["frame"] == 100)]
    f.loc[i, "t"] += 0.5 / 25
    return f, r, s


TABLE_CASES = {
    "in_tiebreak as strings": (_set("rallies", "in_tiebreak", lambda d: d["in_tiebreak"].map(str)),
                               r"rallies: column 'in_tiebreak' must hold booleans.*"
                               r"row 0 holds 'False'"),
    "in_tiebreak None": (_one("rallies", "in_tiebreak", 2, None),
                         r"column 'in_tiebreak' must hold booleans.*row 2 holds None"),
    "rally_id 0.5": (_one("rallies", "rally_id", 3, 0.5),
                     r"rallies: column 'rally_id' must hold integers; row 3 holds 0.5"),
    "point as text": (_one("rallies", "point", 1, "two"),
                      r"column 'point' must hold integers; row 1 holds 'two'"),
    "x as text": (_one("frames", "x", 7, "left"), r"frames: column 'x' must hold numbers; "
                                                  r"row 7 holds 'left'"),
    "t NaN": (_one("frames", "t", 10, np.nan), r"frames row 10 \(rally 0\): t is NaN"),
    "t inf": (_one("frames", "t", 11, np.inf), r"frames row 11 \(rally 0\): t is NaN or inf"),
    "t doubled": (_set("frames", "t", lambda d: d["t"].astype(float) * 2),
                  r"fps is 25, but the t column steps 0.08 s a frame .*12.5 Hz"),
    "one t step off": (_one_step_off, r"\(rally 4, object .*\): t step is not 1/fps = 0.04 s"),
    "duplicated shots row": (lambda f, r, s: (f, r, pd.concat([s, s.iloc[[3]]])),
                             r"shots row 23 \(rally 2\): duplicate shot_index"),
    "shot beyond the last frame": (_one("shots", "frame", 8, 999),
                                   r"shots row 8 \(rally 3\): frame 999 is outside the "
                                   r"rally's frames 0..205"),
    "hitter not in the rally": (_one("shots", "hitter", 9, "Toy Beta"),
                                r"shots row 9 \(rally 3\): hitter is neither"),
    "object neither server, receiver nor ball": (_stranger, r"\(rally 3\): object is neither "
                                                            r"the rally's server"),
    "a player's whole track missing": (_receiver_track_missing,
                                       r"rallies row 1 \(rally 1\): no frames of the receiver"),
    "server is the receiver": (_one("rallies", "receiver", 0, "Toy Gamma"),
                               r"rallies row 0 \(rally 0\): server and receiver are the same"),
    "missing server name": (_one("rallies", "server", 5, None), r"rallies row 5 .*missing server"),
    # (ordering the frames compared the names row by row: a missing one raised a TypeError)
    "missing object name": (_one("frames", "object", 40, None),
                            r"frames row 40 \(rally 0\): missing object"),
    "frames not a table": (lambda f, r, s: ([1, 2], r, s), r"frames must be a pandas DataFrame"),
    "a column twice": (lambda f, r, s: (pd.concat([f, f[["x"]]], axis=1), r, s),
                       r"frames: columns named more than once: \['x'\]"),
    "an extra rallies column twice": (
        lambda f, r, s: (f, pd.concat([r.assign(note=1), r.assign(note=2)[["note"]]], axis=1),
                         s), r"rallies: columns named more than once: \['note'\]"),
}


@pytest.mark.parametrize("case", list(TABLE_CASES))
def test_bad_tracking_tables_are_named(toy, case):
    edit, msg = TABLE_CASES[case]
    f, r, s = edit(*_tables(toy))
    with pytest.raises(TrackingDataError, match=msg):
        RallyData.from_tables(f, r, s, toy.fps)


def test_tables_are_cast_reindexed_and_copied(toy):
    """Columns come out in the schema's dtypes whatever they came in as (object names,
    "str" text, floats holding integers), on a fresh 0..n-1 index, and own their memory: the
    caller's tables edited afterwards change nothing. Extra rallies columns are kept."""
    f, r, s = _tables(toy)
    f = f.astype({"object": object, "frame": float}).set_axis(np.arange(len(f)) * 3 + 7)
    r = r.assign(note=1.5).astype({"server": "str"})
    d = RallyData.from_tables(f, r, s, toy.fps)
    for table, cols in ((d.frames, FRAME_COLUMNS), (d.rallies, RALLY_COLUMNS),
                        (d.shots, SHOT_COLUMNS)):
        assert {c: str(table[c].dtype) for c in cols} == dict(cols)   # "str" is not "string"
    assert list(d.rallies.columns) == list(RALLY_COLUMNS) + ["note"]
    assert d.frames.index.equals(pd.RangeIndex(len(f)))
    assert d.frames["frame"].tolist() == f["frame"].astype(int).tolist()
    x0, server0, note0 = d.frames["x"].iat[0], d.rallies["server"].iat[0], d.rallies["note"].iat[0]
    f.iloc[0, f.columns.get_loc("x")] = 99.0
    r.iloc[0, r.columns.get_loc("server")] = "Somebody Else"
    r.iloc[0, r.columns.get_loc("note")] = -1.0
    assert (d.frames["x"].iat[0], d.rallies["server"].iat[0], d.rallies["note"].iat[0]) == \
        (x0, server0, note0)


def test_one_broken_rally_among_good_ones_is_all_that_repair_drops(toy):
    f, r, s = _tables(toy)
    f.loc[f.index[(f["rally_id"] == 2)][5], "x"] = np.nan
    with pytest.warns(UserWarning, match="repair dropped 1 of 6 rallies"):
        d = RallyData.from_tables(f, r, s, toy.fps, repair=True)
    assert d.meta["repaired"]["dropped_rallies"] == [2]
    assert sorted(d.rallies["rally_id"]) == [0, 1, 3, 4, 5]
    kept = toy.frames[toy.frames["rally_id"] != 2]
    assert len(d.frames) == len(kept) and len(d.shots) == (toy.shots["rally_id"] != 2).sum()


def test_repair_that_would_drop_every_rally_is_an_error(toy):
    f, r, s = _tables(toy)
    f["t"] = f["t"] + np.where(f["frame"] % 7 == 3, 0.5 / 25, 0.0)   # a bad step in every rally
    with pytest.raises(TrackingDataError, match=r"repair would drop every rally \(6\)"):
        RallyData.from_tables(f, r, s, toy.fps, repair=True)


@pytest.mark.parametrize("repair", [False, True])
def test_valid_frames_in_any_row_order_load_whole(toy, tmp_path, repair):
    shuffled = toy.frames.sample(frac=1.0, random_state=7).reset_index(drop=True)
    RallyData(shuffled, toy.rallies.iloc[::-1], toy.shots.sample(frac=1.0, random_state=1),
              toy.fps, dict(toy.meta)).save(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # no repair warning: nothing is dropped
        d = RallyData.load(tmp_path, repair=repair)
    assert "repaired" not in d.meta
    assert sorted(d.rallies["rally_id"]) == sorted(toy.rallies["rally_id"])
    key = ["rally_id", "object", "frame"]
    pd.testing.assert_frame_equal(d.frames.sort_values(key).reset_index(drop=True),
                                  toy.frames.sort_values(key).reset_index(drop=True))


# --- tracking folders ----------------------------------------------------------------------------

FOLDER_CASES = {
    "meta.json broken": ("meta.json", b'{"fps": 25,', r"meta.json is not valid JSON"),
    "fps fast": ("meta.json", b'{"fps": "fast"}',
                 r"meta.json's fps must be a positive number of frames a second, got 'fast'"),
    "meta.json a list": ("meta.json", b"[25]", r"meta.json must hold a JSON object.*got a list"),
    "fps 50 on 25 Hz data": ("meta.json", b'{"fps": 50}',
                             r"meta.json's fps is 50, but the t column steps 0.04 s .*25 Hz"),
    "frames.parquet random bytes": ("frames.parquet", bytes(range(256)) * 8,
                                    r"frames.parquet is not a readable Parquet file"),
    "rallies.parquet empty": ("rallies.parquet", b"",
                              r"rallies.parquet is not a readable Parquet file"),
}


@pytest.mark.parametrize("case", list(FOLDER_CASES))
def test_bad_tracking_folders_name_the_file(toy, tmp_path, case):
    name, content, msg = FOLDER_CASES[case]
    toy.save(tmp_path)
    (tmp_path / name).write_bytes(content)
    with pytest.raises(TrackingDataError, match=msg) as err:
        RallyData.load(tmp_path)
    assert str(tmp_path) in str(err.value)


# --- the simulator ------------------------------------------------------------------------------

FED, NADAL = "Roger Federer", "Rafael Nadal"
POINTS_CASES = {
    "same player twice": (dict(receiver=FED), r"server and receiver must be different players"),
    "surface carpet": (dict(surface="carpet"),
                       r"surface must be one of \['hard', 'clay', 'grass'\], got 'carpet'$"),
    "surface Hard": (dict(surface="Hard"), r"got 'Hard' \(did you mean 'hard'\?\)"),
    "seed None": (dict(seed=None), r"seed must be an integer >= 0, got None"),
    "seed -1": (dict(seed=-1), r"seed must be an integer >= 0, got -1"),
    "n_points 2.5": (dict(n_points=2.5), r"n_points must be an integer in \[1, 100000\], got 2.5"),
    "n_points True": (dict(n_points=True), r"n_points must be an integer .*got True \(bool\)"),
    "n_points '2'": (dict(n_points="2"), r"n_points must be an integer .*got '2' \(str\)"),
    "n_points 10**12": (dict(n_points=10 ** 12), r"n_points must be an integer in \[1, 100000\]"),
    "n_points 0": (dict(n_points=0), r"n_points must be an integer in \[1, 100000\], got 0"),
    "server None": (dict(server=None), r"server must be a non-empty string, got None"),
    "receiver ''": (dict(receiver=""), r"receiver must be a non-empty string"),
    "serve_number 3": (dict(serve_number=3), r"serve_number must be an integer in \[1, 2\]"),
    "top_p 0": (dict(top_p=0.0), r"top_p must be None or a number in \(0, 1\]"),
}


@pytest.mark.parametrize("case", list(POINTS_CASES))
def test_simulate_points_arguments(sim, case):
    kw, msg = POINTS_CASES[case]
    args = {**dict(server=FED, receiver=NADAL, surface="hard", n_points=2, seed=0), **kw}
    with pytest.raises(ArgumentError, match=msg):
        sim.simulate_points(**args)


def test_numpy_integers_are_integers(sim):
    d = sim.simulate_points(FED, NADAL, "grass", np.int64(2), seed=np.int32(1), serve_number=1)
    assert len(d) == 2 and set(d.rallies["surface"]) == {"grass"}
    assert MatchFormat(best_of=np.int64(5), no_ad=np.bool_(True)) == MatchFormat(best_of=5,
                                                                                  no_ad=True)
    assert type(MatchFormat(best_of=np.int64(3)).best_of) is int


MATCH_CASES = {
    "fmt a string": (dict(fmt="best_of_3"), ArgumentError,
                     r"fmt must be a MatchFormat \(or None for best of 3\), got 'best_of_3'"),
    "surface carpet": (dict(surface="carpet"), ArgumentError, r"surface must be one of"),
    "same player twice": (dict(player2=FED), ArgumentError, r"different players"),
    "player None": (dict(player2=None), ArgumentError, r"player2 must be a non-empty string"),
    "seed 1.5": (dict(seed=1.5), ArgumentError, r"seed must be an integer >= 0, got 1.5"),
}


@pytest.mark.parametrize("case", list(MATCH_CASES))
def test_simulate_match_arguments(sim, case):
    kw, err, msg = MATCH_CASES[case]
    args = {**dict(player1=FED, player2=NADAL, surface="hard", seed=0, progress=False), **kw}
    with pytest.raises(err, match=msg):
        sim.simulate_match(**args)


def test_unknown_player_warned_once_per_simulator():
    sim = Simulator.from_pretrained(max_duration_s=0.6, max_retries=0)
    with pytest.warns(UserWarning) as seen:
        sim.simulate_points("Nobody Atall", NADAL, "hard", 3, seed=0)
        sim.simulate_points(NADAL, "Nobody Atall", "hard", 3, seed=1)
        sim.simulate_match("Nobody Atall", NADAL, "hard", seed=0, progress=False,
                           fmt=MatchFormat(best_of=1, games_per_set=1, tiebreak_at=0))
    unknown = [w for w in seen if "unknown player 'Nobody Atall'" in str(w.message)]
    assert len(unknown) == 1
    assert "average (generic) player" in str(unknown[0].message)


def test_rallies_written_are_labelled_with_a_known_surface(sim, tmp_path):
    d = sim.simulate_points(FED, NADAL, "clay", 2, seed=0, serve_number=1)
    d.save(tmp_path)
    assert set(RallyData.load(tmp_path, validate=False).rallies["surface"]) == {"clay"}


@pytest.mark.parametrize("n, msg", [(0, r"got 0"), (-5, r"got -5"), (2.5, r"got 2.5 \(float\)")])
def test_rally_win_probability_n(sim, toy, n, msg):
    with pytest.raises(ArgumentError, match=r"n must be an integer in \[1, 100000\], " + msg):
        sim.rally_win_probability(toy, 2, 30, n=n)


COUNTERFACTUAL_CASES = {
    "bare string": (1, "cross_court", r"options must be a list .*did you mean \['cross_court'\]"),
    "lob": (1, ["lob"], r"option 'lob' is not a direction of a shot; options must be "
                        r"direction names \['cross_court'"),
    "crosscourt": (1, ("crosscourt", "down_the_line"), r"option 'crosscourt' is not"),
    "a serve direction for a rally shot": (1, ["wide"], r"'wide' \(a serve direction\)"),
    "a rally direction for a serve": (0, ["cross_court"], r"not a direction of a serve"),
    "a box of 3 numbers": (1, [(0.0, 5.0, 1.0)], r"option \(0.0, 5.0, 1.0\) is neither"),
    "a box upside down": (1, [(5.0, 0.0, -4.0, 4.0)], r"x_min < x_max"),
    "no options": (1, [], r"options is empty"),
}


@pytest.mark.parametrize("case", list(COUNTERFACTUAL_CASES))
def test_counterfactual_options(sim, toy, case):
    shot, options, msg = COUNTERFACTUAL_CASES[case]
    with pytest.raises(ArgumentError, match=msg):
        sim.counterfactual(toy, 2, shot, options=options, n=2)


# --- scoring ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, msg", [
    (dict(no_ad="no"), r"no_ad must be True or False, got 'no'"),
    (dict(no_ad=1), r"no_ad must be True or False, got 1"),
    (dict(best_of=True), r"best_of must be a positive odd int \(3 or 5\), got True"),
    (dict(best_of=3.0), r"best_of must be .*got 3.0"),
    (dict(games_per_set=np.int64(0)), r"games_per_set must be an int >= 1, got 0"),
])
def test_match_format_refuses_look_alikes(kwargs, msg):
    with pytest.raises(ArgumentError, match=msg):
        MatchFormat(**kwargs)


def test_match_state_needs_a_match_format():
    with pytest.raises(ArgumentError, match=r"fmt must be a MatchFormat .*got 'best_of_3'"):
        MatchState.new("best_of_3")


# --- simulate.py ------------------------------------------------------------------------------

def _simulate_cfg(tmp_path, *overrides):
    with initialize_config_dir(config_dir=CONF, version_base=None):
        return compose("simulate", overrides=[f"output_dir={tmp_path}", *overrides])


@pytest.mark.parametrize("overrides, msg", [
    (["n_matches=1.5"], r"n_matches must be an integer >= 1, got 1.5"),
    (["n_matches=0"], r"n_matches must be an integer >= 1, got 0"),
    (["surface=carpet"], r"surface must be one of \['hard', 'clay', 'grass'\], got 'carpet'"),
    (["surface=carpet", "engine=markov"], r"surface must be one of"),
    (["player2=Roger Federer"], r"player1 and player2 must be different players"),
    (["format.no_ad=no"], r"no_ad must be True or False"),
])
def test_simulate_py_refuses_before_writing(tmp_path, overrides, msg):
    with pytest.raises(ArgumentError, match=msg):
        run_simulation(_simulate_cfg(tmp_path, *overrides))
    assert not (tmp_path / "points.parquet").exists()


# --- model files and training ---------------------------------------------------------------

@pytest.mark.parametrize("content, what", [
    (b"", "the file is empty"),
    (bytes(range(256)) * 4, "corrupt or not a torch file"),
    (json.dumps({"format": "sportsngen-model"}).encode(), "it holds JSON"),
])
def test_model_files_that_are_not_model_files(tmp_path, content, what):
    path = tmp_path / "model.pt"
    path.write_bytes(content)
    for load in (load_model, Simulator.from_pretrained):
        with pytest.raises(ModelFileError, match=f"{path} is not a sportsngen model file: {what}"):
            load(path)


def test_resume_from_a_model_file_says_so():
    with pytest.raises(ModelFileError, match="is a model file, not a training checkpoint"):
        _check_resume(str(model_path()), None, None)


def test_folder_data_without_a_path(tmp_path):
    with pytest.raises(ArgumentError, match=r"data.source=folder needs data.path"):
        load_rally_data({"source": "folder", "path": "???"})
    with initialize_config_dir(config_dir=CONF, version_base=None):
        cfg = compose("train", overrides=["experiment=tiny", "data=folder"])
    with pytest.raises(ArgumentError, match=r"python train.py data=folder data.path="):
        train_from_config(cfg, tmp_path)


def test_every_error_here_is_the_librarys_own():
    for err in (ArgumentError, ModelFileError, TrackingDataError):
        assert issubclass(err, SportsNGENError) and issubclass(err, ValueError)
    assert issubclass(ArgumentError, TypeError)
