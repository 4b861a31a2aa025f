"""The studies layer (`sportsngen.studies`): frozen data, a cached variant run, the continuous
held-out evaluation it scores with, and the markdown the studies write."""

import json
import math

import pandas as pd
import pytest
import torch

from sportsngen.studies import ablations, heads
from sportsngen.studies.outcome import OutcomeStudy
from sportsngen.studies.tables import kept_tail, md_table, write_markdown
from sportsngen.studies.top_p import score_rows
from sportsngen.studies.variants import freeze_data, run_variant
from sportsngen.train.datamodule import data_fingerprint, load_rally_data
from sportsngen.train.evaluate import data_config, evaluate_held_out, format_or_na

torch.set_num_threads(1)


def test_markdown_table_and_kept_notes(tmp_path):
    assert md_table(["a", "b", "c"], [["x", "1", "2"]]) == [
        "| a | b | c |", "|---|---:|---:|", "| x | 1 | 2 |"]
    assert md_table(["k", "v"], [], left=0)[1] == "|---:|---:|"
    assert format_or_na(float("nan")) == "n/a" and format_or_na(None) == "n/a"
    assert format_or_na(1.23456) == "1.235" and format_or_na(2.0, ".1f") == "2.0"
    md = tmp_path / "sub" / "t.md"
    assert kept_tail(md, "<!-- notes -->") is None
    write_markdown(md, ["# T", "row"], "\n<!-- notes -->\nmine\n")
    assert md.read_text() == "# T\nrow\n\n<!-- notes -->\nmine\n"
    assert kept_tail(md, "<!-- notes -->") == "<!-- notes -->\nmine\n"


@pytest.fixture(scope="module")
def frozen_toy(tmp_path_factory):
    cfg = {**data_config("toy"), "n_rallies": 16}
    dest = tmp_path_factory.mktemp("studies") / "data"
    assert freeze_data(dest, lambda: load_rally_data(cfg)) == dest
    # A second freeze reuses the folder and never loads.
    assert freeze_data(dest, lambda: pytest.fail("loaded again")) == dest
    return dest


@pytest.fixture(scope="module")
def variant_run(frozen_toy):
    out_dir = frozen_toy.parent / "run"
    ov = ["experiment=tiny", "data=toy", "data.source=folder", f"+data.path={frozen_toy}",
          "threads=1", "seed=0", "trainer.max_steps=2", "trainer.val_check_interval=2",
          "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
          "events.enabled=false"]
    res = run_variant(out_dir, ov, {"variant": "v", "note": "", "seed": 0, "steps": 2},
                      lambda path: heads.evaluate(path, 16, [frozen_toy]))
    return out_dir, res


def test_run_variant_trains_scores_and_caches(variant_run):
    out_dir, res = variant_run
    assert list(res)[:7] == ["variant", "note", "seed", "steps", "train_wall_s", "n_params",
                             "overrides"]
    assert res["n_params"] > 0 and res["overrides"][0] == "experiment=tiny"
    assert json.loads((out_dir / "result.json").read_text()) == json.loads(json.dumps(res))
    # A result on file is returned as it is: no training, no evaluation.
    again = run_variant(out_dir, [], {"variant": "v"}, lambda path: pytest.fail("evaluated"))
    assert again == json.loads(json.dumps(res))


def test_continuous_evaluation_adds_to_the_discrete_one(variant_run, frozen_toy):
    out_dir, res = variant_run
    plain = evaluate_held_out(out_dir / "model.pt", {"source": "folder",
                                                      "path": str(frozen_toy)}, batch_size=16)
    for k, v in plain.items():       # the same tokens, the same discrete figures
        assert res[k] == v or (isinstance(v, float) and math.isnan(v) and math.isnan(res[k]))
    assert res["data_fingerprint"] == data_fingerprint(load_rally_data(
        {"source": "folder", "path": str(frozen_toy)}))
    for part in ("player", "ball", "ball_flight"):
        assert math.isfinite(res[f"cont_nll_{part}"]) and 0.0 <= res[f"oor_{part}"] <= 1.0
        assert math.isfinite(res[f"cv_cont_nll_{part}"])
    # Bins are narrower than a metre, so the log volume (floor) is negative.
    assert res["cont_nll_ball"] < res["nll_ball"] and res["cont_nll_player"] < res["nll_player"]
    lines = heads.table([res])
    assert len(lines) == 3 and lines[2].count(" | ") == 17
    assert lines[2].startswith("| v | 0 | ") and f"{res['n_params']:,}" in lines[2]


def test_heads_finds_moved_training_data(frozen_toy, tmp_path):
    fp = data_fingerprint(load_rally_data({"source": "folder", "path": str(frozen_toy)}))
    split = {"fingerprint": fp, "data": {"source": "folder", "path": str(tmp_path / "gone")}}
    assert heads.training_data_config(split, [tmp_path, frozen_toy]) == {
        "source": "folder", "path": str(frozen_toy)}
    with pytest.raises(RuntimeError, match="training fingerprint"):
        heads.training_data_config({**split, "fingerprint": "other"}, [frozen_toy])


def test_ablation_table_means_seeds_and_pairs_differences():
    def r(name, seed, ball, player):
        return {"name": name, "seed": seed, "nll_ball": ball, "nll_ball_flight": ball,
                "nll_ball_contact": math.nan, "nll_player": player, "acc_ball": 0.5,
                "acc_player": 0.25, "train_wall_s": 10.0, "n_params": 1234}

    results = [r("default", 0, 1.0, 2.0), r("no_time", 0, 1.5, 1.9),
               r("default", 1, 1.2, 2.0), r("no_time", 1, 1.3, 2.1)]
    lines = ablations.table(results)
    assert lines[1] == "|---|" + "---:|" * 10
    assert lines[3] == ("| no_time (elapsed-time feature) | 1.400 | 1.400 | n/a | 2.000 | "
                        "0.500 | 0.250 | +0.300 | +0.000 | 1,234 | 10 |")
    assert lines[2].startswith("| default (") and " |  |  | 1,234 |" in lines[2]
    assert ablations.per_seed_lines(results) == [
        "- no_time: ball +0.500, +0.100 (worse on every seed); player -0.100, +0.100 (mixed)"]


def test_top_p_score_sums_realism_distances_and_serve_gaps():
    cmp = pd.DataFrame([
        ("all", "wasserstein", "speed", float("nan"), 2.0),
        ("all", "iqr", "speed", 1.0, 4.0),
        ("all", "value", "ace", 0.10, 0.05),
        ("hard", "value", "ace", 0.9, 0.0)],            # another group: ignored
        columns=["group", "statistic", "metric", "sim", "ref"])
    row = score_rows(cmp, 0.2)
    assert row["w_speed"] == 0.5 and row["d_ace"] == pytest.approx(0.05)
    assert row["score"] == pytest.approx(0.2 + 0.5 + 0.05)


def test_outcome_options_refuse_inconsistent_flags(tmp_path):
    with pytest.raises(ValueError, match="--workers"):
        OutcomeStudy(workers=0)
    with pytest.raises(ValueError, match="--kernel-n 0"):
        OutcomeStudy(from_points=[tmp_path / "a.csv", tmp_path / "b.csv"])
    assert OutcomeStudy(from_points=[tmp_path / "a.csv"] * 2, kernel_n=0).kernel_n == 0
