"""The match report: serve odds, the live timeline, key moments, the HTML document, rallies
and what-if records (no real data, no browser: see test_report_real / test_report_browser)."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from sportsngen.baselines.markov import match_win_probability, point_importance
from sportsngen.baselines.serve_model import (
    pooled_serve_model,
    serve_model,
    serve_model_or_pooled,
    simulate_match_points,
)
from sportsngen.data.points import as_points_table
from sportsngen.data.toy import make_toy_rallies
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.report.figures import ATTRIBUTION, real_2011_figures
from sportsngen.report.live import key_moments, replay_states, serve_odds, timeline
from sportsngen.report.rallies import rally_payload
from sportsngen.report.simulated import (
    choose_whatif_shots,
    learned_match_report,
    markov_match_report,
    whatif_entries,
)
from sportsngen.tennis.scoring import MatchFormat, MatchState

NAMES = ("Roger Federer", "Rafael Nadal")
BO3 = MatchFormat()


def embedded_doc(html: str) -> dict:
    m = re.search(r'<script type="application/json" id="match-data">(.*?)</script>', html, re.S)
    assert m is not None
    return json.loads(m.group(1))


@pytest.fixture(scope="module")
def markov_match():
    return simulate_match_points(serve_model(NAMES[0]), serve_model(NAMES[1]), names=NAMES,
                                 fmt=BO3, seed=4, first_server=1)


# --- serve odds ---------------------------------------------------------------------------

def test_serve_odds_own_figures_and_pooled():
    fed, nad = serve_model(NAMES[0]), serve_model(NAMES[1])
    odds = serve_odds(*NAMES)
    assert odds.own_figures == (True, True)
    assert odds.p_serve[0] == pytest.approx(fed.adjusted_against(nad).serve_points_won)
    assert odds.p_serve[1] == pytest.approx(nad.adjusted_against(fed).serve_points_won)
    pooled, own = serve_model_or_pooled("Nobody Atall")
    assert not own and np.isnan(pooled.return_won)
    unknown = serve_odds("Nobody Atall", NAMES[1])
    assert unknown.own_figures == (False, True)
    # The pooled player's return rate is unknown, so he adjusts nobody; Nadal adjusts him.
    assert unknown.p_serve[1] == pytest.approx(nad.serve_points_won)
    assert unknown.p_serve[0] == pytest.approx(pooled.adjusted_against(nad).serve_points_won)
    women = serve_odds("Nobody A", "Nobody B", gender="women")
    assert women.p_serve[0] == women.p_serve[1] < unknown.p_serve[0]
    assert "pooled" in unknown.describe(("X", NAMES[1]))
    with pytest.raises(ValueError, match="gender must be one of"):
        serve_odds("Nobody A", "Nobody B", gender="mixed")


def test_pooled_serve_model_pools_every_server():
    rows = []
    for k, (server, won, first_in) in enumerate([("A", True, True), ("A", False, False),
                                                 ("B", True, True), ("B", True, False),
                                                 ("B", False, True)]):
        rows.append({"match_id": "m", "point": k + 1, "server": server,
                     "receiver": "B" if server == "A" else "A",
                     "winner": server if won else ("B" if server == "A" else "A"),
                     "surface": "hard", "event": "", "serve_number": 1 if first_in else 2,
                     "first_serve_in": first_in, "ace": False, "double_fault": False,
                     "serve_kmh": np.nan, "rally": 3, "set_no": 1, "server_games": 0,
                     "receiver_games": 0, "server_score": "0", "receiver_score": "0"})
    m = pooled_serve_model(as_points_table(pd.DataFrame(rows)))
    assert m.first_serve_in == pytest.approx(3 / 5)
    assert m.first_serve_won == pytest.approx(2 / 3) and m.second_serve_won == 0.5
    assert m.serve_points_won == pytest.approx(3 / 5)
    assert np.isnan(m.return_won) and m.tour_return_won == pytest.approx(2 / 5)


# --- timeline -----------------------------------------------------------------------------

def test_timeline_chains_and_agrees_with_the_markov_model(markov_match):
    points, final = markov_match
    states = replay_states(points, BO3, NAMES)
    assert len(states) == len(points) and states[0].server == 1
    odds = serve_odds(*NAMES)
    tl = timeline(states, [NAMES.index(w) for w in points["winner"]], odds)
    assert np.allclose(tl["p_after"].to_numpy()[:-1], tl["p_before"].to_numpy()[1:], atol=1e-12)
    assert tl["p_after"].iat[-1] == float(final.winner == 0)
    assert tl["p_before"].iat[0] == pytest.approx(
        match_win_probability(*odds.p_serve, state=MatchState.new(BO3, first_server=1)))
    for i in (0, 40, len(tl) - 1):
        assert tl["importance"].iat[i] == pytest.approx(
            point_importance(*odds.p_serve, states[i]), abs=1e-12)
    assert (tl["importance"] >= 0).all()
    assert np.allclose(tl["swing"], tl["p_after"] - tl["p_before"])
    # The last point of a match is a match point; set and game starts are counted right.
    assert tl["tag"].iat[-1] == "match point"
    assert int(tl["new_set"].sum()) == len(final.sets)
    assert int(tl["new_game"].sum()) == sum(a + b for a, b in final.sets)


def test_key_moments_are_the_largest_swings_in_match_order():
    tl = pd.DataFrame({"swing": [0.1, -0.5, 0.2, 0.5, 0.0]})
    assert key_moments(tl, 2) == [1, 3]
    assert key_moments(tl, 3) == [1, 2, 3]
    assert key_moments(tl, 0) == []
    with pytest.raises(ValueError):
        key_moments(tl, -1)


def test_replay_states_names_the_bad_row(markov_match):
    points, _ = markov_match
    bad = points.copy()
    bad.loc[5, ["server", "receiver"]] = bad.loc[5, ["receiver", "server"]].to_numpy()
    with pytest.raises(ValueError, match="points row 5: server"):
        replay_states(bad, BO3, NAMES)
    with pytest.raises(ValueError, match="neither of"):
        replay_states(points, BO3, ("Somebody", "Else"))
    with pytest.raises(ValueError, match="0 .player 1. or 1"):
        timeline(replay_states(points, BO3, NAMES)[:2], [0, 2], serve_odds(*NAMES))


# --- the HTML document --------------------------------------------------------------------

def test_markov_report_is_one_self_contained_file(tmp_path, markov_match):
    points, final = markov_match
    path = markov_match_report(points, NAMES, BO3, "a line", "hard", tmp_path / "r.html")
    html = path.read_text()
    # Nothing to fetch: no external script, stylesheet, image, font or import.
    assert not re.search(r"<(script|link|img)[^>]+(src|href)=", html)
    assert "@import" not in html and "url(" not in html
    assert not re.search(r"""["'(]https?://(?!www\.w3\.org/2000/svg)""", html)
    doc = embedded_doc(html)
    assert doc["players"] == list(NAMES) and doc["rallies"] is None and doc["whatif"] == []
    assert len(doc["points"]["point"]) == len(points) and len(doc["key_moments"]) == 6
    won = int((points["winner"] == NAMES[0]).sum())
    assert doc["stats"]["match"][NAMES[0]]["points_won"] == won
    # Federer's 2011 figures are the generator's targets (first serve in 66.44 %).
    assert doc["stats"]["real2011"][NAMES[0]]["first_serve_in"] == pytest.approx(0.6644)
    assert ATTRIBUTION in doc["stats"]["real_source"]
    assert path.stat().st_size < 200_000


