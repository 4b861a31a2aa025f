"""Realism metrics (`sportsngen.eval.physical`): exact values on hand-built tracking, realistic
filtering, Wasserstein distances, and the measurements on generated tracking."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.tracking import FRAME_COLUMNS, RALLY_COLUMNS, SHOT_COLUMNS, RallyData
from sportsngen.eval import physical as ph
from sportsngen.eval.stats import serve_stats

FPS = 25.0
SHOT_GAP = 10  # frames between contacts in the hand-built rallies


def _rally(rid: int, point: int, serve_number: int, end_reason: str = "winner",
           winner: str = "A", **extra) -> dict:
    row = {c: 0 for c in RALLY_COLUMNS}
    row.update(rally_id=rid, match_id="m1", point=point, server="A", receiver="B",
               serve_number=serve_number, side="deuce", server_end=1, surface="hard",
               tournament="t", in_tiebreak=False, score="0-0", winner=winner,
               end_reason=end_reason, end_detail="none", serve_kmh=np.nan, rally_length=1)
    row.update(extra)
    return row


def _build(rallies: list[dict], shots: dict[int, list[tuple[str, float, float]]]) -> RallyData:
    """Rallies whose shots (stroke, speed m/s, contact z m) are struck every SHOT_GAP frames from
    frame SHOT_GAP; the ball flies straight at each shot's speed (alternating along x) until
    the next contact, so its track speed after a contact is the shot's speed exactly."""
    frames, shot_rows = [], []
    for r in rallies:
        rid = r["rally_id"]
        mine = shots.get(rid, [])
        n = SHOT_GAP * (len(mine) + 1) + 3
        vel = np.zeros((n, 3))
        for k, (stroke, speed, z) in enumerate(mine):
            f = SHOT_GAP * (k + 1)
            vel[f:, :] = [speed * (-1) ** k, 0.0, 0.0]
            shot_rows.append({"rally_id": rid, "shot_index": k, "frame": f,
                              "hitter": "A" if k % 2 == 0 else "B", "stroke": stroke,
                              "spin": "none", "direction": "none", "outcome": "in_play",
                              "error_kind": "none", "contact_x": 0.0, "contact_y": 0.0,
                              "contact_z": z, "speed_mps": speed, "bounce_x": np.nan,
                              "bounce_y": np.nan})
        pos = np.cumsum(vel, axis=0) / FPS  # frame j -> j+1 moves by vel[j+1] / fps
        pos[:, 2] += 1.0
        frames.append(pd.DataFrame({
            "rally_id": rid, "frame": np.arange(n), "t": np.arange(n) / FPS, "object": "ball",
            "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2], "stroke": "none",
            "direction": "none", "outcome": "none", "error_kind": "none"}))
    return RallyData.from_tables(pd.concat(frames, ignore_index=True)[list(FRAME_COLUMNS)],
                                 pd.DataFrame(rallies),
                                 pd.DataFrame(shot_rows, columns=list(SHOT_COLUMNS)),
                                 fps=FPS, validate=False)


def _known() -> RallyData:
    rallies = [_rally(0, 1, 1, "fault", ""), _rally(1, 1, 2), _rally(2, 2, 1)]
    shots = {
        0: [("serve", 50.0, 2.7)],
        1: [("serve", 40.0, 2.6), ("backhand", 25.0, 1.0), ("forehand", 30.0, 1.0),
            ("backhand", 20.0, 1.0), ("forehand_volley", 35.0, 1.2)],
        2: [("serve", 60.0, 2.8), ("forehand", 27.0, 1.0)],
    }
    return _build(rallies, shots)


def _stats(q: pd.DataFrame, name: str) -> dict[str, float]:
    return ph.summary(q.loc[q["quantity"] == name, "value"])


@pytest.mark.parametrize("speed_from", ["shots", "tracks"])
def test_shot_quantities_exact(speed_from):
    q = ph.shot_quantities(_known(), speed_from=speed_from)
    assert _stats(q, "toss_contact_height_m") == pytest.approx(
        {"n": 3, "median": 2.7, "iqr": 0.1})
    assert _stats(q, "first_serve_kmh") == pytest.approx({"n": 2, "median": 198.0, "iqr": 18.0})
    assert _stats(q, "second_serve_kmh") == pytest.approx({"n": 1, "median": 144.0, "iqr": 0.0})
    # The return is shot 1 whatever its stroke, and is no groundstroke; the volley is neither.
    assert _stats(q, "return_kmh") == pytest.approx({"n": 2, "median": 93.6, "iqr": 3.6})
    assert _stats(q, "groundstroke_kmh") == pytest.approx({"n": 2, "median": 90.0, "iqr": 18.0})
    assert set(q.loc[q["quantity"] == "first_serve_kmh", "hitter"]) == {"A"}


