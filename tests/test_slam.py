"""The Grand Slam point-by-point reader and the score replay, on the shared real data."""

import shutil
from pathlib import Path

import pandas as pd
import pytest

from sportsngen.data.paths import SHARED_DATA_MISSING, slam_dir
from sportsngen.data.points import POINTS_COLUMNS, POINTS_DTYPES
from sportsngen.data.slam import (
    list_slam_events,
    parse_match_id,
    read_slam_event,
    read_slam_events,
)
from sportsngen.data.slam_replay import (
    REPLAY_COLUMNS,
    glitch_kind,
    replay_slam_events,
    replay_slam_points,
    replay_summary,
)
from sportsngen.eval.stats import serve_stats

pytestmark = pytest.mark.skipif(slam_dir() is None, reason=SHARED_DATA_MISSING)
EVENTS = ("2011-usopen", "2011-wimbledon", "2012-ausopen", "2012-frenchopen")

# /work/shared/data/README.md, 2011 US Open + Wimbledon pooled: 1st in, aces, DF, 1st won,
# 2nd won (%), median 1st / 2nd serve speed (km/h).
README_TABLE = {
    "Roger Federer": (66.4, 11.1, 1.6, 78.6, 59.8, 189, 156),
    "Rafael Nadal": (70.2, 5.9, 1.9, 73.5, 53.8, 181, 140),
    "Novak Djokovic": (66.2, 7.4, 2.2, 75.1, 56.3, 189, 146),
    "Serena Williams": (59.0, 14.9, 3.0, 78.0, 50.8, 168, 135),
}


def _files(event: str) -> tuple[Path, Path]:
    return slam_dir() / f"{event}-points.csv", slam_dir() / f"{event}-matches.csv"


@pytest.fixture(scope="session")
def usopen() -> pd.DataFrame:
    return read_slam_event(*_files("2011-usopen"))


@pytest.fixture(scope="session")
def replay() -> pd.DataFrame:
    return replay_slam_events(events=list(EVENTS))


def _subset(tmp_path: Path, event: str, match_id: str, edit=None) -> tuple[Path, Path]:
    """Copy one match of an event to tmp_path, optionally editing its rows (a DataFrame of str)."""
    pts, mts = _files(event)
    df = pd.read_csv(pts, dtype=str, keep_default_na=False)
    df = df[df["match_id"] == match_id].reset_index(drop=True)
    if edit is not None:
        df = edit(df)
    out_pts, out_mts = tmp_path / pts.name, tmp_path / mts.name
    df.to_csv(out_pts, index=False)
    shutil.copy(mts, out_mts)
    return out_pts, out_mts


def test_list_events_and_match_ids():
    assert set(EVENTS) <= set(list_slam_events())
    assert parse_match_id("2011-usopen-1101") == (2011, "usopen", "2011-usopen", "men")
    assert parse_match_id("2012-frenchopen-2118")[3] == "women"
    with pytest.raises(ValueError, match="1xxx"):
        parse_match_id("2011-usopen-3101")


def test_reader_columns_dtypes_and_values(usopen):
    assert tuple(usopen.columns) == POINTS_COLUMNS
    assert {c: str(usopen[c].dtype) for c in POINTS_COLUMNS} == {
        c: str(pd.Series(dtype=d).dtype) for c, d in POINTS_DTYPES.items()}
    assert len(usopen) == 27309 - 161  # file rows minus one PointNumber-0 row per match
    assert usopen["point"].min() == 1
    assert set(usopen["surface"]) == {"hard"} and set(usopen["event"]) == {"2011-usopen"}
    first = usopen.iloc[0]  # 2011-usopen-1101 point 1: Djokovic serves 194 km/h, wins
    assert (first["server"], first["receiver"], first["winner"]) == (
        "Novak Djokovic", "Conor Niland", "Novak Djokovic")
    assert (first["serve_kmh"], first["rally"], first["first_serve_in"]) == (194.0, 1, True)
    assert (first["server_score"], first["receiver_score"], first["set_no"]) == ("0", "0", 1)
    assert usopen.iloc[1]["server_score"] == "15"  # scores are BEFORE the point
    # Double faults: second serve, no speed, rally 0; aces have rally 1.
    df = usopen[usopen["double_fault"]]
    assert (df["serve_number"] == 2).all() and df["serve_kmh"].isna().all()
    assert (df["rally"] == 0).all()
    assert (usopen.loc[usopen["ace"], "rally"] == 1).all()
    assert ((usopen["serve_number"] == 1) == usopen["first_serve_in"]).all()