def test_report_survives_hostile_names(tmp_path, markov_match):
    points, _ = markov_match
    names = ('A </script><script>alert(1)</script>', 'B "q" & <b>')
    renamed = points.replace({NAMES[0]: names[0], NAMES[1]: names[1]})
    html = markov_match_report(renamed, names, BO3, "x", "hard", tmp_path / "r.html").read_text()
    assert html.count("</script>") == 2          # the data block's and the script's own
    assert embedded_doc(html)["players"] == list(names)
    assert "<title>A &lt;/script&gt;" in html


def test_real_2011_figures_from_the_serve_models_when_not_a_target():
    f = real_2011_figures("Alex Bogomolov Jr.")     # in the serve models, not the targets
    m = serve_model("Alex Bogomolov Jr.")
    assert f["first_serve_in"] == m.first_serve_in
    assert f["double_fault"] == pytest.approx((1 - m.first_serve_in) * m.double_fault)
    assert f["serve_points_won"] == pytest.approx(m.serve_points_won)
    assert real_2011_figures("Nobody Atall") is None


# --- rallies and what-if ------------------------------------------------------------------

def test_rally_payload_of_toy_rallies():
    data = make_toy_rallies(6, seed=2)
    r0 = data.rallies.iloc[0]
    players = (str(r0["receiver"]), str(r0["server"]))     # player 1 is the receiver here
    pair = data.rallies["server"].isin(players) & data.rallies["receiver"].isin(players)
    data = data.subset(data.rallies.loc[pair, "rally_id"].tolist())
    pay = rally_payload(data, players)
    rid = int(r0["rally_id"])
    r = pay[str(rid)]
    f = data.frames[data.frames["rally_id"] == rid].sort_values("frame")
    ball = f[f["object"] == "ball"]
    assert r["n"] == len(ball) and len(r["ball"]) == 3 * r["n"] and len(r["p"][1]) == 2 * r["n"]
    assert r["ball"][:3] == [round(100 * ball[c].iat[0]) for c in ("x", "y", "z")]
    srv = f[f["object"] == players[1]]
    assert r["p"][1][:2] == [round(100 * srv["x"].iat[0]), round(100 * srv["y"].iat[0])]
    assert r["server"] == 1
    shots = data.shots[data.shots["rally_id"] == rid]
    assert [s["stroke"] for s in r["shots"]] == shots.sort_values("shot_index")["stroke"].tolist()
    rules = analyse_rally_data(data.subset([rid]))
    assert [b[0] + r["f0"] for b in r["bounces"]] == rules.at[rid, "bounce_frames"]
    with pytest.raises(ValueError, match="neither the ball nor"):
        rally_payload(data, (players[0], "Somebody"))


