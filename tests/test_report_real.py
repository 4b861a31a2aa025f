"""Reports and the calibration back-test of recorded slam matches (the shared real data)."""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.report.__main__ import main
from sportsngen.report.backtest import backtest_table, live_predictions, run_backtest
from sportsngen.report.figures import ATTRIBUTION
from sportsngen.report.live import serve_odds, timeline
from sportsngen.report.real import load_recorded_match, score_line

pytestmark = pytest.mark.skipif(slam_dir() is None, reason=SHARED_DATA_MISSING)


def small_folder(tmp_path: Path, event: str, match_ids: list[str]) -> Path:
    """A slam folder holding only `match_ids` of `event` (a user's own folder)."""
    out = tmp_path / "slam"
    out.mkdir(exist_ok=True)
    pts = pd.read_csv(slam_dir() / f"{event}-points.csv", dtype=str, keep_default_na=False)
    pts[pts["match_id"].isin(match_ids)].to_csv(out / f"{event}-points.csv", index=False)
    shutil.copy(slam_dir() / f"{event}-matches.csv", out / f"{event}-matches.csv")
    return out


def test_djokovic_federer_2011_semi_final():
    m = load_recorded_match("2011-usopen-1601")
    assert m.players == ("Novak Djokovic", "Roger Federer") and m.fmt.best_of == 5
    assert len(m.points) == 304 and m.n_glitches == 0 and m.n_after_end == 0
    assert score_line(m) == ("Novak Djokovic v Roger Federer: 6-7(7) 4-6 6-3 6-2 7-5, "
                             "won by Novak Djokovic")
    tl = timeline(m.states, m.winners, serve_odds(*m.players))
    assert tl["p_after"].iat[-1] == 1.0
    # Federer served for the match at 5-3 in the fifth and held two match points (40-15):
    # there P(Djokovic) was at its lowest, then he won the next four points.
    mp = tl[(tl["tag"] == "match point") & (tl["set_no"] == 5) & (tl["games_p1"] == 3)]
    assert mp["point_score"].tolist() == ["15-40", "30-40"]
    assert (mp["winner"] == 0).all()
    assert tl["p_before"].idxmin() == mp.index[0] and tl["p_before"].min() < 0.03


def test_real_command_writes_a_report_quickly(tmp_path, capsys):
    out = tmp_path / "long.html"
    t0 = time.perf_counter()
    assert main(["real", "2011-usopen-1208", "--out", str(out)]) == 0   # 369 points
    assert time.perf_counter() - t0 < 10.0
    html = out.read_text()
    assert ATTRIBUTION in html and "wrote" in capsys.readouterr().out
    doc = json.loads(re.search(r'id="match-data">(.*?)</script>', html, re.S).group(1))
    assert doc["kind"] == "recorded" and doc["rallies"] is None
    assert len(doc["points"]["point"]) == 369
    assert doc["players"] == ["Juan Carlos Ferrero", "Gael Monfils"]


def test_real_command_on_a_user_folder(tmp_path, capsys):
    folder = small_folder(tmp_path, "2011-usopen", ["2011-usopen-1101", "2011-usopen-1108"])
    out = tmp_path / "r.html"
    assert main(["real", "2011-usopen-1108", "--data", str(folder), "--out", str(out)]) == 0
    assert out.exists()
    assert main(["real", "2011-usopen-1999", "--data", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "2011-usopen-1999" in err and "2011-usopen-1101, 2011-usopen-1108" in err
    assert main(["real", "2011-usopen-1108", "--data", str(tmp_path / "none")]) == 2


def test_backtest_on_a_few_matches(tmp_path):
    ids = ["2011-usopen-1101", "2011-usopen-1108", "2011-usopen-1601", "2011-usopen-1208",
           "2011-usopen-1402"]
    folder = small_folder(tmp_path, "2011-usopen", ids)
    preds = live_predictions(folder, progress=False)
    # 1101 ended in a retirement: no outcome decided by play, left out.
    assert preds.attrs["unfinished"] == ["2011-usopen-1101"]
    assert preds["match_id"].nunique() == 4
    assert (preds.groupby("match_id")["p_pre"].nunique() == 1).all()
    table = backtest_table(preds, n_boot=30)
    y = preds["y"].to_numpy()
    assert table.at["50/50", "brier"] == 0.25
    assert table.at["50/50", "ece"] == pytest.approx(abs(y.mean() - 0.5))
    base = preds.groupby("match_id")["y"].first().mean()
    assert table.at["base rate", "brier"] == pytest.approx(np.mean((base - y) ** 2))
    # Live, the error shrinks as the match goes on (whoever was favoured at the start).
    err = (preds["p_live"] - preds["y"]).abs().groupby(preds["match_id"])
    first, last = err.apply(lambda e: e.iloc[:10].mean()), err.apply(lambda e: e.iloc[-10:].mean())
    assert (last < first).all()
    assert (table["ece_lo"] <= table["ece"] + 1e-12).all()
    res = run_backtest(tmp_path / "bt", folder, n_boot=20, progress=False)
    for name in ("backtest.md", "backtest.json", "backtest_reliability.png"):
        assert (tmp_path / "bt" / name).exists()
    assert "| all events | live |" in res["markdown"]
