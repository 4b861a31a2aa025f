"""What the bins alone cost a rollout (`sportsngen.eval.bin_resolution`), without a model."""

import pytest

from sportsngen.eval.bin_resolution import centre_noise_drift, serves_redrawn_in_bins


def test_centre_bin_noise_is_integrated_three_times_by_the_track_acceleration():
    track = centre_noise_drift(n_flights=500, frames=(10, 25))
    plain = centre_noise_drift(n_flights=500, frames=(10, 25), use_track_acceleration=False)
    # Under a millimetre a frame, yet a quarter of a metre across the flight after a second
    # (gravity and drag: 3 cm). Along it (x) the step drops what the track reads, so the noise
    # stays as small as with gravity and drag alone.
    assert track[25][1:].min() > 0.2 and plain[25].max() < 0.1
    assert track[25][0] < 0.1
    assert track[25][1] > 5 * track[10][1]
    # Finer bins near the centre (241 non-uniform: 1/16 the width) shrink it with them.
    fine = centre_noise_drift(n_flights=500, frames=(10,), n_bins=241)
    assert fine[10][1] < track[10][1] / 8


@pytest.fixture(scope="module")
def truth(truth_data):
    return truth_data(160, 2)


def test_serves_redrawn_in_their_bins_land_in_the_box_less_often(truth):
    coarse = serves_redrawn_in_bins(truth, n_bins=61)
    fine = serves_redrawn_in_bins(truth, n_bins=2001)
    assert coarse["n"] == fine["n"] > 40
    # The flight loop itself follows the record (the rules' bounce) closely ...
    assert coarse["loop"] == fine["loop"]
    assert abs(coarse["loop"] - coarse["record"]) < 0.06
    # ... so what bins of 2001 lose is small, and bins of 61 lose a third of the serves.
    assert abs(fine["redrawn"] - fine["loop"]) < 0.05
    assert coarse["redrawn"] < coarse["loop"] - 0.2


def test_strikes_redrawn_in_their_bins_and_in_parts_of_them(truth):
    from sportsngen.eval.bin_resolution import strikes_redrawn_in_bins

    coarse = strikes_redrawn_in_bins(truth, shots=(1, 2))
    parts = strikes_redrawn_in_bins(truth, shots=(1, 2), n_sub=32)
    shots = truth.shots
    for row in coarse.itertuples():
        rec = shots[shots["shot_index"] == row.shot]
        assert row.n > 15 and row.n <= len(rec)
    assert (coarse["n"] == parts["n"]).all()
    assert (coarse["loop_in_play"] == parts["loop_in_play"]).all()
    # The loop follows the record up to what it leaves out (the net: a return into it flies
    # on to a bounce, at most one strike more); uniform inside 61 bins loses a large share of
    # the strikes, the recorded part of 32 keeps them (within a strike or two).
    ret = coarse.iloc[0]
    errors = shots[(shots["shot_index"] == 1) & (shots["outcome"] == "error")]
    detail = truth.rallies.set_index("rally_id")["end_detail"]
    into_net = int((detail.loc[errors["rally_id"]] == "net").sum())
    assert 0.0 <= ret["loop_in_play"] - ret["record_in_play"] <= (into_net + 1) / ret["n"]
    lost = (coarse["loop_in_play"] - coarse["redrawn_in_play"]).sum()
    kept = (parts["loop_in_play"] - parts["redrawn_in_play"]).abs().max()
    assert lost > 0.2 and kept < 2.5 / coarse["n"].min()
