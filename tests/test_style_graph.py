"""Style graphs: shot cycles, k-means with the smallest k, skill index, similarity, layout, and
the style-graph and heatmap figures."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from sportsngen.eval.style_graph import (
    END_COLUMNS,
    STATE_COLUMNS,
    StyleGraph,
    build_style_graph,
    edge_overlap,
    graph_on_nodes,
    kmeans,
    pca_layout,
    shot_cycles,
    similarity,
    skill_index,
    smallest_k,
)
from sportsngen.viz.heatmaps import placements, plot_player_heatmaps, recoveries
from sportsngen.viz.style_graph_plot import plot_style_graphs, transitions


def _edges(rows) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["src", "dst", "action", "count"])


def test_skill_index_on_hand_made_graphs():
    assert skill_index([1, 2, 5, 1, 3], n_nodes=2) == 1.5      # three repeated edges
    assert skill_index([1, 1, 1], n_nodes=3) == 0.0             # single actions are ignored
    assert skill_index([], n_nodes=1) == 0.0
    with pytest.raises(ValueError):
        skill_index([2], n_nodes=0)
    g = StyleGraph("A", np.zeros((4, 4)), np.array([5, 3, 2, 1]),
                   _edges([(0, 1, "fh", 4), (0, 1, "bh", 1), (1, 0, "fh", 2), (2, 2, "bh", 2)]),
                   1.0)
    assert g.n_nodes == 4 and g.skill_index == 0.75
    assert transitions(g) == {(0, 1): 4, (1, 0): 2, (2, 2): 2}


def _table(states: list[tuple], actions: list[str], rally_of: list[int]) -> pd.DataFrame:
    """A shot table with only what shot_cycles reads: alternating hitters A and B per rally."""
    rows = []
    for i, ((ox, oy, px, py), act, rid) in enumerate(zip(states, actions, rally_of)):
        k = sum(1 for r in rally_of[:i] if r == rid)
        stroke, direction = act.split("|")
        rows.append({"rally_id": rid, "shot_index": k, "hitter": "AB"[k % 2],
                     "opponent": "BA"[k % 2], "own_x": ox, "own_y": oy,
                     "opp_x": -px, "opp_y": -py,  # the table keeps the opponent in his frame
                     "stroke": stroke, "direction": direction, "place_x": 10.0, "place_y": 0.0,
                     "speed_mps": 25.0})
    return pd.DataFrame(rows)


def test_shot_cycles_link_a_players_consecutive_contacts():
    s = [(-12.0, float(i), 12.0, 0.0) for i in range(6)]
    t = _table(s, ["forehand|middle"] * 6, [0, 0, 0, 0, 0, 1])
    c = shot_cycles(t)
    a = c[c["player"] == "A"].reset_index(drop=True)
    assert len(a) == 4                          # shots 0, 2, 4 of rally 0 and shot 0 of rally 1
    assert a.loc[0, "end_own_y"] == 2.0 and a.loc[1, "end_own_y"] == 4.0
    assert np.isnan(a.loc[2, list(END_COLUMNS)].to_numpy(float)).all()  # the rally ended
    assert a.loc[0, "opp_x"] == 12.0            # opponent position in A's frame
    assert a.loc[0, "action"] == "forehand|middle|deep|medium"


def test_kmeans_and_the_smallest_k_under_the_threshold():
    rng = np.random.default_rng(0)
    centres = np.array([[0, 0, 0, 0], [10, 0, 0, 0], [0, 10, 0, 0]], dtype=float)
    x = np.concatenate([c + rng.normal(0, 0.2, (30, 4)) for c in centres])
    c, lab = smallest_k(x, threshold_m=1.0)
    assert len(c) == 3
    assert all(len(set(lab[i * 30:(i + 1) * 30])) == 1 for i in range(3))
    assert len(smallest_k(x, threshold_m=100.0)[0]) == 1
    c1, l1 = kmeans(x, 3, seed=4)
    c2, l2 = kmeans(x, 3, seed=4)
    np.testing.assert_array_equal(c1, c2)
    with pytest.raises(ValueError):
        kmeans(x, 0)


def _two_state_rallies(actions_a: list[str], n_rallies: int) -> pd.DataFrame:
    """A alternates between a deuce-corner state and an ad-corner state; B stays central."""
    deuce, ad, b = (-12.0, -3.0, 12.0, 0.0), (-12.0, 3.0, 12.0, 0.0), (-12.0, 0.0, 12.0, 0.0)
    states, acts, rid = [], [], []
    for r in range(n_rallies):
        for k in range(4):   # A, B, A, B
            states.append((deuce if k == 0 else ad) if k % 2 == 0 else b)
            acts.append(actions_a[r % len(actions_a)] if k % 2 == 0 else "backhand|middle")
            rid.append(r)
    return _table(states, acts, rid)


def test_style_graph_nodes_edges_and_skill_index():
    t = _two_state_rallies(["forehand|cross_court", "forehand|down_the_line",
                            "backhand|middle"], n_rallies=6)
    g = build_style_graph(t, "A", threshold_m=1.0)
    assert g.n_nodes == 2 and sorted(g.node_counts.tolist()) == [6, 6]
    # 6 cycles deuce -> ad, 2 with each of three actions; ad-corner cycles have no end state
    assert len(g.edges) == 3 and (g.edges["count"] == 2).all()
    assert g.skill_index == 1.5
    single = build_style_graph(_two_state_rallies(["forehand|a", "forehand|b", "forehand|c",
                                                   "forehand|d", "forehand|e", "forehand|f"],
                                                  6), "A", threshold_m=1.0)
    assert single.skill_index == 0.0            # every action taken once


def test_similarity_is_the_edge_frequency_overlap():
    ref = build_style_graph(_two_state_rallies(["forehand|x", "forehand|y"], 4), "A", 1.0)
    assert similarity(ref, _two_state_rallies(["forehand|x", "forehand|y"], 8)) == 1.0
    assert similarity(ref, _two_state_rallies(["backhand|z"], 4)) == 0.0
    # x only: p = (1/2, 1/2) over (x, y), q = (1, 0) -> overlap 1/2
    assert similarity(ref, _two_state_rallies(["forehand|x"], 4)) == pytest.approx(0.5)
    other = graph_on_nodes(ref, _two_state_rallies(["forehand|x"], 4))
    np.testing.assert_array_equal(other.centroids, ref.centroids)
    assert edge_overlap(ref, other) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="no shot cycles"):
        build_style_graph(_two_state_rallies(["forehand|x"], 2), "Nobody")


def test_pca_layout_is_deterministic_and_keeps_distances_on_a_line():
    pts = np.array([[0, 0, 0, 0], [1, 1, 0, 0], [3, 3, 0, 0]], dtype=float)
    xy = pca_layout(pts)
    np.testing.assert_allclose(np.abs(np.diff(xy[:, 0])), [np.sqrt(2), 2 * np.sqrt(2)])
    np.testing.assert_allclose(xy[:, 1], 0.0, atol=1e-12)
    np.testing.assert_array_equal(xy, pca_layout(pts))
    assert pca_layout(pts[:1]).tolist() == [[0.0, 0.0]]


def test_style_graph_figure(tmp_path):
    t = _two_state_rallies(["forehand|x", "forehand|y"], 4)
    ref = build_style_graph(t, "A", 1.0)
    path = tmp_path / "graphs.png"
    fig = plot_style_graphs([[ref, ref], [graph_on_nodes(ref, t)]], path=path, dpi=40,
                            layouts=[[None, None], [ref.layout()]])
    assert isinstance(fig, Figure) and path.stat().st_size > 1000
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert len(titles) == 3 and all("skill index 1.00" in s for s in titles)


def test_heatmap_points_and_figure(tmp_path):
    rows = [{"hitter": "A", "opponent": "B", "stroke": s, "place_x": x, "place_y": y,
             "recovery_x": -13.0, "recovery_y": y / 4}
            for s, x, y in [("forehand", 9.0, 1.0), ("forehand_volley", 5.0, -2.0),
                            ("backhand", 10.0, 3.0), ("serve", 5.0, 2.0),
                            ("backhand", np.nan, np.nan)]]
    t = pd.DataFrame(rows)
    np.testing.assert_array_equal(placements(t, "A", "forehand"), [[9.0, 1.0], [5.0, -2.0]])
    np.testing.assert_array_equal(placements(t, "A", "backhand"), [[10.0, 3.0]])
    assert len(recoveries(t, "A")) == 4                 # the NaN row is left out
    with pytest.raises(ValueError):
        placements(t, "B")
    path = tmp_path / "heat.png"
    fig = plot_player_heatmaps(t, "A", path=path, dpi=30)
    assert len(fig.axes) == 3 and path.stat().st_size > 1000
    assert "forehand placement (n=2)" in fig.axes[0].get_title()


def test_state_columns_are_positions():
    assert STATE_COLUMNS == ("own_x", "own_y", "opp_x", "opp_y")
