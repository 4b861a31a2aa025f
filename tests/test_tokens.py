"""Tokens: toy data, rally arrays, windows, targets, augmentation, vocabularies, NaN errors."""

import numpy as np
import pytest
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.toy import make_toy_rallies
from sportsngen.data.tracking import RallyData
from sportsngen.model.bins import Bins
from sportsngen.model.inputs import (
    BALL,
    GENERIC_ID,
    flip_xy,
    object_features,
    score_features,
    score_vector,
)
from sportsngen.train.windows import Augment, WindowDataset, ball_noise_amplitudes, check_finite

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def toy():
    return make_toy_rallies(12, seed=3)


@pytest.fixture(scope="module")
def arrays(toy):
    return rally_arrays(toy, Vocab.from_data(toy))


def test_toy_is_valid_and_deterministic(toy):
    again = make_toy_rallies(12, seed=3)
    assert toy.frames.equals(again.frames) and toy.rallies.equals(again.rallies)
    other = make_toy_rallies(12, seed=4)
    assert not np.allclose(toy.frames["x"].to_numpy()[:100], other.frames["x"].to_numpy()[:100])
    RallyData.from_tables(toy.frames, toy.rallies, toy.shots, toy.fps)  # validates
    ball = toy.frames[toy.frames["object"] == "ball"]
    assert (ball["z"] >= 0).all() and ball["z"].max() > 2.5  # the toss goes up to the serve
    assert (toy.frames.loc[toy.frames["object"] != "ball", "z"] == 0).all()
    for _, g in ball.groupby("rally_id"):  # continuous flight: no teleporting ball
        assert np.linalg.norm(np.diff(g[["x", "y", "z"]].to_numpy(), axis=0), axis=1).max() \
            * toy.fps < 40.0
    # Players never move faster than the toy's speed limit (5 m/s).
    for _, g in toy.frames[toy.frames["object"] != "ball"].groupby(["rally_id", "object"]):
        step = np.hypot(np.diff(g["x"]), np.diff(g["y"])) * toy.fps
        assert step.max() <= 5.0 + 1e-9


def test_rally_arrays_object_order_and_labels(toy, arrays):
    r0 = toy.rallies.iloc[0]
    f = toy.frames[toy.frames["rally_id"] == r0["rally_id"]]
    for slot, name in enumerate([r0["server"], r0["receiver"], "ball"]):
        g = f[f["object"] == name].sort_values("frame")
        np.testing.assert_allclose(arrays.pos_m[:len(g), slot],
                                   g[["x", "y", "z"]].to_numpy(np.float32))
    assert arrays.ident[0, 2] == 0 and arrays.ident[0, 0] >= 2
    assert arrays.length.sum() == len(toy.frames) // 3
    serve_frames = (f[f["object"] == "ball"]["stroke"] == "serve").sum()
    assert (arrays.labels[:arrays.length[0], 0] == 1).sum() == serve_frames  # STROKES[1]


