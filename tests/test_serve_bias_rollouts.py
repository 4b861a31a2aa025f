"""The per-server serve shifts refitted on rollouts (`sportsngen.train.serve_bias_rollouts`):
the record's fault shares read from rally labels, and the update that meets them, against a
stub simulator whose fault odds are known in closed form."""

import numpy as np
import pandas as pd
import pytest
import torch

from sportsngen.data.tokens import RallyArrays, Vocab
from sportsngen.data.tracking import ERROR_KINDS
from sportsngen.model import serve_bias
from sportsngen.model.inputs import N_SPECIAL_IDS
from sportsngen.sim.simulator import points_plan
from sportsngen.train.serve_bias_rollouts import (
    ROLLOUT_S,
    recorded_fault_shares,
    refine_serve_bias,
    rollout_fault_share,
    top_receivers,
)

FAULT = ERROR_KINDS.index("fault")
PLAYERS = ("A", "B", "C")


def arrays(rallies: list[tuple[int, int, int, bool]]) -> RallyArrays:
    """Rallies of (server_id, receiver_id, serve, fault), 4 frames each; a fault's label on
    its second frame."""
    k = len(rallies)
    n = 4 * k
    labels = np.zeros((n, 4), np.int64)
    ident = np.zeros((k, 3), np.int64)
    serve = np.zeros(k, np.int64)
    for i, (s, r, srv, fault) in enumerate(rallies):
        ident[i] = (s, r, 0)
        serve[i] = srv
        if fault:
            labels[4 * i + 1, 3] = FAULT
    return RallyArrays(np.zeros((n, 3, 3), np.float32), labels, np.zeros(n, bool),
                       np.arange(0, n, 4, dtype=np.int64), np.full(k, 4, np.int64),
                       np.arange(k), ident, np.zeros(k, np.int64), np.zeros(k, np.int64),
                       serve, np.zeros((k, 7), np.float32), 25.0)


A, B, C = (N_SPECIAL_IDS + i for i in range(3))


def test_recorded_fault_shares_count_labelled_rallies_by_server_and_serve():
    a = arrays([(A, B, 0, True), (A, B, 0, False), (A, C, 0, False), (A, C, 1, True),
                (B, A, 0, False)])
    b = arrays([(A, B, 0, True)])
    got = recorded_fault_shares([a, b]).set_index(["server_id", "serve"])
    assert got.loc[(A, 0), "n"] == 4 and got.loc[(A, 0), "faults"] == 2
    assert got.loc[(A, 0), "share"] == 0.5
    assert got.loc[(A, 1), "share"] == 1.0
    assert got.loc[(B, 0), "share"] == 0.0 and got.loc[(B, 0), "n"] == 1


def test_top_receivers_orders_by_count_and_rejects_an_unknown_server():
    a = arrays([(A, C, 0, False), (A, C, 0, False), (A, B, 0, False), (B, A, 0, False)])
    assert top_receivers([a], A) == [C, B]
    assert top_receivers([a], A, k=1) == [C]
    with pytest.raises(ValueError, match="serves no rally"):
        top_receivers([a], C)


class StubSim:
    """A simulator whose serves fault with odds logit p = base + (the long shift + the wide
    shift) / 2 of the plan's server and serve, faults laid out exactly (round(p n))."""

    def __init__(self, base: dict[tuple[int, int], float]):
        self.vocab = Vocab(players=PLAYERS)
        self.model = type("M", (), {})()
        self.model.serve_bias = torch.zeros(N_SPECIAL_IDS + 3, serve_bias.N_SERVES,
                                            serve_bias.N_KINDS)
        self.base = base
        self.calls = []

    def simulate_rallies(self, plan: pd.DataFrame, seed: int = 0, max_duration_s=None):
        self.calls.append((len(plan), max_duration_s))
        sid = self.vocab.player_index(plan["server"].iloc[0])
        srv = int(plan["serve_number"].iloc[0]) - 1
        shift = self.model.serve_bias[sid, srv, :2].mean().item()
        p = 1.0 / (1.0 + np.exp(-(self.base[(sid, srv)] + shift)))
        n = len(plan)
        k = int(round(p * n))
        reason = ["fault" if srv == 0 else "double_fault"] * k + ["none"] * (n - k)
        return type("D", (), {"rallies": pd.DataFrame({"end_reason": reason})})()


def test_rollout_fault_share_spreads_serves_over_receivers_and_surfaces():
    sim = StubSim({(A, 0): 0.0})
    faults, n = rollout_fault_share(sim, "A", ["B", "C"], 1, 60, seed=0)
    assert n == 60 and faults == 30                       # 2 receivers x 3 surfaces x 10
    assert sim.calls == [(60, ROLLOUT_S)]


def test_refine_meets_the_records_share_and_leaves_others_alone():
    # A's first serves fault 0.2 in rollouts and 0.35 in the record; his second 0.10 / 0.05.
    base = {(A, 0): float(np.log(0.2 / 0.8)), (A, 1): float(np.log(0.1 / 0.9))}
    sim = StubSim(base)
    rec = [(A, B, 0, i < 35) for i in range(100)] + [(A, B, 1, i < 5) for i in range(100)]
    table = refine_serve_bias(sim, [arrays(rec)], ["A"], n_serves=3000, rounds=2,
                              log=lambda s: None)
    last = table[table["round"] == 2].set_index("serve")
    assert last.loc[1, "rollout_share"] == pytest.approx(0.35, abs=2e-3)
    assert last.loc[2, "rollout_share"] == pytest.approx(0.05, abs=2e-3)
    # The first round's full step is exact for logit-linear odds; the second moves nothing.
    first = table[(table["round"] == 0)].set_index("serve")
    want = np.log(0.35 / 0.65) - np.log(0.2 / 0.8)
    assert first.loc[1, "step"] == pytest.approx(want, abs=3e-3)
    assert float(sim.model.serve_bias[A, 0, serve_bias.LONG]) == pytest.approx(want, abs=5e-3)
    assert float(sim.model.serve_bias[A, 0, serve_bias.WIDE]) == pytest.approx(want, abs=5e-3)
    assert float(sim.model.serve_bias[A, 0, serve_bias.SPEED]) == 0.0
    assert sim.model.serve_bias[B].abs().sum() == 0


def test_refine_rejects_a_model_without_the_table_and_bad_sizes():
    sim = StubSim({})
    a = arrays([(A, B, 0, False)])
    with pytest.raises(ValueError, match="n_serves"):
        refine_serve_bias(sim, [a], ["A"], n_serves=5)
    sim.model.serve_bias = None
    with pytest.raises(ValueError, match="no per-server table"):
        refine_serve_bias(sim, [a], ["A"])


def test_points_plan_is_seeded_and_alternates_ends():
    p = points_plan("A", "B", "clay", 6, seed=3, serve_number=2)
    q = points_plan("A", "B", "clay", 6, seed=3, serve_number=2)
    pd.testing.assert_frame_equal(p, q)
    assert list(p["server_end"]) == [1, -1, 1, -1, 1, -1]
    assert (p["serve_number"] == 2).all() and (p["surface"] == "clay").all()
    sides = np.where((p["server_points"] + p["receiver_points"]) % 2 == 0, "deuce", "ad")
    assert (p["side"] == sides).all()