def test_track_speed_unknown_at_track_end():
    data = _known()
    ret = (data.shots["shot_index"] == 1) & (data.shots["rally_id"] == 2)
    # Move rally 2's return to the track's second-to-last frame: no whole frame after it.
    n = int(data.frames.loc[data.frames["rally_id"] == 2, "frame"].max())
    data.shots.loc[ret, "frame"] = n - 1
    q = ph.shot_quantities(data, speed_from="tracks")
    assert _stats(q, "return_kmh")["n"] == 1
    with pytest.raises(ValueError, match="speed_from"):
        ph.shot_quantities(data, speed_from="radar")


def _flagged() -> RallyData:
    """Point 1: realistic fault, unrealistic second serve. Point 2: undecided. Point 3: fine.
    Point 4: unrealistic fault, realistic second serve."""
    rallies = [
        _rally(0, 1, 1, "fault", "", realistic=True, failed_checks=""),
        _rally(1, 1, 2, realistic=False, failed_checks="position_jump"),
        _rally(2, 2, 1, "none", "", realistic=True, failed_checks=""),
        _rally(3, 3, 1, realistic=True, failed_checks=""),
        _rally(4, 4, 1, "fault", "", realistic=False, failed_checks="through_net"),
        _rally(5, 4, 2, realistic=True, failed_checks=""),
    ]
    shots = {i: [("serve", 45.0 + i, 2.7)] for i in range(6)}
    return _build(rallies, shots)


def test_realistic_filtering_drops_whole_points():
    data = _flagged()
    pts = ph.realistic_points(data)
    assert pts["point"].tolist() == [3]
    assert len(data.points()) == 4  # unfiltered, for contrast
    assert ph.realism_shares(data) == pytest.approx(
        {"n_rallies": 6, "non_realistic_share": 2 / 6, "undecided_share": 1 / 6})
    # Physical quantities keep every rally that counts on its own (the realistic fault too).
    q = ph.shot_quantities(data, speed_from="shots")
    assert sorted(q["rally_id"].unique()) == [0, 3, 5]
    assert sorted(ph.shot_quantities(data, realistic_only=False)["rally_id"].unique()) == \
        list(range(6))


def test_data_without_flags_counts_as_realistic():
    data = _known()
    assert "realistic" not in data.rallies.columns
    assert ph.counted_rallies(data.rallies).all()
    assert len(ph.realistic_points(data)) == len(data.points()) == 2


def test_bounce_speeds_exact():
    v_in, v_out = np.array([10.0, 0.0, -5.0]), np.array([8.0, 0.0, 4.0])
    # The ball lands half-way between frames 10 and 11: that segment mixes both flights, and
    # either neighbouring frame may be reported as the bounce frame.
    k = np.arange(21)[:, None] - 10.5
    ball = np.where(k <= 0, k * v_in, k * v_out) / FPS + [0.0, 0.0, 0.5]
    s_in, s_out = ph.bounce_speeds(ball, [10, 11], FPS)
    assert s_in == pytest.approx([np.sqrt(125.0)] * 2)
    assert s_out == pytest.approx([np.sqrt(80.0)] * 2)
    # A contact within two frames spoils the window; so does the track's edge.
    assert np.isnan(ph.bounce_speeds(ball, [10], FPS, contact_frames=[12])[0]).all()
    assert np.isfinite(ph.bounce_speeds(ball, [10], FPS, contact_frames=[13])[0]).all()
    assert np.isnan(ph.bounce_speeds(ball, [1, 19], FPS)[1]).all()


def test_bounce_ratios_with_given_events():
    data = _known()
    # Rally 2's track: the serve flies at 60 m/s from frame 10, the return at 27 m/s from 20.
    # Read as a "bounce" at frame 15 (no contact near), the ratio is 1; at 20 it is 27/60.
    events = pd.DataFrame({"bounce_frames": [[15, 20]], "contact_frames": [[]]},
                          index=pd.Index([2], name="rally_id"))
    b = ph.bounce_ratios(data, events=events)
    assert b["rally_id"].tolist() == [2, 2]
    assert b["surface"].tolist() == ["hard", "hard"]
    assert b["ratio"].to_numpy() == pytest.approx([1.0, 27.0 / 60.0])
    assert b["speed_in_mps"].to_numpy() == pytest.approx([60.0, 60.0])


def _sample(data: RallyData) -> ph.Sample:
    """A Sample without the rally rules (hand-built tracks have no players)."""
    return ph.Sample(shots=ph.shot_quantities(data, speed_from="shots"),
                     bounces=pd.DataFrame({"surface": ["hard"] * 3, "ratio": [0.7, 0.8, 0.9]}),
                     points=ph.realistic_points(data), realism=ph.realism_shares(data))