def test_reader_score_before_point(usopen):
    m = usopen[usopen["match_id"] == "2011-usopen-1109"].set_index("point")
    # Point 111 wins Berdych (P1) the game for 6-6: before it, 5-6 AD-40 on his serve.
    assert m.loc[111, ["server_games", "receiver_games", "server_score", "receiver_score"]
                 ].tolist() == [5, 6, "AD", "40"]
    # Point 113 is in the tie-break, P1 serving at 0-1 (Jouan won point 112).
    assert m.loc[113, ["server_games", "receiver_games", "server_score", "receiver_score"]
                 ].tolist() == [6, 6, "0", "1"]
    # The first point of set 3 starts at 0-0 0-0 (the set-ending row shows 7-6 after).
    assert m.loc[123, ["set_no", "server_games", "receiver_games", "server_score"]
                 ].tolist() == [3, 0, 0, "0"]


def test_2012_events_lack_serve_flags_but_keep_aces():
    au = read_slam_event(*_files("2012-ausopen"))
    assert au["first_serve_in"].isna().all() and au["serve_number"].isna().all()
    assert au["rally"].isna().all()
    assert au["ace"].notna().all() and au["ace"].sum() > 0
    st = serve_stats(au).loc["Novak Djokovic"]
    assert pd.isna(st["first_serve_in"]) and pd.isna(st["first_serve_kmh_median"])
    assert 0.0 < st["ace"] < 0.2


def test_read_slam_events_concatenates():
    both = read_slam_events(events=["2011-usopen", "2011-wimbledon"])
    assert set(both["event"]) == {"2011-usopen", "2011-wimbledon"}
    assert set(both.loc[both["event"] == "2011-wimbledon", "surface"]) == {"grass"}
    with pytest.raises(ValueError, match="2099-usopen"):
        read_slam_events(events=["2099-usopen"])


def test_reader_missing_column(tmp_path):
    pts, mts = _subset(tmp_path, "2011-usopen", "2011-usopen-1101",
                       lambda d: d.drop(columns=["PointWinner"]))
    with pytest.raises(ValueError, match=r"2011-usopen-points\.csv.*PointWinner"):
        read_slam_event(pts, mts)


def test_reader_bad_value_names_file_column_row(tmp_path):
    def corrupt(d):
        d.loc[5, "PointServer"] = "3"  # data row 6: PointNumber 5
        return d

    pts, mts = _subset(tmp_path, "2011-usopen", "2011-usopen-1101", corrupt)
    with pytest.raises(ValueError) as err:
        read_slam_event(pts, mts)
    msg = str(err.value)
    assert str(pts) in msg and "'PointServer'" in msg and "data row 6" in msg and "'3'" in msg
    repaired = read_slam_event(pts, mts, repair=True)
    assert len(repaired.attrs["dropped"]) == 1 and 5 not in set(repaired["point"])


def test_readme_table_reproduced():
    pts = read_slam_events(events=["2011-usopen", "2011-wimbledon"])
    st = serve_stats(pts)
    for name, (fsi, ace, df, w1, w2, kmh1, kmh2) in README_TABLE.items():
        row = st.loc[name]
        got = [100 * row[c] for c in ("first_serve_in", "ace", "double_fault",
                                      "first_serve_won", "second_serve_won")]
        assert got == pytest.approx([fsi, ace, df, w1, w2], abs=0.1), name
        assert row["first_serve_kmh_median"] == pytest.approx(kmh1, abs=1.0), name
        assert row["second_serve_kmh_median"] == pytest.approx(kmh2, abs=1.0), name


