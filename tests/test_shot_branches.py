"""The branches after a recorded return and the share the model's server strikes back."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_branches import (
    answer_share,
    landing_gaps_m,
    shot_branches,
    shot_outcomes,
    strike_shares,
)
from sportsngen.tennis.court import is_in_singles
from tests.conftest import tiny_sim


def test_shot_outcomes_agree_with_the_generators_shots_table():
    truth = truth_points(DiagnosticsSetup(n_points=80, seed=6))
    out = shot_outcomes(truth)
    assert shot_outcomes(truth, 1, analyse_rally_data(truth)).equals(out)   # rules read once
    shots = truth.shots
    ret = shots[shots["shot_index"] == 1].set_index("rally_id")
    third = set(shots.loc[shots["shot_index"] == 2, "rally_id"])
    assert out["struck"].sum() == len(ret) > 15
    assert 10 < out["in_play"].sum() < out["struck"].sum()     # some returns are errors
    for rid, row in out.iterrows():
        assert row["struck"] == (rid in ret.index)
        assert row["in_play"] == (rid in ret.index and ret.at[rid, "outcome"] != "error")
        assert row["answered"] == (rid in third)
        assert (row["contact_frame"] >= 0) == row["struck"]
    # A return that bounced before it was struck again stayed in play exactly when that bounce
    # lies in the server's singles court (a volleyed return has no bounce of its own).
    server_end = truth.rallies.set_index("rally_id")["server_end"]
    bounced = out[out["struck"] & out["bounce_x_m"].notna()]
    assert len(bounced) > 12
    inside = is_in_singles(bounced["bounce_x_m"].to_numpy(), bounced["bounce_y_m"].to_numpy(),
                           server_end.loc[bounced.index].to_numpy())
    assert (inside == bounced["in_play"].to_numpy()).all()
    with pytest.raises(ValueError, match="after the serve"):
        shot_outcomes(truth, 0)


def test_answer_share_on_known_branches():
    truth = pd.DataFrame({"in_play": [True] * 4, "answered": [True, True, True, False]},
                         index=[10, 11, 12, 13])
    branch = pd.DataFrame({"in_play": [True, True, False, True],
                           "answered": [True, False, False, False]}, index=[0, 1, 2, 3])
    order = pd.Series([10, 11, 12, 13], index=[0, 1, 2, 3])
    got = answer_share(branch, truth, order)
    assert got == {"model": pytest.approx(1 / 3), "data": 0.75, "n": 3, "in_play": 0.75}
    truth["bounce_x_m"], truth["bounce_y_m"] = [1.0, 2.0, 3.0, 4.0], [0.0] * 4
    branch["bounce_x_m"] = [1.0, 5.0, np.nan, 1.0]
    branch["bounce_y_m"] = [0.0, 4.0, np.nan, 0.0]
    np.testing.assert_allclose(landing_gaps_m(branch, truth, order), [0.0, 5.0, 3.0])
    # A branch the rules could not read (no row) counts as not in play.
    got = answer_share(branch.drop(index=[0]), truth, order)
    assert got["n"] == 2 and got["model"] == 0.0 and got["in_play"] == 0.5


def test_return_branches_keep_the_record_up_to_three_frames_after_the_return(tiny_model_file,
                                                                             truth_data):
    sim = tiny_sim(tiny_model_file)
    truth = truth_data(40, 4)
    out = shot_outcomes(truth)
    with pytest.warns(UserWarning, match="unknown player"):
        branches, order = shot_branches(sim, truth, after_frames=3, seed=0, truth_out=out)
    assert sorted(order.to_numpy()) == sorted(out.index[out["in_play"]])
    rec = rally_arrays(truth, Vocab.from_data(truth, generic=True))
    got = rally_arrays(branches, Vocab.from_data(branches, generic=True))
    rec_at = {rid: i for i, rid in enumerate(rec.rally_id)}
    for gi, bid in enumerate(got.rally_id):
        ri = rec_at[int(order[bid])]
        k = int(out.at[int(order[bid]), "contact_frame"]) + 4
        kept = got.pos_m[got.start[gi]:got.start[gi] + k]
        np.testing.assert_allclose(kept, rec.pos_m[rec.start[ri]:rec.start[ri] + k], atol=1e-5)
        assert got.length[gi] > k                  # and the model played on


class _Replay:
    """A stand-in simulator whose rollouts replay the recorded rally they branched from (the
    one whose first frames they were given), under the plan's rally id."""

    fps = 25.0

    def __init__(self, truth: RallyData):
        self.truth = truth
        self.vocab = Vocab.from_data(truth, generic=True)
        arr = rally_arrays(truth, self.vocab)
        self.tracks = {int(r): arr.pos_m[s:s + n]
                       for r, s, n in zip(arr.rally_id, arr.start, arr.length)}
        self.calls = []

    def simulate_rallies(self, plan, seed, init_pos_m, max_duration_s, forced_pos_m=None,
                         init_frames=None, label_events=True):
        kept = np.full(len(plan), init_pos_m.shape[1]) if init_frames is None else init_frames
        self.calls.extend(int(k) for k in kept)
        parts = []
        for new_id, init, k in zip(plan["rally_id"], init_pos_m, kept):
            rid, = [r for r, t in self.tracks.items()
                    if len(t) > k and np.array_equal(t[:k], init[:k])]
            one = self.truth.subset([rid])
            tables = {name: getattr(one, name).assign(rally_id=int(new_id))
                      for name in ("frames", "rallies", "shots")}
            parts.append(RallyData(**tables, fps=one.fps))
        return RallyData.concat(parts)


def test_strike_shares_of_a_replay_are_the_records():
    # A "model" that plays the record again keeps exactly the record's shares, shot by shot,
    # and every branch starts at its own recorded contact (the frames before it only).
    truth = truth_points(DiagnosticsSetup(n_points=60, seed=2))
    rules = analyse_rally_data(truth)       # read once: the rules are most of this test's time
    sim = _Replay(truth)
    table = strike_shares(sim, truth, shots=(1, 2, 3), seed=0, rules=rules)
    assert table["shot"].tolist() == [1, 2, 3]
    assert table["hitter"].tolist() == ["receiver", "server", "receiver"]
    for row in table.itertuples():
        rec = shot_outcomes(truth, row.shot, rules)
        rec = rec[rec["struck"]]
        assert row.n == len(rec) > 0
        assert row.recorded_in_play == pytest.approx(rec["in_play"].mean())
        assert row.model_struck == 1.0
        assert row.model_in_play == pytest.approx(row.recorded_in_play)
        assert row.model_answered == pytest.approx(row.recorded_answered)
        assert row.model_side_m == pytest.approx(row.recorded_side_m)
        in_bounds = rec.loc[rec["in_play"], "bounce_y_m"].abs().dropna()
        assert row.recorded_side_m == pytest.approx(in_bounds.median())
        assert 0.0 < row.recorded_side_m < 4.115   # inside a singles half-width
    first_return = shot_outcomes(truth, 1, rules)
    first_return = first_return[first_return["struck"]]
    assert min(sim.calls) == first_return["contact_frame"].min()
    assert table.loc[0, "recorded_in_play"] < 1.0   # some returns are errors: the test can tell
