"""The rally-outcome study's branch points and the generator's players' answer at each."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.branch_points import (
    AFTER_SERVE_FRAMES,
    BRANCH_S,
    pool_branch_points,
    study_branch_points,
    truth_rates,
    with_truth_rates,
)
from sportsngen.eval.expert_outcomes import kernel_win_shares, paired_reference_gaps
from sportsngen.eval.rules import analyse_rally_data


@pytest.fixture(scope="module")
def generated(truth_data):
    return truth_data(80, 6)


@pytest.fixture(scope="module")
def branched(generated):
    return study_branch_points(generated, 30, seed=2)


def test_branch_points_follow_the_study_design(generated, branched):
    rules = analyse_rally_data(generated)
    length = generated.frames.groupby("rally_id")["frame"].max()
    rallies = generated.rallies.set_index("rally_id")
    assert branched["rally_id"].nunique() == 30
    assert (rallies.loc[branched["rally_id"], "winner"] != "").all()    # decided rallies only
    for b in branched.itertuples():
        serve = int(rules.loc[b.rally_id, "contact_frames"][0])
        assert b.frame == max(int(round(b.branch_s * generated.fps)), serve + AFTER_SERVE_FRAMES)
        assert b.frame < length[b.rally_id] - 2
        r = rallies.loc[b.rally_id]
        assert b.server_won == float(r["winner"] == r["server"])
        assert b.decided == (b.frame >= rules.loc[b.rally_id, "end_frame"])
    assert set(branched["branch_s"]) <= set(BRANCH_S)
    # The folds alternate in the draw order, a rally's points in one fold.
    order = branched.drop_duplicates("rally_id")
    assert order["half"].tolist() == [k % 2 for k in range(30)]
    assert branched.groupby("rally_id")["half"].nunique().max() == 1
    assert study_branch_points(generated, 30, seed=2).equals(branched)
    with pytest.raises(ValueError, match="n_rallies"):
        study_branch_points(generated, 0)
    with pytest.raises(ValueError, match="decided"):
        study_branch_points(generated, 10_000)


def test_kernel_answers_each_branch_point_from_its_hand_over(generated, branched):
    rules = analyse_rally_data(generated)
    got = kernel_win_shares(generated, branched, n=6, seed=1)
    assert got.index.equals(branched.index)
    assert got[branched.columns].equals(branched)           # the points' own columns kept
    end = rules.loc[got["rally_id"], "end_frame"].to_numpy()
    decided = got["frame"].to_numpy() >= end
    assert (got["decided"].to_numpy() == decided).all() and decided.any()
    # A branch frame after the point's end is answered by the recorded winner, exactly.
    d = got[got["decided"]]
    assert (d["p_kernel"] == d["server_won"]).all() and (d["n_kernel"] == 0).all()
    live = got[~got["decided"] & got["p_kernel"].notna()]
    assert len(live) > 0.8 * (~got["decided"]).sum()
    assert live["n_kernel"].between(1, 6).all()
    assert live["p_kernel"].between(0, 1).all()
    for b in live.itertuples():     # the hand-over: 8 frames after the last contact, or sooner
        struck = [c for c in rules.loc[b.rally_id, "contact_frames"] if c <= b.frame]
        assert b.handover_frame == min(struck[-1] + 8, b.frame)
    again = kernel_win_shares(generated, branched, n=6, seed=1)
    pd.testing.assert_frame_equal(got, again)


def test_kernel_refuses_what_it_cannot_answer(generated, branched):
    # Before the serve's contact there is no flight to hand over.
    early = branched.head(3).assign(frame=2)
    got = kernel_win_shares(generated, early, n=2)
    assert got["p_kernel"].isna().all() and (got["n_kernel"] == 0).all()
    with pytest.raises(ValueError, match="column"):
        kernel_win_shares(generated, branched.drop(columns="frame"))
    with pytest.raises(ValueError, match="not in the data"):
        kernel_win_shares(generated, branched.head(1).assign(rally_id=10**9))
    with pytest.raises(ValueError, match="n must be"):
        kernel_win_shares(generated, branched, n=0)


def test_paired_reference_gaps_cluster_the_error_by_rally():
    points = pd.DataFrame({"rally_id": [1, 1, 2, 3], "server_won": [1.0, 1.0, 0.0, 1.0],
                           "p": [0.6, 0.8, 0.3, 0.5], "p_kernel": [0.5, 0.5, 0.5, np.nan],
                           "server": ["A", "A", "B", "B"]})
    got = paired_reference_gaps(points).loc["all"]
    gaps = np.array([0.1, 0.3, -0.2])
    dev = [gaps[:2].sum() - 2 * gaps.mean(), gaps[2] - gaps.mean()]
    assert got["n"] == 3 and got["rallies"] == 2
    assert got["gap"] == pytest.approx(gaps.mean())
    assert got["se"] == pytest.approx(np.sqrt(np.sum(np.square(dev))) / 3)
    assert got["outcome"] == pytest.approx(2 / 3)
    by = paired_reference_gaps(points, by="server")
    assert by.loc["A", "gap"] == pytest.approx(0.2) and by.loc["B", "n"] == 1
    with pytest.raises(ValueError, match="p_kernel"):
        paired_reference_gaps(points.drop(columns="p_kernel"))


def test_truth_rates_are_the_servers_share_by_group(generated):
    rates = truth_rates(generated)
    decided = int((generated.rallies["winner"] != "").sum())
    every = study_branch_points(generated, decided)
    live = every[~every["decided"]]
    assert rates["n"].sum() == len(live)
    one = live[(live["serve_number"] == 1) & (live["branch_s"] == 2.0)]
    for server, g in one.groupby("server"):
        assert rates.loc[(server, 1, 2.0), "rate"] == pytest.approx(g["server_won"].mean())


def test_with_truth_rates_takes_each_points_group_rate():
    rates = pd.DataFrame({"n": [10, 20], "rate": [0.7, 0.4]}, index=pd.MultiIndex.from_tuples(
        [("A", 1, 1.0), ("A", 2, 1.0)], names=["server", "serve_number", "branch_s"]))
    points = pd.DataFrame({"server": ["A", "A", "A", "B"], "serve_number": [2, 1, 1, 1],
                           "branch_s": [1.0, 1.0, 1.0, 1.0], "decided": [False, False, True, False],
                           "p": [0.5, 0.6, 1.0, 0.5]}, index=[7, 3, 5, 9])
    got = with_truth_rates(points, rates)
    assert got.index.tolist() == [7, 3, 5, 9]
    assert got["p_truth"].tolist()[:2] == [0.4, 0.7]
    assert np.isnan(got["p_truth"].tolist()[2:]).all()     # decided; a group the truth lacks
    assert got.drop(columns="p_truth").equals(points)


def test_pooled_branch_points_keep_each_runs_rallies_apart():
    a = pd.DataFrame({"rally_id": [0, 0, 7], "p": [0.1, 0.2, 0.3]})
    b = pd.DataFrame({"rally_id": [0, 3], "p": [0.4, 0.5]})
    got = pool_branch_points([a, b])
    assert got["rally_id"].tolist() == [0, 0, 7, 8, 11]
    assert got["p"].tolist() == [0.1, 0.2, 0.3, 0.4, 0.5]
    assert a["rally_id"].tolist() == [0, 0, 7]              # the parts are not changed
    with pytest.raises(ValueError, match="no branch points"):
        pool_branch_points([])
    # A part written before the decided flag existed drops the flag from the pool (it would
    # read NaN, and NaN as True).
    c = a.assign(decided=[False, True, False])
    assert list(pool_branch_points([c, b]).columns) == ["rally_id", "p"]
    assert pool_branch_points([c, c])["decided"].tolist() == [False, True, False] * 2
