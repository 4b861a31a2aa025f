"""Reports of learned-engine matches (a tiny model), and the report in a real browser
(headless Chromium; skipped where none is on the PATH)."""

from __future__ import annotations

import json
import re

import pandas as pd
import pytest

from sportsngen.report.browser import assert_clean, check_report, find_chromium
from sportsngen.report.document import write_report
from sportsngen.report.simulated import (
    _rallies_of_point,
    learned_match_document,
    simulated_timeline,
    whatif_entries,
)
from sportsngen.tennis.scoring import MatchFormat
from tests.conftest import tiny_sim

SHORT = MatchFormat(best_of=1, games_per_set=2, tiebreak_at=1, no_ad=True)
NO_CHROMIUM = "no Chromium on the PATH (Debian: apt-get install chromium)"


class FakeSim:
    """Fixed counterfactual answers: the browser test checks drawing, not the model."""

    def counterfactual(self, rallies, rally_id, shot_index, options, n, seed):
        return pd.DataFrame({"option": list(options), "win_probability": [0.62, 0.35],
                             "ci_low": [0.4, 0.16], "ci_high": [0.8, 0.59], "n": [n, n],
                             "n_sims": [n, n], "n_unrealistic": [0, 0],
                             "n_forced_failed": [0, 0]})


@pytest.fixture(scope="module")
def tiny_match(tiny_model_file):
    sim = tiny_sim(tiny_model_file, max_duration_s=1.2)
    res = sim.simulate_match("Toy Alpha", "Toy Beta", "hard", fmt=SHORT, seed=0,
                             progress=False)
    odds, tl = simulated_timeline(res.points, res.players, SHORT)
    by_point = _rallies_of_point(res.rallies.rallies)
    # A what-if on the last shot of the deciding rally of the biggest swing with a shot.
    shots = res.rallies.shots
    for i in tl["swing"].abs().sort_values(ascending=False, kind="stable").index:
        rid = by_point[int(tl["point"].iat[i])][-1]
        mine = shots[shots["rally_id"] == rid]
        if len(mine):
            chosen = [(int(i), rid, int(mine["shot_index"].max()))]
            break
    whatif = whatif_entries(FakeSim(), res.rallies, tl, res.players, chosen, n=12,
                            progress=False)
    return res, learned_match_document(res, odds, tl, whatif, "tiny")


def test_learned_document_has_every_points_rallies(tiny_match):
    res, doc = tiny_match
    assert len(doc["points"]["point"]) == len(res.points)
    rallies, winners = doc["rallies"], doc["points"]["winner"]
    for i, ids in enumerate(doc["points"]["rallies"]):
        assert ids, f"point {i + 1} has no rally"
        last = rallies[str(ids[-1])]
        assert last["point"] == i + 1
        # The rally that decided the point was won by the point's winner (or by fiat).
        assert last["winner"] in (winners[i], -1)
        assert all(rallies[str(r)]["end_reason"] == "fault" for r in ids[:-1])
    assert set(map(int, rallies)) == set(res.rallies.rallies["rally_id"])
    w = doc["whatif"][0]
    assert [o["option"] for o in w["options"]] == ["cross_court", "down_the_line"]
    assert "tiny" in doc["notes"][0]


@pytest.mark.skipif(find_chromium() is None, reason=NO_CHROMIUM)
def test_report_in_headless_chromium(tiny_match, tmp_path):
    _, doc = tiny_match
    path = write_report(doc, tmp_path / "report.html")
    seen = check_report(path, tmp_path / "shots")
    assert_clean(seen)                 # no JavaScript error, no network request, it plays
    assert seen["has_rallies"] and seen["animated"] and seen["has_whatif"]
    assert seen["whatif_bars"] == 4    # two options, point and match charts
    assert seen["selected_point"] == doc["key_moments"][0]["i"]
    for name in ("timeline", "rally", "whatif", "page"):
        assert (tmp_path / "shots" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    assert seen["seconds"] < 30


@pytest.mark.skipif(find_chromium() is None, reason=NO_CHROMIUM)
def test_browser_check_catches_a_broken_page(tmp_path):
    page = tmp_path / "bad.html"
    page.write_text('<html><body><script type="application/json" id="match-data">{}</script>'
                    '<script>console.error("boom"); undefinedFunction();</script>'
                    '<img src="http://example.invalid/x.png"></body></html>')
    seen = check_report(page)
    with pytest.raises(AssertionError) as err:
        assert_clean(seen)
    text = str(err.value)
    assert "boom" in text and "undefinedFunction" in text and "example.invalid" in text
    assert json.dumps(seen)        # plain data, printable by the command
    assert re.search(r"network request: http://example\.invalid", text)