def _metric(m: pd.DataFrame, metric: str, group: str, statistic: str) -> pd.Series:
    hit = m[(m["metric"] == metric) & (m["group"] == group) & (m["statistic"] == statistic)]
    assert len(hit) == 1, (metric, group, statistic)
    return hit.iloc[0]


def test_wasserstein_identical_and_shifted():
    data = _known()
    same = ph.compare(_sample(data), _sample(data))
    w = same[same["statistic"] == "wasserstein"]
    assert w["sim"].isna().all()
    assert (w["ref"].dropna() == 0.0).all() and w["ref"].notna().sum() >= 10
    shifted = _known()
    shifted.shots["speed_mps"] += 1.0  # +3.6 km/h on every shot
    m = ph.compare(_sample(data), _sample(shifted))
    for q in ("first_serve_kmh", "return_kmh", "groundstroke_kmh"):
        assert _metric(m, q, "all", "wasserstein")["ref"] == pytest.approx(3.6)
        row = _metric(m, q, "all", "median")
        assert row["ref"] - row["sim"] == pytest.approx(3.6)
    assert _metric(m, "toss_contact_height_m", "all", "wasserstein")["ref"] == 0.0
    assert np.isnan(ph.wasserstein([1.0, 2.0], []))


def _real_points() -> pd.DataFrame:
    pts = pd.DataFrame({
        "server": ["A", "A", "A", "A", "C"], "receiver": ["X", "X", "X", "X", "A"],
        "winner": ["A", "X", "A", "X", "C"], "first_serve_in": [True, True, False, False, True],
        "ace": [True, False, False, False, False],
        "double_fault": [False, False, False, True, False],
        "serve_kmh": [200.0, 190.0, 150.0, np.nan, 170.0], "rally": [1, 5, 3, 0, 2],
        "event": "2011-usopen"})
    return pts


def test_compare_real_column():
    data = _known()
    m = ph.compare(_sample(data), _sample(data), real_points=_real_points())
    fs = _metric(m, "first_serve_kmh", "all", "median")
    assert fs["real"] == pytest.approx(195.0)  # server C is no player of the data: left out
    assert _metric(m, "first_serve_kmh", "A", "n")["real"] == 2
    assert _metric(m, "second_serve_kmh", "A", "median")["real"] == pytest.approx(150.0)
    assert np.isnan(_metric(m, "return_kmh", "all", "median")["real"])
    assert np.isnan(_metric(m, "bounce_speed_ratio", "hard", "median")["real"])
    assert _metric(m, "first_serve_in", "A", "value")["real"] == pytest.approx(0.5)
    assert _metric(m, "ace", "all", "value")["real"] == pytest.approx(0.25)
    assert _metric(m, "rally_length", "A", "share_0")["real"] == pytest.approx(0.25)
    assert _metric(m, "rally_length", "A", "mean")["real"] == pytest.approx(2.25)
    assert _metric(m, "n_points_counted", "all", "value")["real"] == 4
    assert _metric(m, "bounce_speed_ratio", "hard", "median")["sim"] == pytest.approx(0.8)


def test_pooled_group_counts_every_server_win():
    data = _known()
    data.rallies.loc[data.rallies["rally_id"] == 2, ["server", "receiver", "winner"]] = \
        ["B", "A", "B"]
    m = ph.compare(_sample(data), _sample(data))
    pts = ph.realistic_points(data)
    # Both servers won their point: the pooled share is 1, as it is for each of them.
    assert serve_stats(pts)["serve_points_won"].tolist() == [1.0, 1.0]
    assert _metric(m, "serve_points_won", "all", "value")["sim"] == 1.0
    assert _metric(m, "n_points", "all", "value")["sim"] == 2


@pytest.fixture(scope="module")
def generated() -> RallyData:
    from sportsngen.synth import generate_matches

    return generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points=25, seed=4,
                            workers=1)


def test_generated_tracking_measurements(generated):
    s = ph.collect(generated)
    # The rules find nearly every bounce the generator made (one a shot that bounced, plus
    # the deciding second bounces).
    bounced = int(generated.shots["bounce_x"].notna().sum())
    assert len(s.bounces) >= 0.9 * bounced
    ratio = s.bounces["ratio"].to_numpy()
    assert 0.65 < np.median(ratio) < 0.85  # hard court, measured 0.74 at 30 points
    # Track speeds sit a few per cent under the launch speeds (drag over the first frame).
    launch = ph.shot_quantities(generated, speed_from="shots")
    for q in ("first_serve_kmh", "groundstroke_kmh"):
        r = _stats(s.shots, q)["median"] / _stats(launch, q)["median"]
        assert 0.9 < r < 1.0, (q, r)
    assert s.realism["non_realistic_share"] == 0.0
    assert len(s.points) == 25
