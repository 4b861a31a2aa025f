"""Style graphs (SkillVis style): a player's repertoire as states (nodes) and actions (edges).

Shot cycles: a player's cycle runs from one of his contacts to his next contact in the same
rally (his shot, the opponent's reply). Its start state is where both players stand at his
contact, in his frame (`shot_cycle_table`: his baseline at -x), as the 4-vector
(own_x, own_y, opp_x, opp_y) in metres; its end state the same vector at his next contact (none
when the rally ended first). Its action is his shot, discretised: stroke, direction label,
depth class of the first bounce (short inside the service line, mid, deep beyond the midpoint
of service line and baseline, long or wide out, net) and speed class (`SPEED_CLASS_EDGES_MPS`).

Nodes: k-means clusters of the start states, with the smallest k whose mean distance from a
state to its centroid is at most `threshold_m`. Edges: for a (start node, end node) pair, one
edge per distinct action, counted over the cycles; cycles without an end state add to the node
counts only. Skill index = edges / nodes, counting only edges taken by at least two cycles
(an action seen once is noise, not repertoire).

Similarity of a graph to a reference graph of the same player: the other data's cycles are
assigned to the reference's nodes (nearest centroid), and the score is the overlap of the two
normalised edge-frequency distributions, sum over (start, end, action) of min(p, q): 1 when the
same transitions happen at the same rates, 0 when none is shared.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from sportsngen.baselines.shot_cycle_table import PLAYER_FRONT_X_M, shot_table
from sportsngen.data.tracking import RallyData
from sportsngen.tennis.court import BASELINE_X_M, SERVICE_LINE_X_M, SINGLES_HALF_WIDTH_M

STATE_COLUMNS = ("own_x", "own_y", "opp_x", "opp_y")
END_COLUMNS = tuple(f"end_{c}" for c in STATE_COLUMNS)
SPEED_CLASS_EDGES_MPS = (22.0, 30.0, 40.0)
SPEED_CLASSES = ("slow", "medium", "fast", "very_fast")
DEFAULT_THRESHOLD_M = 1.5
K_MAX = 40
KMEANS_ITERS = 60
KMEANS_RESTARTS = 3


def _depth_class(place_x: np.ndarray, place_y: np.ndarray) -> np.ndarray:
    """Depth of a first bounce in the hitter's frame (his opponent's half at +x)."""
    x, y = np.abs(place_x), np.abs(place_y)
    out = np.where(x <= SERVICE_LINE_X_M, "short",
                   np.where(x <= PLAYER_FRONT_X_M, "mid", "deep")).astype(object)
    out[(x > BASELINE_X_M) | (y > SINGLES_HALF_WIDTH_M) | (place_x < 0)] = "out"
    out[~np.isfinite(place_x)] = "net"
    return out


def shot_cycles(data: RallyData | pd.DataFrame) -> pd.DataFrame:
    """One row per shot cycle: player, opponent, rally_id, shot_index, the start state
    (`STATE_COLUMNS`), the end state (`END_COLUMNS`, NaN without one) and ``action``.
    Accepts a `RallyData` or its `shot_table`."""
    t = data if isinstance(data, pd.DataFrame) else shot_table(data)
    t = t.sort_values(["rally_id", "shot_index"], kind="stable").reset_index(drop=True)
    # The opponent's position into the hitter's frame (the table gives it in his own).
    state = np.column_stack([t["own_x"], t["own_y"], -t["opp_x"], -t["opp_y"]]).astype(float)
    rid = t["rally_id"].to_numpy()
    nxt = np.full((len(t), 4), np.nan)
    same = np.r_[rid[2:] == rid[:-2], False, False]
    nxt[same] = state[2:][same[:-2]]
    speed = np.asarray(SPEED_CLASSES, dtype=object)[
        np.searchsorted(SPEED_CLASS_EDGES_MPS, t["speed_mps"].to_numpy(float), side="right")]
    depth = _depth_class(t["place_x"].to_numpy(float), t["place_y"].to_numpy(float))
    action = (t["stroke"].astype(str) + "|" + t["direction"].astype(str) + "|" + depth + "|"
              + speed)
    out = pd.DataFrame({"player": t["hitter"].astype(str), "opponent": t["opponent"].astype(str),
                        "rally_id": rid, "shot_index": t["shot_index"].to_numpy(),
                        "action": action.to_numpy(object)})
    for k, c in enumerate(STATE_COLUMNS):
        out[c] = state[:, k]
        out[END_COLUMNS[k]] = nxt[:, k]
    return out


def kmeans(x: np.ndarray, k: int, seed: int = 0, n_iter: int = KMEANS_ITERS,
           restarts: int = KMEANS_RESTARTS) -> tuple[np.ndarray, np.ndarray]:
    """(centroids (k, d), labels (n,)) by Lloyd's algorithm from k-means++ seeds; the best of
    `restarts` runs by inertia. Deterministic for a seed."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    if not 1 <= k <= n:
        raise ValueError(f"k must lie in [1, {n}], got {k}")
    rng = np.random.default_rng(seed)
    best = (np.inf, None, None)
    for _ in range(restarts):
        cent = [x[rng.integers(n)]]
        for _ in range(1, k):  # k-means++: far points are likelier seeds
            d2 = np.min(((x[:, None, :] - np.asarray(cent)[None]) ** 2).sum(-1), axis=1)
            p = d2 / d2.sum() if d2.sum() > 0 else np.full(n, 1.0 / n)
            cent.append(x[rng.choice(n, p=p)])
        c = np.asarray(cent)
        for _ in range(n_iter):
            lab = assign(x, c)
            new = np.array([x[lab == j].mean(0) if np.any(lab == j) else c[j] for j in range(k)])
            if np.allclose(new, c):
                break
            c = new
        lab = assign(x, c)
        inertia = float(((x - c[lab]) ** 2).sum())
        if inertia < best[0]:
            best = (inertia, c, lab)
    return best[1], best[2]