def test_replay_agreement_and_glitches(replay):
    assert tuple(replay.columns) == REPLAY_COLUMNS
    summary = replay_summary(replay)
    assert set(summary.index) == set(EVENTS)
    assert (summary["agreement_pct"] >= 99.0).all(), summary
    disagree = replay[~replay["agrees"]]
    assert (disagree["glitch"] != "").all()
    assert (replay.loc[replay["agrees"], "glitch"] == "").all()
    assert summary.loc["2012-frenchopen", "glitches"] > 0  # the known-glitchy event
    assert summary.loc["2012-frenchopen", "dropped_rows"] == 4


def test_replay_2011_matches_end_where_recorded(replay):
    # The 2011 files are clean: every point agrees, and exactly the retired matches end early.
    r = replay[replay["event"].str.startswith("2011")]
    assert r["agrees"].all()
    last = r.groupby("match_id").tail(1)
    unfinished = set(last.loc[~last["match_over"], "match_id"])
    retired = set()
    for ev in ("2011-usopen", "2011-wimbledon"):
        m = pd.read_csv(_files(ev)[1])
        retired |= set(m.loc[m["status"] == "Retired", "match_id"])
    assert unfinished == retired and len(retired) == 12


def test_replay_detects_missing_point(tmp_path):
    # Drop 2011-usopen-1108 point 13 (mid-game, 0-15 -> 15-15): the row after the next shows
    # a score one point ahead of the replay.
    pts, mts = _subset(tmp_path, "2011-usopen", "2011-usopen-1108",
                       lambda d: d[d["PointNumber"] != "13"])
    r = replay_slam_points(pts, mts)
    bad = r[~r["agrees"]]
    assert list(bad["point"]) == [15]
    assert glitch_kind(bad["glitch"]).tolist() == ["points missing"]
    assert "set 1 0-2 15-30 P1 serving" in bad["glitch"].iloc[0]
    assert r["match_over"].iloc[-1]  # re-synchronised and finished the match


def test_replay_detects_rows_out_of_order(tmp_path):
    def swap(d):  # swap points 13 and 14 (won by different players)
        i, j = d.index[d["PointNumber"] == "13"][0], d.index[d["PointNumber"] == "14"][0]
        rows = d.loc[[j, i]].to_numpy()
        d.loc[[i, j]] = rows
        return d

    pts, mts = _subset(tmp_path, "2011-usopen", "2011-usopen-1108", swap)
    r = replay_slam_points(pts, mts)
    bad = r[~r["agrees"]]
    assert len(bad) >= 1 and (bad["glitch"] != "").all()
    assert bad["glitch"].str.contains("PointNumber not increasing").any()
    assert r["agrees"].mean() > 0.98 and r["match_over"].iloc[-1]


def test_replay_truncated_match_is_not_a_glitch(tmp_path):
    pts, mts = _subset(tmp_path, "2011-usopen", "2011-usopen-1108",
                       lambda d: d.iloc[:100])
    r = replay_slam_points(pts, mts)
    assert r["agrees"].all() and not r["match_over"].iloc[-1]
    assert replay_summary(r).loc["2011-usopen", "unfinished"] == 1


def test_committed_targets_match_the_data():
    # sportsngen/synth/data/slam2011_targets.csv is generated by scripts/derive_player_stats.py;
    # it must equal what the data gives today.
    path = Path(__file__).resolve().parents[1] / "sportsngen/synth/data/slam2011_targets.csv"
    assert path.read_text().startswith("# Source: Jeff Sackmann / Tennis Abstract")
    targets = pd.read_csv(path, comment="#").set_index("player")
    assert len(targets) == 7 and targets.loc["Serena Williams", "gender"] == "women"
    pts = read_slam_events(events=["2011-usopen", "2011-wimbledon"])
    st = serve_stats(pts).loc[targets.index]
    for col in ("first_serve_in", "ace", "double_fault", "first_serve_won", "second_serve_won",
                "first_serve_kmh_median", "rally_mean"):
        assert targets[col].to_numpy() == pytest.approx(st[col].to_numpy(), abs=1e-4), col
    rally_cols = [c for c in targets.columns if c.startswith("rally_") and c != "rally_mean"]
    assert targets[rally_cols].sum(axis=1).to_numpy() == pytest.approx(1.0, abs=1e-3)
    assert ((targets["return_points_won"] > 0.2) & (targets["return_points_won"] < 0.6)).all()
