"""Hawk-Eye ball statistics (`sportsngen.eval.hawkeye`) on hand-made tracks with known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.paths import HAWKEYE_TARGETS_MISSING, hawkeye_targets_path
from sportsngen.data.tracking import RALLY_COLUMNS, SHOT_COLUMNS, RallyData, TrackingDataError
from sportsngen.eval.hawkeye import (
    STATISTICS,
    TOLERANCES,
    compare,
    comparison_markdown,
    hawkeye_stats,
    load_targets,
    strike_keypoints,
)
from sportsngen.eval.hawkeye_strikes import crossing_height, parabola_vertex
from sportsngen.synth import physics

G = 9.81
R = physics.BALL_RADIUS_M
FPS = 25.0


def _parabola(pa, pb, duration_s):
    """Launch velocity of the drag-free flight from pa to pb in duration_s."""
    pa, pb = np.asarray(pa, float), np.asarray(pb, float)
    v = (pb - pa) / duration_s
    v[2] += 0.5 * G * duration_s
    return v


def _at(pa, v, tau):
    return pa + v * tau + np.array([0.0, 0.0, -0.5 * G * tau * tau])


def _track(waypoints: list[tuple[float, tuple]], t_end: float) -> np.ndarray:
    """Ball at every frame: still at the first waypoint before it, drag-free parabolas between
    consecutive waypoints, still at the last one after it."""
    t = np.arange(int(t_end * FPS) + 1) / FPS
    out = np.empty((len(t), 3))
    ts = [w[0] for w in waypoints]
    for k, tk in enumerate(t):
        if tk <= ts[0]:
            out[k] = waypoints[0][1]
        elif tk >= ts[-1]:
            out[k] = waypoints[-1][1]
        else:
            i = np.searchsorted(ts, tk) - 1
            (ta, pa), (tb, pb) = waypoints[i], waypoints[i + 1]
            out[k] = _at(np.asarray(pa, float), _parabola(pa, pb, tb - ta), tk - ta)
    return out


def _exact_net_z(pa, pb, duration_s):
    """Height where the drag-free flight pa -> pb crosses x = 0."""
    pa = np.asarray(pa, float)
    v = _parabola(pa, pb, duration_s)
    return _at(pa, v, -pa[0] / v[0])[2]


def _exact_peak(pa, pb, duration_s):
    pa = np.asarray(pa, float)
    v = _parabola(pa, pb, duration_s)
    tau = min(max(v[2] / G, 0.0), duration_s)
    return _at(pa, v, tau)[2]


# Rallies as (server, server_end, side, serve_number, serve_kmh, strikes); a strike is
# (hitter, contact time, contact, bounce, flight time to the bounce, then to the next contact).
# The bounce is (x, y), "net" (stopped by the net), or ("air", (x, y)): taken in the air by
# the opponent before it bounced at (x, y), which the shots table still records (as the
# generator's flights do). A at the -x end, B at the +x end throughout.
RALLIES = [
    ("A", -1, "deuce", 1, 180.0, [
        ("A", 1.013, (-12.3, -0.6, 2.9), (5.0, 2.0), 0.55, 0.50),      # serve in, body
        ("B", 2.063, (14.0, 1.5, 1.0), (-8.0, 0.5), 0.90, 0.60),       # return 2.115 m behind
        ("A", 3.563, (-12.5, 0.0, 0.9), (10.0, 1.0), 1.00, 0.50),      # rally groundstroke
        ("B", 5.063, (12.0, 1.0, 1.0), ("air", (-13.0, 0.0)), 1.10, 0.0),  # ... volleyed by A
        ("A", 6.163, (-10.5, 0.0, 1.2), (7.0, -1.0), 0.80, 0.40),      # the volley
        ("B", 7.363, (8.0, -0.5, 1.0), (-9.0, 0.0), 1.00, 0.50),       # struck inside 9 m
        ("A", 8.863, (-12.0, 0.0, 2.3), (13.0, 0.0), 1.00, 0.0),       # above 2 m, lands out
    ]),
    ("A", -1, "ad", 1, 200.0, [("A", 1.013, (-12.2, 0.7, 2.8), (7.0, -1.0), 0.50, 0.0)]),
    ("A", -1, "ad", 2, 150.0, [
        ("A", 1.013, (-12.1, 0.7, 2.7), (4.0, -1.0), 0.60, 0.45),      # second serve in
        ("B", 2.063, (11.5, 0.5, 0.8), (-6.0, 0.2), 0.85, 0.55),       # return inside the line
        ("A", 3.463, (-11.0, 0.0, 1.0), "net", 0.50, 0.0),             # into the net
    ]),
    ("A", -1, "deuce", 1, 190.0, [("A", 1.013, (-12.0, -0.5, 3.0), (6.0, 0.5), 0.50, 0.0)]),
    ("B", 1, "deuce", 1, 170.0, [
        ("B", 1.013, (12.3, 0.6, 2.6), (-5.0, -2.9), 0.55, 0.50),      # serve in, wide
        ("A", 2.063, (-13.0, -3.5, 1.1), (7.0, -1.0), 0.90, 0.60),     # return
        ("B", 3.563, (12.8, 1.2, 0.9), (-12.5, 0.0), 1.00, 0.0),       # rally ball long
    ]),
]


def _rally_data() -> tuple[RallyData, dict]:
    frames, rallies, shots, exact = [], [], [], {}
    for rid, (server, end, side, serve_no, kmh, strikes) in enumerate(RALLIES):
        way = []
        for k, (hitter, t, c, b, t1, _) in enumerate(strikes):
            way.append((t, c))
            bxy = b[1] if b[0] == "air" else b
            if b == "net":  # stops against the net on the hitter's side, drops
                net_pt = (-R if c[0] < 0 else R, c[1], 0.5)
                way += [(t + t1, net_pt), (t + t1 + 0.3, (net_pt[0], c[1], R))]
                exact[(rid, k)] = {"net": np.nan, "peak": _exact_peak(c, net_pt, t1)}
            elif b[0] == "air":  # volleyed: straight to the next contact
                nxt = strikes[k + 1]
                exact[(rid, k)] = {"net": _exact_net_z(c, nxt[2], t1),
                                   "peak": _exact_peak(c, nxt[2], t1)}
            else:
                bp = (b[0], b[1], R)
                way.append((t + t1, bp))
                exact[(rid, k)] = {"net": _exact_net_z(c, bp, t1), "peak": _exact_peak(c, bp, t1)}
                if k == len(strikes) - 1:  # after the last bounce, on and up a little
                    way.append((t + t1 + 0.4, (b[0] + np.sign(b[0]) * 3.0, b[1], 0.5)))
            shots.append({"rally_id": rid, "shot_index": k, "frame": int(round(t * FPS)),
                          "hitter": hitter, "stroke": "serve" if k == 0 else "forehand",
                          "spin": "flat", "direction": "none", "outcome": "in_play",
                          "error_kind": "none", "contact_x": c[0], "contact_y": c[1],
                          "contact_z": c[2], "speed_mps": 30.0,
                          "bounce_x": np.nan if b == "net" else bxy[0],
                          "bounce_y": np.nan if b == "net" else bxy[1]})
        ball = _track(way, way[-1][0] + 0.5)
        n = len(ball)
        receiver = "B" if server == "A" else "A"
        # The players stand behind their baselines (the statistics read the ball alone).
        for obj, x, z in (("ball", ball[:, 0], ball[:, 2]), (server, end * 12.5, 0.0),
                          (receiver, -end * 12.5, 0.0)):
            frames.append(pd.DataFrame({
                "rally_id": rid, "frame": np.arange(n), "t": np.arange(n) / FPS,
                "object": obj, "x": x, "y": ball[:, 1] if obj == "ball" else 0.0, "z": z,
                "stroke": "none", "direction": "none", "outcome": "none", "error_kind": "none"}))
        rallies.append({"rally_id": rid, "match_id": "m1", "point": [1, 2, 2, 3, 4][rid],
                        "server": server, "receiver": "B" if server == "A" else "A",
                        "serve_number": serve_no, "side": side, "server_end": end,
                        "surface": "hard", "tournament": "test", "set_no": 1, "server_sets": 0,
                        "receiver_sets": 0, "server_games": 0, "receiver_games": 0,
                        "server_points": 0, "receiver_points": 0, "in_tiebreak": False,
                        "score": "0-0", "winner": "" if rid == 1 else server,
                        "end_reason": "fault" if rid == 1 else "winner", "end_detail": "out",
                        "serve_kmh": kmh, "rally_length": 0})
    data = RallyData.from_tables(pd.concat(frames, ignore_index=True),
                                 pd.DataFrame(rallies, columns=list(RALLY_COLUMNS)),
                                 pd.DataFrame(shots, columns=list(SHOT_COLUMNS)), fps=FPS)
    return data, exact


@pytest.fixture(scope="module")
def hand():
    data, exact = _rally_data()
    return strike_keypoints(data), exact


def _stat(stats, player, name):
    row = stats[(stats["player"] == player) & (stats["statistic"] == name)]
    assert len(row) == 1, (player, name)
    return float(row["value"].iloc[0]), int(row["n"].iloc[0])


def test_interpolation_exact_on_parabolas():
    rng = np.random.default_rng(0)
    for _ in range(20):
        x0, vx = rng.uniform(-3, -1), rng.uniform(15, 40)
        z0, vz = rng.uniform(0.5, 2.5), rng.uniform(-3, 6)
        t = (np.arange(3) + rng.uniform(0, 1)) / FPS - 0.04 + (-x0 / vx - 1 / FPS)
        x, z = x0 + vx * t, z0 + vz * t - 0.5 * G * t * t
        ts = -x0 / vx
        assert crossing_height(x[None], z[None])[0] == pytest.approx(
            z0 + vz * ts - 0.5 * G * ts * ts, abs=1e-9)
        tp = np.arange(-1, 2) / FPS + vz / G + rng.uniform(-0.02, 0.02)
        zp = z0 + vz * tp - 0.5 * G * tp * tp
        assert parabola_vertex(*zp) == pytest.approx(z0 + vz * vz / (2 * G), abs=1e-9)


def test_interpolation_within_a_millimetre_with_drag_and_spin():
    """A topspin groundstroke with drag, sampled at 25 Hz: net height and peak from three
    frames against the integrated flight (dense bisection)."""
    for phase in (0.0, 0.013, 0.027):
        flight = physics.fly((-12.0, 0.5, 0.9), (26.0, -1.0, 6.0), 6.0, "hard", 2.0)
        t = np.arange(phase, flight.t_s[-1], 1 / FPS)
        p = flight.at(t)
        k = int(np.flatnonzero((p[:-1, 0] < 0) & (p[1:, 0] >= 0))[0])
        lo, hi = t[k], t[k + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if flight.at(mid)[0] < 0 else (lo, mid)
        z_net = crossing_height(p[None, k - 1:k + 2, 0], p[None, k - 1:k + 2, 2])[0]
        assert abs(z_net - flight.at(lo)[2]) < 5e-4  # a straight line: ~1-3 mm
        dense = flight.at(np.linspace(0, flight.events[0].t_s, 20001))
        top = int(np.argmax(p[:, 2]))
        assert abs(parabola_vertex(*p[top - 1:top + 2, 2]) - dense[:, 2].max()) < 5e-4


def test_keypoints_exact_and_aligned(hand):
    strikes, exact = hand
    s = strikes.set_index(["rally_id", "strike"])
    for (rid, k), want in exact.items():
        row = s.loc[(rid, k + 1)]
        assert row["peak_z_m"] == pytest.approx(want["peak"], abs=1e-9)
        if np.isnan(want["net"]):
            assert np.isnan(row["net_z_m"])
        else:
            assert row["net_z_m"] == pytest.approx(want["net"], abs=1e-9)
    # B's serve from the +x end is rotated: hitter at x < 0, deuce server at y < 0.
    serve_b = s.loc[(4, 1)]
    assert (serve_b["hit_x_m"], serve_b["hit_y_m"]) == (-12.3, -0.6)
    assert (serve_b["bounce_x_m"], serve_b["bounce_y_m"]) == (5.0, 2.9)
    assert serve_b["player"] == "B" and serve_b["landed_in"]
    ret = s.loc[(0, 2)]
    assert (ret["hit_x_m"], ret["hit_y_m"], ret["bounce_x_m"]) == (-14.0, -1.5, 8.0)
    # Strike 4 was volleyed: its recorded bounce is dropped (the ball never got there), it
    # counts as in play, and the volley knows its ball did not bounce.
    assert not s.loc[(0, 4), "bounced"] and s.loc[(0, 4), "in_play"]
    assert np.isnan(s.loc[(0, 4), "bounce_x_m"])
    assert not s.loc[(0, 5), "incoming_bounced"] and s.loc[(0, 3), "incoming_bounced"]
    assert not s.loc[(1, 1), "landed_in"] and not s.loc[(0, 7), "landed_in"]


def test_statistics_known_answers(hand):
    strikes, exact = hand
    st = hawkeye_stats(strikes, pooled=False)
    assert list(st.columns) == ["player", "surface", "statistic", "value", "n"]
    assert set(st["statistic"]) == set(STATISTICS) and set(st["surface"]) == {"hard"}
    a = lambda name: _stat(st, "A", name)  # noqa: E731
    b = lambda name: _stat(st, "B", name)  # noqa: E731
    assert a("serve1_kmh_median") == (185.0, 2)
    assert a("serve2_kmh_median") == (150.0, 1)
    assert a("serve_contact_z_median") == (pytest.approx(2.85), 4)
    assert a("serve_contact_behind_m_median") == (pytest.approx(0.265), 4)
    assert a("serve1_net_z_median")[0] == pytest.approx(
        np.median([exact[(0, 0)]["net"], exact[(3, 0)]["net"]]), abs=1e-9)
    assert a("serve2_net_z_median")[0] == pytest.approx(exact[(2, 0)]["net"], abs=1e-9)
    assert a("serve1_depth_m_median") == (pytest.approx(np.median([1.4, 0.4])), 2)
    assert a("serve2_depth_m_median") == (pytest.approx(2.4), 1)
    assert [a(f"serve1_{z}_share") for z in ("wide", "body", "t")] == [
        (0.0, 2), (0.5, 2), (0.5, 2)]
    assert b("serve1_wide_share") == (1.0, 1)
    # Returns: B against a first serve (2.115 m behind) and a second (0.385 m inside).
    assert b("return_contact_behind_m_median") == (pytest.approx(0.865), 2)
    assert b("return1_contact_behind_m_median") == (pytest.approx(2.115), 1)
    assert b("return2_contact_behind_m_median") == (pytest.approx(-0.385), 1)
    assert b("return_depth_m_median") == (pytest.approx(np.median([3.885, 5.885])), 2)
    assert b("return_net_z_median")[1] == 2 and a("return_net_z_median")[1] == 1
    # Rally groundstrokes: A's strikes 3 of rallies 0 and 2 (the volley and the ball above 2 m
    # are out; the net ball has no net height or depth); B's strike 4 of rally 0 (volleyed
    # back: no depth) and strike 3 of rally 4 (the ball struck inside 9 m is out).
    assert a("rally_contact_behind_m_median") == (pytest.approx(np.median([0.615, -0.885])), 2)
    assert a("rally_contact_z_median") == (pytest.approx(0.95), 2)
    assert a("rally_net_z_median") == (pytest.approx(exact[(0, 2)]["net"], abs=1e-9), 1)
    # The peak counts only balls that crossed the net, as Hawk-Eye's peak keypoints do.
    assert a("rally_peak_z_median") == (pytest.approx(exact[(0, 2)]["peak"], abs=1e-9), 1)
    assert a("rally_depth_m_median") == (pytest.approx(1.885), 1)
    assert a("rally_deep_share") == (1.0, 1)
    assert b("rally_contact_behind_m_median") == (pytest.approx(0.515), 2)
    assert b("rally_net_z_median") == (pytest.approx(
        np.median([exact[(0, 3)]["net"], exact[(4, 2)]["net"]]), abs=1e-9), 2)
    assert b("rally_depth_m_median")[1] == 0 and np.isnan(b("rally_depth_m_median")[0])
    # Rally lengths of A's three service points: 6, 2 (second serve), 1 (ace); B's: 2.
    assert a("rally_len_5-8_share") == (pytest.approx(1 / 3), 3)
    assert a("rally_len_2_share") == (pytest.approx(1 / 3), 3)
    assert a("rally_len_mean") == (pytest.approx(3.0), 3)
    assert b("rally_len_2_share") == (1.0, 1)


def test_pooled_rows(hand):
    strikes, _ = hand
    alone = hawkeye_stats(strikes)  # A and B are not named players: no tour rows
    assert set(alone["player"]) == {"A", "B"}
    both = hawkeye_stats(strikes, tours={"A": "ATP", "B": "ATP"})
    assert _stat(both, "ATP", "serve_contact_z_median")[1] == 5
    assert _stat(both, "ATP", "rally_contact_behind_m_median")[1] == 4
    assert _stat(both, "ATP", "rally_len_mean") == (pytest.approx(11 / 4), 4)
    only_a = hawkeye_stats(strikes, tours={"A": "WTA"})
    assert _stat(only_a, "WTA", "serve_contact_z_median") == (pytest.approx(2.85), 4)


def test_generated_rally_lengths_and_bounce_check():
    from sportsngen.synth import generate_matches

    data = generate_matches([("Roger Federer", "Serena Williams")], "hard", 40, seed=3)
    s = strike_keypoints(data)
    assert set(s["tour"]) == {"ATP", "WTA"}
    lengths = s.groupby("rally_id")["in_play"].sum()
    assert (lengths == data.rallies.set_index("rally_id").loc[lengths.index,
                                                               "rally_length"]).all()
    assert (s["hit_x_m"] < 0).all()
    shots = data.shots.copy()
    in_box = (shots["bounce_x"].abs() < 6.4) & (shots["bounce_y"].abs() < 4.1)
    j = int(np.flatnonzero(in_box & (shots["shot_index"] == 0))[0])
    shots.loc[j, "bounce_y"] -= 2.0 * np.sign(shots.loc[j, "bounce_y"])  # 2 m off the track
    bad = RallyData(data.frames, data.rallies, shots, data.fps)
    with pytest.raises(TrackingDataError, match=f"rally {int(shots['rally_id'][j])}, shot 0"):
        strike_keypoints(bad)
    strike_keypoints(bad, check_bounces=False)


def test_compare_flags_and_markdown():
    gen = pd.DataFrame({"player": ["ATP"] * 4, "surface": ["hard"] * 4,
                        "statistic": ["serve1_kmh_median", "return_net_z_median",
                                      "rally_net_z_p90", "serve1_body_share"],
                        "value": [190.0, 2.05, 2.5, 0.2], "n": [10, 10, 10, 10]})
    real = gen.assign(value=[184.0, 1.80, 2.3, 0.1], n=[100, 100, 100, 100])
    cmp = compare(gen, real, [("ATP", "hard")])
    assert len(cmp) == len(STATISTICS)
    row = cmp.set_index("statistic")
    assert row.loc["serve1_kmh_median", "within"] and row.loc["serve1_kmh_median",
                                                                "tolerance"] == 8.0
    assert not row.loc["return_net_z_median", "within"]  # 0.25 > 0.20
    assert row.loc["rally_net_z_p90", "within"]           # 0.20 <= 0.25
    assert not row.loc["serve1_body_share", "within"]     # 10 pp > 8 pp
    assert row.loc["serve1_body_share", "difference"] == pytest.approx(0.1)
    assert pd.isna(row.loc["rally_len_mean", "within"]) and row.loc["rally_len_mean",
                                                                     "n_real"] == 0
    assert (row.loc["serve1_kmh_median", "n_generated"], row.loc["serve1_kmh_median",
                                                                  "n_real"]) == (10, 100)
    assert TOLERANCES["return_net_z_p10"] == 0.25 and TOLERANCES["serve1_depth_m_median"] == 0.75
    md = comparison_markdown(cmp)
    assert "| serve1_kmh_median | 8 | 190 / 184 |" in md
    assert "**20 / 10**" in md and "**2.05 / 1.80**" in md and "| 2.50 / 2.30 |" in md
    assert "| within tolerance | | 2/4 |" in md
    # Beside an earlier comparison: "now / real (before)", the earlier one in italics if out.
    earlier = cmp.assign(generated=cmp["generated"] + 1.0,
                         within=cmp["within"].map(lambda w: w if w is pd.NA else False))
    md = comparison_markdown(cmp, before=earlier)
    assert "| serve1_kmh_median | 8 | 190 / 184 (*191*) |" in md
    assert "| within tolerance | | 0/4 -> 2/4 |" in md


@pytest.mark.skipif(hawkeye_targets_path() is None, reason=HAWKEYE_TARGETS_MISSING)
def test_real_targets_layout():
    t = load_targets()
    assert set(t["statistic"]) == set(STATISTICS)
    assert t.groupby(["player", "surface"]).size().eq(len(STATISTICS)).all()
    assert {("ATP", "hard"), ("WTA", "clay"), ("Rafael Nadal", "clay")} <= set(
        zip(t["player"], t["surface"]))


@pytest.mark.skipif(hawkeye_targets_path() is None, reason=HAWKEYE_TARGETS_MISSING)
def test_generated_matchups_compared_with_the_real_figures():
    from sportsngen.eval.hawkeye import comparison_markdown
    from sportsngen.eval.hawkeye_report import README_GROUPS, generated_strikes, hawkeye_report

    strikes = generated_strikes(30, seed=4)
    assert strikes.groupby(["match_id", "rally_id"]).ngroups == strikes["rally_id"].nunique()
    _, cmp = hawkeye_report(strikes, groups=README_GROUPS)
    assert len(cmp) == 10 * len(STATISTICS)
    serve_pos = cmp[cmp["statistic"] == "serve_contact_behind_m_median"]
    assert serve_pos["generated"].notna().all() and serve_pos["within"].all()
    md = comparison_markdown(cmp)
    assert "| statistic | tol. | Federer hard | Federer clay |" in md and "WTA hard |" in md