def test_windows_targets_padding_and_velocity(arrays):
    w = 40
    ds = WindowDataset(arrays, w)
    n0 = int(arrays.length[0])
    rows = arrays.pos_m[:n0]
    first = ds[0]
    np.testing.assert_array_equal(first["pos_m"], rows[:w])
    np.testing.assert_array_equal(first["next_pos_m"][:w - 1], rows[1:w])
    assert (first["vel_mps"][0] == 0).all()  # backward difference: nothing before frame 0
    np.testing.assert_allclose(first["vel_mps"][5], (rows[5] - rows[4]) * arrays.fps, rtol=1e-6)
    second = ds[1]  # starts at frame w: its velocity uses frame w - 1 (the past only)
    np.testing.assert_allclose(second["vel_mps"][0], (rows[w] - rows[w - 1]) * arrays.fps,
                               rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(second["t_s"][0], w / arrays.fps)
    # The last window of rally 0 is padded; the rally's last frame has no target.
    last = ds[[i for i, (r, _) in enumerate(ds.items) if r == 0][-1]]
    m = n0 % w or w
    assert last["valid"].sum() == m and last["has_next"].sum() == m - 1
    assert not last["valid"][m:].any() and (last["pos_m"][m:] == 0).all()


def test_flip_maps_targets_consistently(arrays):
    ds = WindowDataset(arrays, 30, Augment(flip=True, ball_noise=False, random_crop=False), 0)
    plain = WindowDataset(arrays, 30)[2]
    flipped = 0
    for _ in range(12):
        s = ds[2]
        if np.array_equal(s["pos_m"], plain["pos_m"]):
            continue
        flipped += 1
        for key in ("pos_m", "vel_mps", "next_pos_m"):
            np.testing.assert_array_equal(s[key], flip_xy(plain[key]))
    assert 0 < flipped < 12
    # Bins of the flipped offsets mirror those of the original in x and y, z unchanged.
    bins = Bins((2.0, 1.0, 1.0), 21, "uniform")
    off = torch.tensor(plain["next_pos_m"] - plain["pos_m"])[:, BALL]
    off_f = torch.tensor(flip_xy(plain["next_pos_m"]) - flip_xy(plain["pos_m"]))[:, BALL]
    i, j = bins.index(off), bins.index(off_f)
    assert torch.equal(j[:, :2], 20 - i[:, :2]) and torch.equal(j[:, 2], i[:, 2])


def test_ball_noise_bounded_and_scaled_to_frame_rate(arrays):
    p25, v25 = ball_noise_amplitudes(25.0)
    np.testing.assert_allclose(p25, [0.025, 0.0125, 0.0125])
    np.testing.assert_allclose(v25, [0.625, 0.3125, 0.3125])
    p50, v50 = ball_noise_amplitudes(50.0)
    np.testing.assert_allclose(p50, p25 / 2)
    np.testing.assert_allclose(v50, v25)
    plain = WindowDataset(arrays, 30)[0]
    s = WindowDataset(arrays, 30, Augment(flip=False, ball_noise=True, random_crop=False), 1)[0]
    dp = s["pos_m"] - plain["pos_m"]
    dv = s["vel_mps"] - plain["vel_mps"]
    assert (dp[:, :BALL] == 0).all() and (dv[:, :BALL] == 0).all()  # players untouched
    above = plain["pos_m"][:, BALL, 2] > 0.02
    assert (np.abs(dp[above, BALL]) <= p25 + 1e-6).all() and np.abs(dp[:, BALL]).max() > 0.005
    assert (np.abs(dv[:, BALL]) <= v25 + 1e-5).all()
    np.testing.assert_array_equal(s["next_pos_m"], plain["next_pos_m"])  # targets stay clean


def test_player_shift_moves_each_players_window_and_keeps_his_moves(arrays):
    plain = WindowDataset(arrays, 30)[0]
    shifts = []
    for seed in range(40):
        s = WindowDataset(arrays, 30, Augment(flip=False, random_crop=False,
                                              player_shift_m=0.4), seed)[0]
        d = s["pos_m"] - plain["pos_m"]
        m = plain["valid"]
        # One constant horizontal offset a player for the window; ball and heights untouched.
        assert np.allclose(d[m, :BALL, :2], d[:1, :BALL, :2], atol=1e-5)
        assert (d[:, BALL] == 0).all() and (d[:, :BALL, 2] == 0).all()
        assert (d[~m] == 0).all()
        n = plain["has_next"]
        np.testing.assert_allclose((s["next_pos_m"] - s["pos_m"])[n],
                                   (plain["next_pos_m"] - plain["pos_m"])[n], atol=1e-5)
        np.testing.assert_array_equal(s["vel_mps"], plain["vel_mps"])
        shifts.append(d[0, :BALL, :2])
    r = np.linalg.norm(np.concatenate(shifts), axis=-1)
    assert r.max() <= 0.4 + 1e-6 and r.max() > 0.3
    # Uniform in the disc: a quarter of them inside half the radius.
    assert 0.1 < (r < 0.2).mean() < 0.45
    assert not np.allclose(shifts[0][0], shifts[0][1])   # each player his own


def test_random_crops_vary_and_stay_consistent(arrays):
    ds = WindowDataset(arrays, 20, Augment(flip=False, ball_noise=False, random_crop=True), 0)
    i = next(k for k, (r, _) in enumerate(ds.items) if arrays.length[r] > 60)
    starts = {round(float(ds[i]["t_s"][0]) * arrays.fps) for _ in range(10)}
    assert len(starts) > 1
    s = ds[i]
    r = ds.items[i][0]
    k0 = round(float(s["t_s"][0]) * arrays.fps)
    rows = arrays.pos_m[arrays.start[r]:arrays.start[r] + arrays.length[r]]
    np.testing.assert_array_equal(s["pos_m"], rows[k0:k0 + 20])


def test_features_shape_and_normalisation():
    pos = torch.zeros(1, 2, 3, 3)
    pos[0, :, 0, 0] = 11.885   # server on the baseline
    pos[0, :, 2] = torch.tensor([0.0, 0.0, 3.0])  # ball 3 m up above the net centre
    f = object_features(pos, torch.zeros_like(pos), torch.tensor([[0.0, 5.0]]))
    assert f.shape == (1, 2, 3, 8)
    assert f[0, 0, 0, 0] == pytest.approx(1.0) and f[0, 0, 2, 2] == pytest.approx(1.0)
    assert f[0, 0, 2, 6] == 0.0  # distance of the ball to itself
    assert f[0, 0, 0, 6] == pytest.approx(np.hypot(11.885, 3.0) / 10.0, rel=1e-6)
    assert f[0, 1, 1, 7] == pytest.approx(0.5)


def test_score_vector_values():
    v = score_vector(1, 0, 3, 6, 2, 4, True)
    np.testing.assert_allclose(v, [1 / 3, 0, 0.5, 1.0, 0.5, 1.0, 1.0])
    # Deuce-reduced: 5-5 in a game is 40-40 (3-3), 9-8 in a tie-break is 7-6.
    np.testing.assert_allclose(score_vector(0, 0, 0, 0, 5, 5, False)[4:6], [0.75, 0.75])
    np.testing.assert_allclose(score_vector(0, 0, 6, 6, 9, 8, True)[4:6], [7 / 4, 6 / 4])
    np.testing.assert_allclose(score_features([1, 0, 3, 6, 2, 4, 1, 0, 1, 0, 0, 0, 0]), v)


def test_vocab_unknown_policies(toy):
    v = Vocab.from_data(toy)
    assert v.player_index(v.players[0]) == 2
    with pytest.warns(UserWarning, match="unknown player 'Nobody'"):
        assert v.player_index("Nobody", "warn") == GENERIC_ID
    with pytest.raises(ValueError, match="unknown player 'Nobody'"):
        v.player_index("Nobody", "error")
    with pytest.raises(ValueError, match="unknown surface 'ice'"):
        v.surface_index("ice", "error")
    assert Vocab.from_data(toy, generic=True).player_index(v.players[0]) == GENERIC_ID
    w = v.with_player("New Guy")
    assert w.players[:-1] == v.players and w.player_index("New Guy") == v.n_ids
    assert Vocab.from_dict(w.to_dict()) == w


def test_nan_in_batch_names_the_rally(arrays):
    batch = default_collate([WindowDataset(arrays, 20)[i] for i in range(3)])
    check_finite(batch)  # clean batch passes
    batch["pos_m"][1, 4, 2, 0] = float("nan")
    with pytest.raises(ValueError, match=f"rally {int(batch['rally_id'][1])}"):
        check_finite(batch)


def test_missing_object_is_an_error_naming_the_rally(toy):
    f = toy.frames
    rid = int(toy.rallies["rally_id"].iloc[1])
    drop = f.index[(f["rally_id"] == rid) & (f["object"] == "ball") & (f["frame"] > 10)]
    sub = RallyData(f.drop(drop).reset_index(drop=True), toy.rallies, toy.shots, toy.fps)
    with pytest.raises(ValueError, match=f"rally {rid}"):
        rally_arrays(sub, Vocab.from_data(toy))


def test_near_contact_flags_frames_around_each_shot(toy, arrays):
    """A frame is near contact exactly when it is within one frame of a shot's frame (clipped
    to the rally), and the flag follows rallies through select() and into windows."""
    for i, rid in enumerate(toy.rallies["rally_id"]):
        n = int(arrays.length[i])
        expected = np.zeros(n, dtype=bool)
        for f in toy.shots.loc[toy.shots["rally_id"] == rid, "frame"]:
            expected[max(f - 1, 0):min(f + 2, n)] = True
        got = arrays.near_contact[arrays.start[i]:arrays.start[i] + n]
        np.testing.assert_array_equal(got, expected)
    sub = arrays.select(np.array([3, 1]))
    np.testing.assert_array_equal(
        sub.near_contact[:sub.length[0]],
        arrays.near_contact[arrays.start[3]:arrays.start[3] + arrays.length[3]])
    ds = WindowDataset(arrays, 30)
    assert ds.items[1] == (0, 30)
    win = ds[1]  # rally 0, frames 30..59
    n0 = int(arrays.length[0])
    np.testing.assert_array_equal(win["near_contact"][:min(30, n0 - 30)],
                                  arrays.near_contact[30:min(60, n0)])
    assert not win["near_contact"][win["valid"] == 0].any()