def assign(x: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    """Index of the nearest centroid for each row of `x`."""
    d2 = ((np.asarray(x, float)[:, None, :] - centroids[None]) ** 2).sum(-1)
    return np.argmin(d2, axis=1)


def smallest_k(x: np.ndarray, threshold_m: float, seed: int = 0,
               k_max: int = K_MAX) -> tuple[np.ndarray, np.ndarray]:
    """k-means with the smallest k (<= `k_max`) whose mean point-to-centroid distance is at
    most `threshold_m`; `k_max` clusters if none is."""
    x = np.asarray(x, dtype=float)
    for k in range(1, min(k_max, len(x)) + 1):
        c, lab = kmeans(x, k, seed)
        if np.mean(np.linalg.norm(x - c[lab], axis=1)) <= threshold_m:
            return c, lab
    return c, lab


def skill_index(edge_counts, n_nodes: int) -> float:
    """Edges taken by at least two cycles, per node."""
    if n_nodes <= 0:
        raise ValueError(f"n_nodes must be positive, got {n_nodes}")
    return float(np.sum(np.asarray(edge_counts) >= 2)) / n_nodes


@dataclass
class StyleGraph:
    """Nodes (`centroids` (k, 4) in metres, `node_counts`) and `edges` (src, dst, action,
    count) of one player's style graph."""

    player: str
    centroids: np.ndarray
    node_counts: np.ndarray
    edges: pd.DataFrame
    threshold_m: float

    @property
    def n_nodes(self) -> int:
        return len(self.centroids)

    @property
    def skill_index(self) -> float:
        return skill_index(self.edges["count"], self.n_nodes)

    def layout(self) -> np.ndarray:
        """2-D positions of the nodes: the first two principal components of the centroids."""
        return pca_layout(self.centroids)


def _player_cycles(cycles: pd.DataFrame, player: str) -> pd.DataFrame:
    mine = cycles[cycles["player"] == player]
    mine = mine[np.isfinite(mine[list(STATE_COLUMNS)].to_numpy(float)).all(axis=1)]
    if mine.empty:
        raise ValueError(f"no shot cycles of {player!r}; players: "
                         f"{sorted(cycles['player'].unique())}")
    return mine


def _graph(player: str, cycles: pd.DataFrame, centroids: np.ndarray,
           threshold_m: float) -> StyleGraph:
    start = assign(cycles[list(STATE_COLUMNS)].to_numpy(float), centroids)
    end_x = cycles[list(END_COLUMNS)].to_numpy(float)
    has_end = np.isfinite(end_x).all(axis=1)
    e = pd.DataFrame({"src": start[has_end], "dst": assign(end_x[has_end], centroids),
                      "action": cycles["action"].to_numpy(object)[has_end]})
    edges = e.groupby(["src", "dst", "action"]).size().rename("count").reset_index()
    counts = np.bincount(start, minlength=len(centroids))
    return StyleGraph(player, centroids, counts, edges, threshold_m)


def build_style_graph(data: RallyData | pd.DataFrame, player: str,
                      threshold_m: float = DEFAULT_THRESHOLD_M, seed: int = 0) -> StyleGraph:
    """The style graph of `player` from a `RallyData`, its shot table or its `shot_cycles`."""
    cycles = data if isinstance(data, pd.DataFrame) and "action" in data.columns \
        else shot_cycles(data)
    mine = _player_cycles(cycles, player)
    centroids, _ = smallest_k(mine[list(STATE_COLUMNS)].to_numpy(float), threshold_m, seed)
    return _graph(player, mine, centroids, threshold_m)


def graph_on_nodes(reference: StyleGraph, data: RallyData | pd.DataFrame) -> StyleGraph:
    """The reference player's graph from other data, on the reference's nodes."""
    cycles = data if isinstance(data, pd.DataFrame) and "action" in data.columns \
        else shot_cycles(data)
    mine = _player_cycles(cycles, reference.player)
    return _graph(reference.player, mine, reference.centroids, reference.threshold_m)


def edge_overlap(a: StyleGraph, b: StyleGraph) -> float:
    """sum min(p, q) of the two graphs' normalised edge frequencies (same node indexing)."""
    key = ["src", "dst", "action"]
    m = a.edges.merge(b.edges, on=key, how="outer", suffixes=("_a", "_b")).fillna(0)
    if m.empty:
        return 0.0
    p = m["count_a"].to_numpy(float)
    q = m["count_b"].to_numpy(float)
    if p.sum() == 0 or q.sum() == 0:
        return 0.0
    return float(np.minimum(p / p.sum(), q / q.sum()).sum())


def similarity(reference: StyleGraph, data: RallyData | pd.DataFrame) -> float:
    """How alike the reference player's play in `data` is to the reference graph (module doc):
    in [0, 1], 1 for identical edge frequencies on the reference's nodes."""
    return edge_overlap(reference, graph_on_nodes(reference, data))


def pca_layout(points: np.ndarray) -> np.ndarray:
    """(k, 2) projection of `points` (k, d) on their first two principal axes; axis signs fixed
    so the largest loading is positive (a deterministic picture)."""
    p = np.asarray(points, dtype=float)
    out = np.zeros((len(p), 2))
    if len(p) < 2:
        return out
    centred = p - p.mean(0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    for j in range(min(2, len(vt))):
        v = vt[j] * np.sign(vt[j][np.argmax(np.abs(vt[j]))])
        out[:, j] = centred @ v
    return out


def compare_style_graphs(cycles: dict[str, pd.DataFrame], players, threshold_m: float,
                         seed: int) -> tuple[list[dict], list[StyleGraph], list[StyleGraph]]:
    """Each player's graph of the "truth" cycles against the "sim" cycles and a second truth
    sample's ("truth2": the similarity a finite sample of the same players reaches) -> (a row
    a player: nodes, skill indices, similarities, cycles; the truth's graphs; the simulated
    cycles on the truth's nodes)."""
    rows: list[dict] = []
    ref_graphs, sim_graphs = [], []
    for p in players:
        g = build_style_graph(cycles["truth"], p, threshold_m, seed)
        g_own = build_style_graph(cycles["sim"], p, threshold_m, seed)
        g_on = graph_on_nodes(g, cycles["sim"])
        g2 = graph_on_nodes(g, cycles["truth2"])
        rows.append({"player": p, "nodes": g.n_nodes, "skill_index_truth": g.skill_index,
                     "skill_index_truth2": build_style_graph(cycles["truth2"], p,
                                                             threshold_m,
                                                             seed).skill_index,
                     "skill_index_sim": g_own.skill_index, "nodes_sim": g_own.n_nodes,
                     "similarity_sim": edge_overlap(g, g_on),
                     "similarity_truth2": edge_overlap(g, g2),
                     "cycles_truth": int(g.node_counts.sum()),
                     "cycles_sim": int(g_on.node_counts.sum())})
        ref_graphs.append(g)
        sim_graphs.append(g_on)
    return rows, ref_graphs, sim_graphs
