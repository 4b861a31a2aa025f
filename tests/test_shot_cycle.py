"""Shot-cycle behaviour model: shot table, KDEs and rejection rule, marginalisation order,
opponent-specific models, and the simulator (valid RallyData, plausible serving, determinism)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from sportsngen.baselines.shot_cycle import (
    MARGINALISATION_ORDER,
    RALLY_LEVELS,
    SERVE_LEVELS,
    fit_from_table,
    fit_shot_cycle,
)
from sportsngen.baselines.shot_cycle_kde import fit_kde, loo_log_likelihood
from sportsngen.baselines.shot_cycle_sim import simulate_points
from sportsngen.baselines.shot_cycle_table import (
    NO_REGION,
    NO_SPEED_BIN,
    bounce_region,
    infer_handedness,
    region,
    shot_table,
    speed_bin,
)
from sportsngen.data.tracking import END_REASONS, RallyData
from sportsngen.eval.stats import serve_stats
from sportsngen.eval.style_graph import build_style_graph, shot_cycles, similarity
from sportsngen.synth.generate import generate_matches
from sportsngen.tennis.court import is_in_singles

FED, NADAL = "Roger Federer", "Rafael Nadal"


@pytest.fixture(scope="module")
def data() -> RallyData:
    return generate_matches([(FED, NADAL)], "hard", n_points=150, seed=3, workers=1)


@pytest.fixture(scope="module")
def model(data):
    return fit_shot_cycle(data)


# -- the shot table -------------------------------------------------------------------------------

def test_regions_and_speed_bins_exact():
    # hitter's frame: baseline at -x, deuce (his right) is y < 0; centre third |y| <= 1.372 m
    assert region(-12.0, -3.0) == 3 and region(-12.0, 0.0) == 4 and region(-12.0, 2.0) == 5
    assert region(-5.0, -3.0) == 0 and region(-9.0, 1.0) == 1   # 9.0 < 9.1425: front
    assert region(np.nan, 0.0) == NO_REGION
    assert bounce_region(6.5, 0.0) == 4 and bounce_region(6.3, 0.0) == 1  # service line 6.40
    assert list(speed_bin([0.5, 1.0, 2.49, 2.5, 5.0, 9.0, np.nan])) == [0, 1, 1, 2, 3, 4,
                                                                      NO_SPEED_BIN]


def test_shot_table_frames_and_invariants(data):
    t = shot_table(data)
    assert len(t) == len(data.shots)
    assert (t["own_x"] < 0).all()                    # everyone at -x in his own frame
    serves = t[t["is_serve"]]
    assert (serves["in_start_region"] == NO_REGION).all()
    assert (serves["speed_bin"] == NO_SPEED_BIN).all()
    rally = t[~t["is_serve"] & (t["result"] == "in")]
    assert is_in_singles(rally["place_x"].to_numpy(), rally["place_y"].to_numpy(), 1).all()
    # the incoming bounce is the previous shot's placement seen from the other end
    prev = t.shift(1)
    same = (t["rally_id"] == prev["rally_id"]) & np.isfinite(prev["place_x"])
    expect = bounce_region(-prev.loc[same, "place_x"], -prev.loc[same, "place_y"])
    assert (t.loc[same, "in_bounce_region"].to_numpy() == expect).all()
    # recovery of a shot = the hitter's position at the opponent's next contact = the
    # opponent's view of him (opp_x flipped back) on the next row
    nxt = t.shift(-1)
    has = t["rally_id"] == nxt["rally_id"]
    np.testing.assert_allclose(t.loc[has, "recovery_x"], nxt.loc[has, "opp_x"])
    assert infer_handedness(t) == {FED: "right", NADAL: "left"}


# -- KDE: leave-one-out bandwidth, rejection rule, mode --------------------------------------------

def test_loo_log_likelihood_matches_brute_force():
    pts = np.random.default_rng(0).normal(size=(20, 1))
    base = np.cov(pts, rowvar=False).reshape(1, 1)
    f = 0.4
    sd = f * math.sqrt(base[0, 0])
    brute = np.mean([math.log(np.mean(norm.pdf(pts[i, 0], np.delete(pts[:, 0], i), sd)))
                     for i in range(20)])
    assert loo_log_likelihood(pts, base, np.array([f]))[0] == pytest.approx(brute, rel=1e-9)


def test_loo_bandwidth_is_sensible():
    rng = np.random.default_rng(1)
    one = fit_kde(rng.normal(size=400))
    # Normal data: the LOO optimum sits near the normal-reference factor 400^(-1/5) = 0.30.
    assert 0.15 <= one.factor <= 0.6
    two = fit_kde(np.r_[rng.normal(-4, 0.3, 200), rng.normal(4, 0.3, 200)])
    assert two.factor < 0.15   # two tight clusters far apart need a much narrower kernel


def test_rejection_rule_truncates_below_a_tenth_of_peak():
    kde = fit_kde(np.array([[2.0]]), min_std=0.5)   # one point: a plain Gaussian
    sd = math.sqrt(kde.cov[0, 0])
    assert kde.peak == pytest.approx(1.0 / (math.sqrt(2 * math.pi) * sd))
    x = kde.sample(np.random.default_rng(2), 20000)[:, 0]
    assert (kde.pdf(x) >= 0.1 * kde.peak - 1e-12).all()
    a = math.sqrt(2.0 * math.log(10.0))          # density = peak / 10 at |z| = 2.146
    z = (x - 2.0) / sd
    assert np.abs(z).max() <= a + 1e-9
    truncated_var = 1.0 - 2.0 * a * norm.pdf(a) / (2.0 * norm.cdf(a) - 1.0)
    assert np.var(z) == pytest.approx(truncated_var, rel=0.03)
    plain = kde.sample(np.random.default_rng(2), 20000, reject_below=0.0)[:, 0]
    share_below = np.mean(np.abs((plain - 2.0) / sd) > a)   # 3.2 % of an untruncated normal
    assert share_below == pytest.approx(2.0 * norm.sf(a), abs=0.005)


def test_sample_conditioned_on_centres_and_acceptance():
    pts = np.array([[0.0, 0.0]] * 5 + [[10.0, 0.0]] * 5)
    kde = fit_kde(pts, min_std=0.5)
    x = kde.sample(np.random.default_rng(3), 500, centres=pts[:, 0] > 5,
                   accept=lambda d: d[:, 1] > 0)
    assert (x[:, 0] > 5).all() and (x[:, 1] > 0).all()


def test_mode_finds_the_bigger_cluster():
    rng = np.random.default_rng(4)
    pts = np.r_[rng.normal([-13, 0], 0.3, (60, 2)), rng.normal([-3, 1], 0.3, (20, 2))]
    np.testing.assert_allclose(fit_kde(pts, 0.1).mode(), [-13, 0], atol=0.2)


# -- marginalisation and opponent-specific models ----------------------------------------------

def _row(**kw) -> dict:
    row = {"hitter": "A", "opponent": "B", "is_serve": False, "serve_number": 1,
           "side": "deuce", "shot_type": "forehand/topspin", "stroke": "forehand",
           "spin": "topspin", "own_region": 4, "opp_region": 4, "in_start_region": 4,
           "in_bounce_region": 1, "speed_bin": 2, "speed_mps": 25.0, "place_x": 9.0,
           "place_y": 0.0, "result": "in", "error_kind": "none", "recovery_x": -13.0,
           "recovery_y": 0.0, "net_approach": 0.0, "contact_y": -0.5, "own_y": 0.0}
    row.update(kw)
    return row


def test_marginalisation_order_on_hand_built_data():
    assert MARGINALISATION_ORDER[:4] == ("speed_bin", "in_bounce_region", "in_start_region",
                                         "opp_region")
    assert RALLY_LEVELS[1] == ("own_region", "opp_region", "in_start_region",
                               "in_bounce_region")
    assert RALLY_LEVELS[-1] == () and SERVE_LEVELS[-1] == ()
    rows = [_row(speed_bin=2)] * 2                       # the full state: 2 examples
    rows += [_row(in_bounce_region=3, speed_bin=0)]      # level 1 = 2, level 2 = 3
    rows += [_row(in_start_region=3)] * 5                # would win if start went first
    rows += [_row(opp_region=3, in_start_region=5)] * 4  # own region 4: level 4 = 12
    rows += [_row(own_region=5, opp_region=1, shot_type="backhand/slice",
                  stroke="backhand")] * 20
    pm = fit_from_table(pd.DataFrame(rows), min_examples=3).player_model("A")
    state = {"own_region": 4, "opp_region": 4, "in_start_region": 4, "in_bounce_region": 1,
             "speed_bin": 2}
    lvl, got = pm.lookup("rally", state)
    assert lvl == 2 and len(got) == 3
    assert (pm.table.loc[got, "in_start_region"] == 4).all()
    lvl, got = pm.lookup("rally", {**state, "in_start_region": 5, "opp_region": 2})
    assert lvl == 4 and len(got) == 12                   # only the own region left
    lvl, got = pm.lookup("rally", {**state, "own_region": 0})
    assert lvl == 5 and len(got) == 32                   # nothing left: every rally shot
    # decisions follow the same cells: from own region 5 only backhand slices were seen
    rng = np.random.default_rng(0)
    d = pm.choose_shot({**state, "own_region": 5}, rng)
    assert d.shot_type == "backhand/slice" and d.type_level == 4
    _, names, probs = pm.shot_types("rally", state)
    assert list(names) == ["forehand/topspin"] and probs.tolist() == [1.0]


def test_result_rates_and_error_kind_follow_the_cell():
    rows = [_row()] * 30 + [_row(result="net", place_x=np.nan, place_y=np.nan,
                                 error_kind="forced")] * 10
    pm = fit_from_table(pd.DataFrame(rows), min_examples=5).player_model("A")
    rng = np.random.default_rng(1)
    state = {"own_region": 4, "opp_region": 4, "in_start_region": 4, "in_bounce_region": 1,
             "speed_bin": 2}
    ds = [pm.choose_shot(state, rng) for _ in range(400)]
    net = np.mean([d.result == "net" for d in ds])
    assert net == pytest.approx(0.25, abs=0.06)
    assert all(d.error_kind == "forced" for d in ds if d.result == "net")
    assert all(is_in_singles(*d.place_xy, 1) for d in ds if d.result == "in")


def test_opponent_specific_models_where_data_allows():
    rows = [_row(opponent="B")] * 50 + [_row(opponent="C")] * 5
    m = fit_from_table(pd.DataFrame(rows), min_opponent_shots=40)
    assert m.player_model("A", "B").opponent == "B"
    assert m.player_model("A", "C").opponent is None       # too few: the general model
    assert len(m.player_model("A", "C").table) == 55
    with pytest.raises(KeyError, match="no shot-cycle model"):
        m.player_model("Z")


# -- the simulator -------------------------------------------------------------------------------

def test_fitted_physique_and_stances(model):
    pm = model.player_model(FED, NADAL)
    assert pm.handedness == "right" and model.player_model(NADAL).handedness == "left"
    assert 5.0 < pm.physique.max_speed_mps <= 7.5 and 1.0 < pm.physique.reach_m < 2.5
    st = model.stances[FED][("server", 1, "deuce")]
    assert st.xy[0] < -11.0 and 2.0 < st.contact_xyz[2] < 3.2


def test_simulator_valid_rally_data_and_plausible_serving(model):
    sim = simulate_points(model, FED, NADAL, "clay", n_points=200, seed=5)
    RallyData.from_tables(sim.frames, sim.rallies, sim.shots, sim.fps)  # validates again
    pts = sim.points()
    assert len(pts) == 200
    assert set(sim.rallies["end_reason"]) <= set(END_REASONS)
    stats = serve_stats(pts)
    assert set(stats.index) == {FED, NADAL}
    assert ((stats["first_serve_in"] > 0.45) & (stats["first_serve_in"] < 0.9)).all()
    assert (stats["double_fault"] < 0.15).all() and (stats["ace"] < 0.25).all()
    assert ((stats["rally_mean"] > 1.5) & (stats["rally_mean"] < 10)).all()
    assert (stats["first_serve_kmh_median"] > 150).all()
    # outcomes are consistent with the shots: a winner/ace is the last hitter's point
    last = sim.shots.sort_values("shot_index").groupby("rally_id").tail(1).set_index(
        "rally_id")
    r = sim.rallies.set_index("rally_id")
    won = r["end_reason"].isin(["ace", "winner"])
    assert (r.loc[won, "winner"] == last.loc[r.index[won], "hitter"]).all()
    assert (last.loc[r.index[won], "outcome"] == "winner").all()
    faults = r["end_reason"].isin(["fault", "double_fault"])
    assert (last.loc[r.index[faults], "stroke"] == "serve").all()


def test_simulator_deterministic_for_a_seed(model):
    a = simulate_points(model, NADAL, FED, "grass", n_points=12, seed=11)
    b = simulate_points(model, NADAL, FED, "grass", n_points=12, seed=11)
    c = simulate_points(model, NADAL, FED, "grass", n_points=12, seed=12)
    for name in ("frames", "rallies", "shots"):
        pd.testing.assert_frame_equal(getattr(a, name), getattr(b, name))
    assert not a.shots["speed_mps"].equals(c.shots["speed_mps"])


def test_style_graphs_of_generated_and_simulated_play(data, model):
    cycles = shot_cycles(data)
    assert len(cycles) == len(data.shots)
    ref = build_style_graph(cycles, FED)
    assert ref.skill_index > 1.0 and ref.n_nodes >= 2
    assert similarity(ref, cycles) == pytest.approx(1.0)
    sim = simulate_points(model, FED, NADAL, "hard", n_points=40, seed=8)
    assert 0.05 < similarity(ref, sim) < 1.0
