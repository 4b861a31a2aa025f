"""The Hawk-Eye keypoint reader (`sportsngen.data.keypoints`) on small files written here in
the collection's layout (made-up values; nothing of the real data), good and corrupted."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.keypoints import KeypointDataError, read_keypoints
from sportsngen.data.points import POINTS_COLUMNS
from sportsngen.data.tracking import SHOT_COLUMNS
from sportsngen.eval.hawkeye import hawkeye_stats, keypoint_strikes

MATCH = "atp_australian_open_2020MS901"
TRAJ_HEADER = "point_ID,set_num,game_num,point_num,serve_num,strike_index,position,x,y,z"
# P1 serves game 1 from the -x end; ends change, P2 serves game 2 from the -x end.
STRIKES = {
    "1_1_1_1": [  # serve in, return, P1's groundstroke lands deep: rally of 3
        [("hit", -11.5, -0.4, 2.85), ("peak", -11.5, -0.4, 2.85), ("net", 0.0, 0.5, 1.10),
         ("bounce", 5.2, 1.0, 0.033)],
        [("hit", 13.0, 1.5, 1.2), ("peak", 4.0, 1.0, 2.1), ("net", 0.0, 0.6, 1.9),
         ("bounce", -8.5, 0.2, 0.033), ("peak", -12.0, 0.0, 1.1)],
        [("hit", -12.4, 0.1, 1.05), ("peak", -3.0, 0.5, 1.9), ("net", 0.0, 0.7, 1.6),
         ("bounce", 9.5, 1.2, 0.033), ("last", 14.0, 1.5, 0.9)],
    ],
    "1_1_2_1": [  # first serve long
        [("hit", -11.4, 0.6, 2.8), ("peak", -11.4, 0.6, 2.8), ("net", 0.0, -0.5, 1.2),
         ("bounce", 7.2, -1.5, 0.033), ("last", 13.0, -2.5, 1.0)],
    ],
    "1_1_2_2": [  # second serve in, return into the net
        [("hit", -11.45, 0.7, 2.75), ("peak", -11.45, 0.7, 2.75), ("net", 0.0, -0.4, 1.25),
         ("bounce", 4.5, -1.0, 0.033)],
        [("hit", 12.0, -1.2, 0.9), ("peak", 5.0, -0.8, 1.8), ("last", 0.0, -0.5, 0.8),
         ("net", 0.0, -0.5, 0.8)],
    ],
    "1_2_1_1": [  # P2 serves wide, P1 returns, P2's ball goes long
        [("hit", -11.6, -0.5, 2.7), ("peak", -11.6, -0.5, 2.7), ("net", 0.0, 1.5, 1.15),
         ("bounce", 6.0, 3.0, 0.033)],
        [("hit", 12.5, 3.0, 1.0), ("peak", 3.0, 1.5, 2.4), ("net", 0.0, 1.0, 2.3),
         ("bounce", -9.0, -2.0, 0.033)],
        [("hit", -12.9, -2.2, 0.95), ("peak", -2.0, -1.0, 2.2), ("net", 0.0, -0.8, 2.1),
         ("bounce", 12.6, 0.0, 0.033), ("last", 15.0, 0.5, 1.0)],
    ],
}
PBP_HEADER = ("point_ID,set_num,game_num,point_num,serve_num,server_id,returner_id,"
              "point_winner_id,court_side,serve_speed_kph,rally_length,point_end_type,is_ace,"
              "is_doublefault,is_tiebreak,server_score,returner_score,player1,player2,"
              "p1_cum_games,p2_cum_games")
PBP = [
    "1_1_1_1,1,1,1,1,P1ID,P2ID,P1ID,DeuceCourt,190 KPH,3,Winner,0,0,0,0,0,P1ID,P2ID,0,0",
    "1_1_2_1,1,1,2,1,P1ID,P2ID,,AdCourt,0 KPH,1,Faulty Serve,0,0,0,1,0,P1ID,P2ID,0,0",
    "1_1_2_2,1,1,2,2,P1ID,P2ID,P1ID,AdCourt,150 KPH,1,Forced Error,0,0,0,1,0,P1ID,P2ID,0,0",
    "1_2_1_1,1,2,1,1,P2ID,P1ID,P1ID,DeuceCourt,NA,2,Unforced Error,0,0,0,0,0,P1ID,P2ID,1,0",
]


def _traj_lines() -> list[str]:
    lines = [TRAJ_HEADER]
    for pid, strikes in STRIKES.items():
        s, g, p, v = pid.split("_")
        for k, kps in enumerate(strikes, start=1):
            lines += [f"{pid},{s},{g},{p},{v},{k},{kind},{x},{y},{z}" for kind, x, y, z in kps]
    return lines


def _write(folder: Path, traj: list[str] | None = None, pbp: list[str] | None = None) -> Path:
    (folder / "ball_trajectory").mkdir(parents=True, exist_ok=True)
    (folder / "play_by_play").mkdir(exist_ok=True)
    (folder / "misc").mkdir(exist_ok=True)
    (folder / "ball_trajectory" / f"{MATCH}_ball_trajectory.csv").write_text(
        "\n".join(traj or _traj_lines()) + "\n")
    (folder / "play_by_play" / f"{MATCH}_pbp.csv").write_text(
        "\n".join([PBP_HEADER] + (pbp or PBP)) + "\n")
    (folder / "misc" / "player_ids.csv").write_text(
        '"name","id"\n"P.ONE","P1ID"\n"P.TWO","P2ID"\n')
    return folder


def test_good_files_into_tables(tmp_path):
    kd = read_keypoints(_write(tmp_path), player_names={"P.ONE": "Player One"})
    assert len(kd.attempts) == 4 and len(kd.keypoints) == sum(
        len(k) for s in STRIKES.values() for k in s)
    assert list(kd.points.columns) == list(POINTS_COLUMNS)
    pts = kd.points.set_index("point")
    assert list(pts.index) == [1, 2, 3]
    assert (pts.loc[1, "server"], pts.loc[1, "receiver"], pts.loc[1, "winner"]) == (
        "Player One", "P.TWO", "Player One")
    assert pts.loc[2, "serve_number"] == 2 and not pts.loc[2, "first_serve_in"]
    assert pts.loc[1, "serve_kmh"] == 190.0 and pts.loc[2, "serve_kmh"] == 150.0
    assert np.isnan(pts.loc[3, "serve_kmh"])
    assert (pts.loc[2, "server_score"], pts.loc[2, "receiver_score"]) == ("15", "0")
    assert (pts.loc[3, "server_games"], pts.loc[3, "receiver_games"]) == (0, 1)
    assert pts.loc[1, "rally"] == 3 and pts.loc[1, "surface"] == "hard"
    assert pts.loc[1, "event"] == "2020-australian_open"
    a = kd.attempts.set_index("point_id")
    assert a.loc["1_1_2_1", "side"] == "ad" and np.isnan(a.loc["1_1_2_1", "serve_kmh"])
    assert a.loc["1_2_1_1", "server_end"] == -1 and a.loc["1_1_1_1", "tour"] == "ATP"
    assert list(kd.shots.columns) == list(SHOT_COLUMNS)
    sh = kd.shots[kd.shots["rally_id"] == a.loc["1_2_1_1", "rally_id"]]
    assert list(sh["hitter"]) == ["P.TWO", "Player One", "P.TWO"]
    assert list(sh["bounce_x"]) == [6.0, -9.0, 12.6] and sh["frame"].isna().all()
    assert sh["speed_mps"].isna().all()


def test_statistics_on_keypoints(tmp_path):
    kd = read_keypoints(_write(tmp_path))
    s = keypoint_strikes(kd).set_index(["rally_id", "strike"])
    r0 = int(kd.attempts.set_index("point_id").loc["1_1_2_2", "rally_id"])
    assert np.isnan(s.loc[(r0, 2), "net_z_m"])  # into the net: did not clear it
    assert not s.loc[(r0, 2), "in_play"]
    st = hawkeye_stats(keypoint_strikes(kd))
    v = st.set_index(["player", "surface", "statistic"])

    def get(player, name):
        row = v.loc[(player, "hard", name)]
        return float(row["value"]), int(row["n"])

    assert get("P.ONE", "serve1_kmh_median") == (190.0, 1)
    assert get("P.ONE", "serve2_kmh_median") == (150.0, 1)
    assert get("P.ONE", "serve_contact_z_median") == (pytest.approx(2.8), 3)
    assert get("P.ONE", "serve_contact_behind_m_median") == (pytest.approx(-0.435), 3)
    assert get("P.ONE", "serve1_net_z_median") == (1.10, 1)
    assert get("P.ONE", "serve2_depth_m_median") == (pytest.approx(1.9), 1)
    assert get("P.TWO", "return_net_z_median") == (1.9, 1)  # the other return hit the net
    assert get("P.TWO", "return_contact_behind_m_median") == (pytest.approx(0.615), 2)
    assert get("P.TWO", "serve1_wide_share") == (1.0, 1)
    # P1's third ball: 0.515 m behind, peak 1.9, over the net at 1.6, 2.385 m from the line.
    assert get("P.ONE", "rally_contact_behind_m_median") == (pytest.approx(0.515), 1)
    assert get("P.ONE", "rally_peak_z_median") == (1.9, 1)
    assert get("P.ONE", "rally_net_z_median") == (1.6, 1)
    assert get("P.ONE", "rally_depth_m_median") == (pytest.approx(2.385), 1)
    assert get("P.ONE", "rally_deep_share") == (1.0, 1)
    assert get("P.TWO", "rally_depth_m_median")[1] == 0  # long
    assert get("P.ONE", "rally_len_mean") == (2.0, 2) and get("P.TWO", "rally_len_2_share") == (
        1.0, 1)
    assert get("ATP", "serve_contact_z_median")[1] == 4  # the league's pooled rows


def _one_line_changed(lines: list[str], row: int, column: str, value: str) -> list[str]:
    cols = lines[0].split(",")
    cells = lines[row].split(",")
    cells[cols.index(column)] = value
    return lines[:row] + [",".join(cells)] + lines[row + 1:]


TRAJ_FILE = f"{MATCH}_ball_trajectory.csv"


@pytest.mark.parametrize("change, column, row, message", [
    (("x", "abc"), "x", 3, "cannot be read as a number: 'abc'"),
    (("z", ""), "z", 5, "NaN coordinate"),
    (("y", "45.0"), "y", 7, "45 m is off any plausible court"),
    (("position", "apex"), "position", 2, "unknown keypoint 'apex'"),
    (("strike_index", "3"), "strike_index", 5, "strike 3 follows strike 1"),
    (("set_num", "one"), "set_num", 4, "cannot be read as an integer: 'one'"),
])
def test_corrupted_values_name_file_row_and_column(tmp_path, change, column, row, message):
    lines = _one_line_changed(_traj_lines(), row, *change)
    _write(tmp_path, traj=lines)
    with pytest.raises(KeypointDataError) as err:
        read_keypoints(tmp_path)
    text = str(err.value)
    assert re.search(rf"{TRAJ_FILE} row {row} \(point 1_1_1_1\), column '{column}': "
                     rf"{re.escape(message)}", text), text


def test_missing_column_duplicate_row_order_and_missing_file(tmp_path):
    lines = _traj_lines()
    dropped = [",".join(c for i, c in enumerate(line.split(",")) if i != 9) for line in lines]
    _write(tmp_path / "a", traj=dropped)
    with pytest.raises(KeypointDataError, match=rf"{TRAJ_FILE}: missing columns \['z'\]"):
        read_keypoints(tmp_path / "a")

    _write(tmp_path / "b", traj=lines[:8] + [lines[7]] + lines[8:])
    with pytest.raises(KeypointDataError, match=rf"{TRAJ_FILE} row 8 \(point 1_1_1_1\), "
                                                r"column 'point_ID': duplicate of row 7"):
        read_keypoints(tmp_path / "b")

    swapped = lines[:1] + [lines[2], lines[1]] + lines[3:]  # the serve's peak before its hit
    _write(tmp_path / "c", traj=swapped)
    with pytest.raises(KeypointDataError, match=r"row 1 \(point 1_1_1_1\), column 'position': "
                                                r"strike 1 starts with 'peak', not 'hit'"):
        read_keypoints(tmp_path / "c")

    _write(tmp_path / "d", pbp=[PBP[0], PBP[0].replace("1_1_1_1,1,1,1,1", "1_1_2_1,1,1,2,1"),
                                PBP[0].replace("P1ID,DeuceCourt", "P1ID,Middle")])
    with pytest.raises(KeypointDataError) as err:
        read_keypoints(tmp_path / "d")
    text = str(err.value)
    assert "_pbp.csv row 3 (point 1_1_1_1), column 'point_ID': duplicate point_ID (also row 1)" \
        in text
    assert "column 'court_side': unknown court side 'Middle'" in text
    assert "column 'point_ID': no row for this point in the play-by-play file" in text  # 1_1_2_2

    _write(tmp_path / "e")
    (tmp_path / "e" / "play_by_play" / f"{MATCH}_pbp.csv").unlink()
    with pytest.raises(KeypointDataError, match=rf"{TRAJ_FILE}: no play-by-play file "
                                                rf"{MATCH}_pbp.csv"):
        read_keypoints(tmp_path / "e")
    with pytest.raises(FileNotFoundError, match="no keypoint folder"):
        read_keypoints(tmp_path / "absent")


def test_repair_drops_exactly_the_named_points(tmp_path):
    lines = _one_line_changed(_traj_lines(), 22, "z", "NA")  # in point 1_1_2_2
    lines = _one_line_changed(lines, 3, "x", "99.0")         # in point 1_1_1_1
    _write(tmp_path, traj=lines)
    kd = read_keypoints(tmp_path, repair=True)
    dropped = kd.meta["repaired"]["dropped_points"]
    assert dropped == [(MATCH, "1_1_1_1"), (MATCH, "1_1_2_2")]
    assert len(kd.meta["repaired"]["problems"]) == 2
    assert list(kd.attempts["point_id"]) == ["1_1_2_1", "1_2_1_1"]
    assert set(kd.keypoints["rally_id"]) == set(kd.attempts["rally_id"])
    good = read_keypoints(_write(tmp_path / "good"))
    kept = good.keypoints[good.keypoints["rally_id"].isin(good.attempts.loc[
        good.attempts["point_id"].isin(["1_1_2_1", "1_2_1_1"]), "rally_id"])]
    pd.testing.assert_frame_equal(kd.keypoints.reset_index(drop=True),
                                  kept.reset_index(drop=True))


def test_report_on_keypoint_files(tmp_path):
    """The statistics of real files through the same report and code as generated play."""
    from sportsngen.data.paths import hawkeye_targets_path
    from sportsngen.eval.hawkeye_report import write_hawkeye_report

    if hawkeye_targets_path() is None:
        pytest.skip("real Hawk-Eye figures absent")
    _write(tmp_path / "files")
    assert write_hawkeye_report(tmp_path / "real", keypoints=tmp_path / "files") == 0
    assert (tmp_path / "real.md").read_text().startswith("### Hawk-Eye statistics: real")
    cmp = pd.read_csv(tmp_path / "real.csv").set_index(["player", "surface", "statistic"])
    assert cmp.loc[("ATP", "hard", "serve_contact_z_median"), "generated"] == pytest.approx(2.775)
    assert cmp.loc[("ATP", "hard", "serve_contact_z_median"), "n_generated"] == 4