class FakeSim:
    """Stands in for `Simulator.counterfactual` with fixed answers."""

    def __init__(self):
        self.calls = []

    def counterfactual(self, rallies, rally_id, shot_index, options, n, seed):
        self.calls.append((rally_id, shot_index, tuple(options), n))
        return pd.DataFrame({"option": list(options), "win_probability": [0.6, 0.25],
                             "ci_low": [0.4, 0.1], "ci_high": [0.8, 0.45], "n": [n - 1, n],
                             "n_sims": [n, n], "n_unrealistic": [1, 0],
                             "n_forced_failed": [0, 0]})


def test_whatif_shots_chosen_by_swing_and_mapped_to_the_match():
    tl = pd.DataFrame({"point": [1, 2, 3, 4], "swing": [0.05, -0.3, 0.2, 0.25],
                       "p_if_won": [0.6, 0.7, 0.55, 0.9], "p_if_lost": [0.5, 0.3, 0.4, 0.6]})
    by_point = {1: [10], 2: [20, 21], 3: [30], 4: [40]}
    shots = pd.DataFrame({
        "rally_id": [10, 10, 21, 21, 21, 21, 30, 30, 40],
        "shot_index": [0, 1, 0, 1, 2, 3, 0, 1, 0],
        "stroke": ["serve", "forehand", "serve", "backhand", "forehand", "forehand_volley",
                   "serve", "backhand", "serve"],
        "hitter": ["A", "B", "A", "B", "A", "B", "B", "A", "A"],
        "direction": "cross_court",
        "outcome": ["in_play", "error", "in_play", "in_play", "in_play", "winner", "in_play",
                    "error", "in_play"]})
    # Point 2 (swing 0.3) then point 4 (0.25: a serve only, skipped) then point 3. In point 2
    # the last groundstroke that stayed in play; in point 3 the only one (an error).
    chosen = choose_whatif_shots(by_point, shots, tl, 2)
    assert chosen == [(1, 21, 2), (2, 30, 1)]
    shots.loc[4, "outcome"] = "error"
    assert choose_whatif_shots(by_point, shots, tl, 1) == [(1, 21, 1)]
    shots.loc[4, "outcome"] = "in_play"
    sim = FakeSim()
    rallies = type("R", (), {"shots": shots})()
    out = whatif_entries(sim, rallies, tl, ("A", "B"), chosen, n=20, progress=False)
    assert sim.calls == [(21, 2, ("cross_court", "down_the_line"), 20),
                         (30, 1, ("cross_court", "down_the_line"), 20)]
    # Point 2, hitter A (player 1): match 0.3 if he loses the point, 0.7 if he wins it.
    o = out[0]["options"][0]
    assert (out[0]["match_if_lost"], out[0]["match_if_won"]) == (0.3, 0.7)
    assert o["match_p"] == pytest.approx(0.3 + 0.6 * 0.4)
    assert (o["match_lo"], o["match_hi"]) == (pytest.approx(0.46), pytest.approx(0.62))
    # Point 3 again hitter A; a hitter who is player 2 sees 1 - P(player 1).
    out_b = whatif_entries(sim, rallies, tl, ("B", "A"), chosen[1:], n=20, progress=False)[0]
    assert (out_b["match_if_lost"], out_b["match_if_won"]) == (pytest.approx(0.45),
                                                               pytest.approx(0.6))


def test_a_whatif_that_cannot_branch_is_skipped_not_fatal():
    class Refuses(FakeSim):
        def counterfactual(self, rallies, rally_id, shot_index, options, n, seed):
            if rally_id == 21:
                raise ValueError("the shot is struck too early in the track to branch before it")
            return super().counterfactual(rallies, rally_id, shot_index, options, n, seed)

    tl = pd.DataFrame({"point": [1, 2], "swing": [0.1, 0.2], "p_if_won": [0.6, 0.7],
                       "p_if_lost": [0.5, 0.3]})
    shots = pd.DataFrame({"rally_id": [21, 30], "shot_index": [1, 1],
                          "stroke": ["forehand", "backhand"], "hitter": ["A", "B"],
                          "direction": "middle", "outcome": "in_play"})
    rallies = type("R", (), {"shots": shots})()
    out = whatif_entries(Refuses(), rallies, tl, ("A", "B"), [(0, 21, 1), (1, 30, 1)], n=8,
                         progress=False)
    assert [w["rally"] for w in out] == [30]
    with pytest.raises(ValueError, match="whatif_rollouts >= 1"):
        learned_match_report(None, "x.html", sim=FakeSim(), whatif_shots=2, whatif_rollouts=0)
