"""The realism report (`sportsngen.eval.report`) and its command line (`python -m
sportsngen.eval report`), on small generated tracking."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.tracking import RallyData
from sportsngen.eval.__main__ import main
from sportsngen.eval.physical import METRIC_COLUMNS, collect
from sportsngen.eval.report import load_real_points, write_report
from sportsngen.synth import generate_matches

PAIR = [("Roger Federer", "Rafael Nadal")]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def pair() -> tuple[RallyData, RallyData]:
    return (generate_matches(PAIR, "hard", n_points=30, seed=1, workers=1),
            generate_matches(PAIR, "hard", n_points=30, seed=2, workers=1))


@pytest.fixture(scope="module")
def samples(pair):
    return collect(pair[0]), collect(pair[1])


def _check_outputs(out, labels):
    md = (out / "report.md").read_text()
    for name in ("speeds", "rally_length", "bounce_ratio"):
        png = out / "figures" / f"{name}.png"
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert f"figures/{name}.png" in md
    for label in labels:
        assert label in md
    for head in ("## Realism", "## Physical quantities", "## Bounce speed ratio by surface",
                 "## Serving statistics", "## Rally length"):
        assert head in md
    m = pd.read_csv(out / "metrics.csv", keep_default_na=False, na_values=[""])
    assert tuple(m.columns) == METRIC_COLUMNS
    return md, m


def test_write_report(pair, samples, tmp_path):
    sim, ref = pair
    path = write_report(sim, ref, tmp_path, labels=("model", "truth"), sim_sample=samples[0],
                        ref_sample=samples[1])
    assert path == tmp_path / "report.md"
    md, m = _check_outputs(tmp_path, ("model", "truth"))
    assert set(m["section"]) == {"physical", "bounce", "serve", "rally", "realism"}
    assert set(m["group"]) >= {"all", "Roger Federer", "Rafael Nadal", "hard"}
    assert m["real"].isna().all() and "| real" not in md
    n = m[(m["metric"] == "n_points_counted")].iloc[0]
    assert (n["sim"], n["ref"]) == (30, 30)
    # What the table says is what the samples hold.
    first = m[(m["metric"] == "first_serve_kmh") & (m["group"] == "all")
              & (m["statistic"] == "median")].iloc[0]
    q = samples[0].shots
    assert first["sim"] == pytest.approx(q.loc[q["quantity"] == "first_serve_kmh",
                                               "value"].median())


def test_write_report_real_column(pair, samples, tmp_path):
    sim, ref = pair
    real = ref.points()  # stands in for real points: its column must equal the reference's
    write_report(sim, ref, tmp_path, real_points=real, sim_sample=samples[0],
                 ref_sample=samples[1])
    md, m = _check_outputs(tmp_path, ("simulated", "synthetic truth", "real"))
    serve = m[m["section"].isin(["serve", "rally"]) & (m["statistic"] != "wasserstein")]
    assert np.allclose(serve["real"], serve["ref"], equal_nan=True)
    assert serve["real"].notna().sum() > 50
    toss = m[m["metric"] == "toss_contact_height_m"]
    assert toss["real"].isna().all()
    assert m.loc[m["metric"] == "first_serve_kmh", "real"].notna().any()


def test_write_report_refuses_empty(pair, tmp_path):
    sim, _ = pair
    empty = sim.subset([])
    with pytest.raises(ValueError, match="reference data has no rallies"):
        write_report(sim, empty, tmp_path)


@pytest.mark.skipif(slam_dir() is None, reason=SHARED_DATA_MISSING)
def test_load_real_points_2011():
    pts = load_real_points(["Roger Federer"], 2011)
    assert set(pts["server"]) == {"Roger Federer"}
    assert set(pts["event"]) == {"2011-usopen", "2011-wimbledon"}
    # The shared data README's table: Federer 66.4 % first serves in, 11.1 % aces.
    assert pts["first_serve_in"].mean() == pytest.approx(0.664, abs=0.0005)
    assert pts["ace"].mean() == pytest.approx(0.111, abs=0.0005)
    with pytest.raises(ValueError, match="no slam events of 1999"):
        load_real_points(["Roger Federer"], 1999)


def test_cli_errors(pair, tmp_path, capsys):
    rc = main(["report", "--sim", str(tmp_path / "absent"), "--ref", str(tmp_path),
               "--out", str(tmp_path / "out")])
    assert rc == 2
    assert "no tracking folder at" in capsys.readouterr().err
    pair[0].subset([]).save(tmp_path / "empty")
    rc = main(["report", "--sim", str(tmp_path / "empty"), "--ref-synthetic", "Roger Federer",
               "--out", str(tmp_path / "out")])
    assert rc == 2
    assert "holds no rallies" in capsys.readouterr().err
    (tmp_path / "half").mkdir()
    pair[0].rallies.to_parquet(tmp_path / "half" / "rallies.parquet")
    rc = main(["report", "--sim", str(tmp_path / "half"), "--ref", str(tmp_path / "half"),
               "--out", str(tmp_path / "out")])
    assert rc == 2
    assert "not a RallyData folder" in capsys.readouterr().err


def test_cli_report_from_folders(pair, tmp_path, capsys):
    sim, ref = pair
    sim = sim.subset(sim.rallies["rally_id"][sim.rallies["point"] <= 10])
    sim.rallies["realistic"] = sim.rallies["point"] != 3  # a simulated-looking flag
    sim.save(tmp_path / "sim")
    ref.save(tmp_path / "ref")
    rc = main(["report", "--sim", str(tmp_path / "sim"), "--ref", str(tmp_path / "ref"),
               "--no-real", "--out", str(tmp_path / "out")])
    assert rc == 0, capsys.readouterr().err
    _, m = _check_outputs(tmp_path / "out", ("simulated", "reference"))
    n = m[m["metric"] == "n_points_counted"].iloc[0]
    assert (n["sim"], n["ref"]) == (9, 30)
    share = m[m["metric"] == "non_realistic_share"].iloc[0]
    n_bad = int((sim.rallies["point"] == 3).sum())
    assert share["sim"] == pytest.approx(n_bad / len(sim.rallies))


def test_cli_synthetic_reference(pair, tmp_path, capsys):
    sim = pair[0]
    sim.subset(sim.rallies["rally_id"][sim.rallies["point"] <= 8]).save(tmp_path / "sim")
    rc = main(["report", "--sim", str(tmp_path / "sim"), "--ref-synthetic",
               "Roger Federer, Rafael Nadal", "--no-real", "--out", str(tmp_path / "out")])
    assert rc == 0, capsys.readouterr().err
    _, m = _check_outputs(tmp_path / "out", ("simulated", "synthetic truth"))
    n = m[m["metric"] == "n_points_counted"].iloc[0]
    assert (n["sim"], n["ref"]) == (8, 8)  # the reference defaults to as many points
    rc = main(["report", "--sim", str(tmp_path / "sim"), "--ref-synthetic", "Roger Federer,Nobody",
               "--no-real", "--out", str(tmp_path / "out2")])
    assert rc == 2
    assert "unknown player 'Nobody'" in capsys.readouterr().err
