"""Distributed batch simulation: a season cut into fixed chunks, simulated through Lightning
predict on one process or on DDP (gloo) with two CPU processes, gives the same points table."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import torch

from sportsngen.data.points import POINTS_DTYPES, as_points_table
from sportsngen.sim import Simulator
from sportsngen.sim.distributed import (
    SeasonChunks,
    gather_chunks,
    match_index,
    parse_matchups,
    season_match_id,
    simulate_season,
)
from sportsngen.tennis.scoring import MatchFormat, MatchState

REPO = Path(__file__).resolve().parents[1]
# One no-ad game a match (4-7 points): the chunks, seeds and ids are what is tested, and the
# season is simulated three times (one process, rebuilt without Lightning, two processes).
SHORT = MatchFormat(best_of=1, games_per_set=1, tiebreak_at=1, no_ad=True)
# The untrained tiny model's frames mostly fail the physical limits, and redrawing them is most
# of a rollout's time; what is tested here is the cut into chunks, not the limits.
SIM_KW = {"max_duration_s": 1.2, "max_retries": 0, "physical_limits": False}
PAIRS = [("Toy Alpha", "Toy Beta"), ("Toy Gamma", "Toy Delta"), ("Toy Beta", "Toy Gamma")]
SEED, CHUNK = 5, 2                 # 3 matches -> chunk 0 (matches 0, 1) and chunk 1 (match 2)


@pytest.fixture(scope="module")
def season(tiny_model_file, tmp_path_factory):
    """The 3-match season on one process (in-process Lightning predict)."""
    out = tmp_path_factory.mktemp("season1")
    pts = simulate_season(tiny_model_file, PAIRS, "hard", SHORT, seed=SEED, chunk_size=CHUNK,
                          devices=1, out_dir=out, sim_kwargs=SIM_KW)
    return pts, out


def test_parse_matchups_and_chunks():
    assert parse_matchups("A,B; C , D;") == [("A", "B"), ("C", "D")]
    with pytest.raises(ValueError, match="player1,player2"):
        parse_matchups("A,B;C")
    ds = SeasonChunks([("A", "B")] * 5, chunk_size=2)
    assert ds.n_chunks == 3 and len(ds) == 3
    assert ds[2] == {"chunk": 2, "start": 4, "matchups": [("A", "B")]}
    share = SeasonChunks([("A", "B")] * 5, chunk_size=2, ranks_chunks=range(1, 3, 2))
    assert len(share) == 1 and share[0]["chunk"] == 1 and share[0]["start"] == 2
    with pytest.raises(ValueError, match="chunk_size"):
        SeasonChunks([("A", "B")], chunk_size=0)
    ids = pd.Series([season_match_id(i, "sim-0-0000") for i in (0, 7, 123456)])
    assert ids[1] == "00007:sim-0-0000"
    assert match_index(ids).tolist() == [0, 7, 123456]


def test_season_one_process_is_valid_and_follows_the_chunks(season, tiny_model_file):
    pts, out = season
    assert list(pts.columns) == list(POINTS_DTYPES)
    assert sorted(p.name for p in out.glob("*.parquet")) == [
        "chunk_00000.parquet", "chunk_00001.parquet", "points.parquet"]
    pd.testing.assert_frame_equal(pd.read_parquet(out / "points.parquet").pipe(as_points_table),
                                  pts)
    # Sorted by global match index, then point; every match played to the end of the format.
    assert match_index(pts["match_id"]).is_monotonic_increasing
    assert match_index(pts["match_id"]).unique().tolist() == [0, 1, 2]
    for i, (mid, g) in enumerate(pts.groupby("match_id", sort=False)):
        assert g["point"].tolist() == list(range(1, len(g) + 1))
        assert set(g["server"]) == set(PAIRS[i]) and set(g["winner"]) <= set(PAIRS[i])
        state = MatchState.new(SHORT, first_server=PAIRS[i].index(g["server"].iat[0]))
        for w in g["winner"]:
            assert not state.is_over
            state = state.point_won(PAIRS[i].index(w))
        assert state.is_over, mid
    # Chunk k is one simulate_matches call with seed SEED + k: rebuild it without Lightning.
    sim = Simulator.from_pretrained(tiny_model_file, **SIM_KW)
    for k, lo in ((0, 0), (1, 2)):
        results = sim.simulate_matches(PAIRS[lo:lo + CHUNK], "hard", fmt=SHORT, seed=SEED + k,
                                       progress=False)
        for j, res in enumerate(results):
            mine = pts[match_index(pts["match_id"]) == lo + j].reset_index(drop=True)
            assert mine["match_id"].iat[0] == f"{lo + j:05d}:sim-{SEED + k}-{j:04d}"
            expect = as_points_table(res.points.assign(match_id=mine["match_id"].iat[0]))
            pd.testing.assert_frame_equal(mine, expect, check_exact=True)
    # Stale chunk files beyond the season are ignored by the gather.
    pts.to_parquet(out / "chunk_00002.parquet")
    pd.testing.assert_frame_equal(gather_chunks(out, 2), pts)


def test_other_seed_changes_the_season(season, tiny_model_file, tmp_path):
    pts, _ = season
    before = torch.get_num_threads()
    other = simulate_season(tiny_model_file, PAIRS[2:], "hard", SHORT, seed=SEED + 7,
                            chunk_size=CHUNK, devices=1, out_dir=tmp_path, sim_kwargs=SIM_KW,
                            threads=1)
    assert torch.get_num_threads() == before          # the caller's setting is restored
    mine = pts[match_index(pts["match_id"]) == 2]
    assert other["match_id"].iat[0] == f"00000:sim-{SEED + 7}-0000"
    assert not (len(other) == len(mine) and
                (other["winner"].to_numpy() == mine["winner"].to_numpy()).all()
                and (other["serve_kmh"].to_numpy() == mine["serve_kmh"].to_numpy()).all())


@pytest.mark.skipif(sys.platform == "win32", reason="gloo DDP test on POSIX only")
def test_ddp_two_processes_same_points_table_slow(season, tiny_model_file, tmp_path):
    """SLOW (~10-20 s): the CLI on 2 CPU processes (DDP, gloo, the ranks forked) gives the
    one-process table."""
    pts, _ = season
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    matchups = ";".join(",".join(p) for p in PAIRS)
    cmd = [sys.executable, "-m", "sportsngen.sim.distributed", "--model", str(tiny_model_file),
           "--matchups", matchups, "--surface", "hard", "--matches-per-pair", "1",
           "--seed", str(SEED), "--chunk-size", str(CHUNK), "--devices", "2",
           "--out", str(tmp_path), "--best-of", "1", "--games-per-set", "1",
           "--tiebreak-at", "1", "--no-ad", "--max-duration-s", "1.2", "--max-retries", "0",
           "--no-physical-limits"]
    res = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=240)
    log = res.stdout + res.stderr
    assert res.returncode == 0, log[-3000:]
    assert "distributed_backend=gloo" in log
    assert "All distributed processes registered. Starting with 2 processes" in log
    assert f"3 matches, {len(pts)} points" in res.stdout
    assert (tmp_path / "chunk_00000.parquet").exists()
    assert (tmp_path / "chunk_00001.parquet").exists()
    two = as_points_table(pd.read_parquet(tmp_path / "points.parquet"))
    pd.testing.assert_frame_equal(two, pts, check_exact=True)


def test_season_strategy_forks_only_single_threaded_ranks():
    """A forked child hangs if it starts an OpenMP pool its parent already ran, so ranks are
    forked only at one thread each; more threads re-launch the script."""
    from sportsngen.sim.distributed import season_strategy

    assert season_strategy(1, None) == "auto" and season_strategy(1, 4) == "auto"
    assert season_strategy(2, None) == "ddp_fork" and season_strategy(3, 1) == "ddp_fork"
    assert season_strategy(2, 2) == "ddp"
