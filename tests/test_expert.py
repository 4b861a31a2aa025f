"""The generator as expert on a model's own rollouts (sportsngen.train.expert)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sportsngen.data.tokens import RallyArrays
from sportsngen.model.inputs import BALL
from sportsngen.synth import physics
from sportsngen.synth.profiles import get_profile
from sportsngen.synth.rally import continue_rally, play_rally
from sportsngen.train.expert import (
    ExpertConfig,
    ball_state,
    bounce_frames,
    load_expert,
    rally_state,
    save_expert,
    spin_from_lift,
)
from sportsngen.train.windows import Augment, WindowDataset

FPS = 25.0


def _magnus_acc(vel: np.ndarray, spin: float) -> np.ndarray:
    """Gravity + drag + Magnus of the generator's model (physics._accel), in 3-D."""
    aero = physics.DEFAULT_AERO
    kcd, kl, tas, g = physics._coeffs(spin, aero)
    vh = float(np.hypot(vel[0], vel[1]))
    au, az = physics._accel(vh, float(vel[2]), kcd, kl, tas, g)
    u = vel[:2] / vh
    return np.array([au * u[0], au * u[1], az])


@pytest.mark.parametrize("spin", [-6.0, 0.0, 4.0, 10.0])
@pytest.mark.parametrize("vel", [(30.0, 2.0, 3.0), (-25.0, -4.0, -2.0), (12.0, 0.5, 6.0)])
def test_spin_from_lift_inverts_the_generators_magnus(spin, vel):
    v = np.array(vel)
    assert spin_from_lift(v, _magnus_acc(v, spin)) == pytest.approx(spin, abs=1e-6)


def test_spin_from_lift_of_a_slow_ball_is_zero():
    v = np.array([1.0, 0.0, 2.0])
    assert spin_from_lift(v, _magnus_acc(v, 8.0)) == 0.0


def _framed(flight: physics.Flight, n: int) -> np.ndarray:
    return np.stack([flight.at(i / FPS) for i in range(n)])


def test_ball_state_reads_velocity_and_spin_of_a_generator_flight():
    spin = 7.0
    vel0 = np.array([28.0, 1.5, 4.0])
    flight = physics.fly([-11.0, 0.5, 1.0], vel0, spin, "hard", 0.6, net=False)
    track = _framed(flight, 12)
    assert not len(bounce_frames(track[:, 2]))
    pos, vel, got_spin = ball_state(track, FPS)
    assert np.allclose(pos, track[-1])
    true_vel = np.interp(11 / FPS, flight.t_s, flight.vel_mps[:, 0]), \
        np.interp(11 / FPS, flight.t_s, flight.vel_mps[:, 2])
    assert vel[0] == pytest.approx(true_vel[0], abs=0.05)
    assert vel[2] == pytest.approx(true_vel[1], abs=0.05)
    assert got_spin == pytest.approx(spin, abs=1.0)


def test_ball_state_refuses_a_flight_just_after_a_bounce():
    flight = physics.fly([-3.0, 0.0, 1.0], [20.0, 0.0, -6.0], 5.0, "hard", 1.0, net=False)
    track = _framed(flight, 25)
    b = int(bounce_frames(track[:, 2])[0])
    assert ball_state(track[:b + 2], FPS) is None        # one frame since the bounce
    read = ball_state(track[:b + 6], FPS)                 # five: read from those alone
    assert read is not None and read[1][2] > 0            # rising again


def _rally(seed: int = 3):
    fed, nad = get_profile("Roger Federer"), get_profile("Rafael Nadal")
    rng = np.random.default_rng(seed)
    while True:
        r = play_rally(fed, nad, 1, "deuce", 1, "hard", rng)
        if len(r.shots) >= 4:
            pos = np.zeros((r.n_frames, 3, 3))
            pos[:, BALL] = r.ball_m
            pos[:, :BALL, :2] = np.transpose(r.players_m, (1, 0, 2))
            return fed, nad, r, pos


def test_the_expert_continues_a_recorded_flight_as_recorded():
    fed, nad, r, pos = _rally()
    errors = []
    for si in range(1, len(r.shots) - 1):
        c = int(np.ceil(r.shots[si].t_s * FPS))
        c2 = int(np.floor(r.shots[si + 1].t_s * FPS))
        for h in range(c + 6, c2 - 6, 3):
            state = rally_state(pos, h, c, r.shots[si].hitter, si + 1, FPS)
            if state is None or state.bounces:
                continue
            res = continue_rally(fed, nad, state, 1, "deuce", 1, "hard",
                                 np.random.default_rng(0))
            errors.append(np.linalg.norm(res.ball_m[1:6] - r.ball_m[h + 1:h + 6], axis=1).max())
            assert state.last_hitter == r.shots[si].hitter
    assert len(errors) >= 10
    assert np.median(errors) < 0.02         # 2 cm over five frames of flight


def test_rally_state_refuses_a_ball_struck_back():
    _, _, r, pos = _rally()
    c = int(np.ceil(r.shots[1].t_s * FPS))
    c2 = int(np.ceil(r.shots[2].t_s * FPS))
    assert rally_state(pos, c2 - 2, c, r.shots[1].hitter, 2, FPS) is not None
    assert rally_state(pos, c2 + 6, c, r.shots[1].hitter, 2, FPS) is None


def _arrays(lengths, learn=None) -> RallyArrays:
    lengths = np.asarray(lengths, dtype=np.int64)
    n = int(lengths.sum())
    pos = np.zeros((n, 3, 3), dtype=np.float32)
    pos[:, :, 0] = np.arange(n, dtype=np.float32)[:, None]
    k = len(lengths)
    return RallyArrays(pos, np.zeros((n, 4), np.int64), np.zeros(n, bool),
                       np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64), lengths,
                       np.arange(k), np.zeros((k, 3), np.int64), np.zeros(k, np.int64),
                       np.zeros(k, np.int64), np.zeros(k, np.int64), np.zeros((k, 7), np.float32),
                       FPS, learn_from=None if learn is None else np.asarray(learn, np.int64))


def test_window_targets_start_at_learn_from():
    a = _arrays([40, 300], learn=[25, 200])
    ds = WindowDataset(a, 20)
    first = ds[0]                                  # rally 0, frames 0-19: all inputs
    assert not first["has_next"].any()
    second = ds[1]                                 # rally 0, frames 20-39
    assert second["has_next"].tolist() == [i >= 5 for i in range(19)] + [False]
    aug = WindowDataset(a, 50, Augment(flip=False), seed=1)
    for i in range(len(aug)):
        item = aug[i]
        ri = 0 if item["rally_id"] == 0 else 1
        assert item["has_next"].any(), "a training window of an expert rally holds a target"
        start = int(round(item["t_s"][0] * FPS))
        assert start + 50 > a.learn_from[ri]


def test_concat_and_select_keep_learn_from():
    plain, expert = _arrays([10, 12]), _arrays([30], learn=[7])
    both = RallyArrays.concat([plain, expert])
    assert both.length.tolist() == [10, 12, 30]
    assert both.learn_from_frames().tolist() == [0, 0, 7]
    assert np.array_equal(both.pos_m[22:], expert.pos_m)
    assert both.select(np.array([2])).learn_from.tolist() == [7]
    assert RallyArrays.concat([plain]).learn_from is None


def test_save_and_load_expert(tmp_path):
    a = _arrays([30, 20], learn=[7, 3])
    back = load_expert(save_expert(a, tmp_path / "e.npz"))
    assert back.learn_from.tolist() == [7, 3]
    assert np.array_equal(back.pos_m, a.pos_m) and back.fps == FPS
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="not an expert-rally file"):
        load_expert(tmp_path / "other.npz")
    with pytest.raises(FileNotFoundError, match="expert_data.py"):
        load_expert(tmp_path / "missing.npz")


def test_expert_config_checks():
    with pytest.raises(ValueError, match="min_model_frames"):
        ExpertConfig(min_model_frames=10, max_model_frames=5)
    with pytest.raises(ValueError, match="n_branches"):
        ExpertConfig(n_branches=0)


@pytest.fixture(scope="module")
def generated():
    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.synth import generate_matches

    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", 12, seed=5, workers=1)
    vocab = Vocab.from_data(data)
    return data, vocab, rally_arrays(data, vocab)


def test_expert_rallies_are_record_then_expert(generated, monkeypatch):
    from sportsngen.train import expert

    data, vocab, arrays = generated

    def recorded(sim, data, arrays, branches, cfg, progress=False):
        return {int(i): arrays.pos_m[arrays.start[ri]:arrays.start[ri] + arrays.length[ri]]
                for i, ri in zip(branches.index, branches["ri"])}

    monkeypatch.setattr(expert, "_rollouts", recorded)
    profiles = {n: get_profile(n) for n in ("Roger Federer", "Rafael Nadal")}
    cfg = ExpertConfig(n_branches=20, min_model_frames=4, max_model_frames=12, keep_frames=30)
    pos = np.arange(len(arrays))
    out, counts = expert.expert_arrays(None, data, arrays, pos, profiles, cfg)
    assert counts["kept"] == len(out) >= 5
    assert counts["kernel_refused"] == 0
    assert counts["kept"] + counts["ended"] + counts["no_flight"] == counts["branches"]
    branches = expert.branch_points(data, arrays, pos, cfg)
    assert (branches["start"] - branches["contact"] == 2).all()
    assert (branches["last"] - branches["start"] >= 4).all()
    jumps = []
    for i in range(len(out)):
        h = int(out.learn_from[i])
        track = out.pos_m[out.start[i]:out.start[i] + out.length[i]]
        assert 0 < h < len(track) - 1 and len(track) - 1 - h <= 30
        # Up to the hand-over the rally is a recorded one's first frames.
        src = [ri for ri in range(len(arrays)) if arrays.length[ri] > h and np.array_equal(
            arrays.pos_m[arrays.start[ri]:arrays.start[ri] + h + 1], track[:h + 1])]
        assert src, "the frames before the hand-over are the (here recorded) rollout"
        jumps.append(np.linalg.norm(track[h + 1, BALL] - 2 * track[h, BALL] + track[h - 1, BALL]))
    # The expert's first frame continues the flight (a second difference of one frame's
    # gravity and drag, not a jump).
    assert np.median(jumps) < 0.05
    assert (out.rally_id < 0).all() and out.ident.shape == (len(out), 3)


def test_datamodule_mixes_expert_rallies_into_training_only(tmp_path):
    from omegaconf import OmegaConf

    from sportsngen.data.tokens import Vocab, rally_arrays
    from sportsngen.data.toy import make_toy_rallies
    from sportsngen.train.datamodule import TrackingDataModule
    from sportsngen.train.run import _expert_arrays

    data = make_toy_rallies(10, 0, FPS)
    vocab = Vocab.from_data(data)
    extra = rally_arrays(data, vocab).select(np.array([0, 1, 2]))
    extra.learn_from = extra.length // 2
    path = save_expert(extra, tmp_path / "e.npz")
    cfg = OmegaConf.create({"expert": {"path": str(path)}})
    loaded = _expert_arrays(cfg, vocab)
    dm = TrackingDataModule(data, vocab, 20, val_fraction=0.2, extra_train=loaded)
    dm.setup()
    assert len(dm.train_arrays) == 8 + 3 and len(dm.val_arrays) == 2
    assert dm.train_arrays.learn_from_frames().tolist()[-3:] == extra.learn_from.tolist()
    assert dm.val_arrays.learn_from is None
    extra.ident[0, 0] = vocab.n_ids + 5
    save_expert(extra, path)
    with pytest.raises(ValueError, match="beyond this model"):
        _expert_arrays(cfg, vocab)
    assert _expert_arrays(OmegaConf.create({"expert": {"path": None}}), vocab) is None


def test_serve_return_fidelity_counts_the_recorded_returns(generated):
    from sportsngen.train.expert import serve_return_fidelity

    data, vocab, arrays = generated
    profiles = {n: get_profile(n) for n in ("Roger Federer", "Rafael Nadal")}
    pos = np.arange(len(arrays))
    out = serve_return_fidelity(data, arrays, pos, profiles, frames_after=2, n_branches=400)
    shots = data.shots
    serves = shots[shots["shot_index"] == 0]
    in_play = set(serves.loc[serves["outcome"] != "error", "rally_id"])
    returned = set(shots.loc[shots["shot_index"] == 1, "rally_id"])
    # Every serve in play is a branch here (400 > the rallies): the record's share is exact.
    branches = expert_branch_ids(data, arrays, pos)
    ids = [r for r in branches if r in in_play]
    assert out["n"] == len(ids) > 5
    assert out["recorded_returned"] == pytest.approx(np.mean([r in returned for r in ids]))
    assert 0.0 <= out["expert_returned"] <= 1.0
    assert out == serve_return_fidelity(data, arrays, pos, profiles, 2, n_branches=400)


def expert_branch_ids(data, arrays, pos):
    from sportsngen.train.expert import ExpertConfig, branch_points

    br = branch_points(data, arrays, pos, ExpertConfig(n_branches=400))
    return br.loc[br["n_shots"] == 1, "rally_id"].tolist()


def test_late_contacts_fly_the_ball_on_then_the_kernel_strikes_it(generated):
    from sportsngen.model.centre import physics_step_m
    from sportsngen.train.expert import late_contact_arrays

    data, vocab, arrays = generated
    profiles = {n: get_profile(n) for n in ("Roger Federer", "Rafael Nadal")}
    pos = np.arange(len(arrays))
    out, counts = late_contact_arrays(data, arrays, pos, profiles, delays=(2,), n_branches=400,
                                      keep_frames=30)
    assert counts["kept"] + counts["no_flight"] + counts["kernel_refused"] == counts["branches"]
    # Every shot after the serve is a branch here; a ball half a frame to a frame and a half
    # late is still in reach about half the time or more (15 of 27 here; 22 of 28 with
    # generator version 6.1's profiles), not always.
    assert counts["kept"] == len(out) >= 10
    assert 0.5 * counts["kept"] <= counts["struck"] < counts["kept"]
    first = data.frames.groupby("rally_id")["frame"].min()
    contacts = data.shots[data.shots["shot_index"] >= 1].copy()
    contacts["c"] = contacts["frame"] - first.reindex(contacts["rally_id"]).to_numpy()
    fps = arrays.fps
    for i in range(len(out)):
        h = int(out.learn_from[i]) - 1     # the hand-over: the kernel's lead frame is no target
        track = out.pos_m[out.start[i]:out.start[i] + out.length[i]]
        # The record up to the frame before a recorded contact c = h - 1, then two frames of
        # the ball flown on unstruck, the players' recorded frames kept.
        src = [ri for ri in range(len(arrays)) if arrays.length[ri] > h and np.array_equal(
            arrays.pos_m[arrays.start[ri]:arrays.start[ri] + h - 1], track[:h - 1])]
        assert src
        rec = arrays.pos_m[arrays.start[src[0]]:arrays.start[src[0]] + arrays.length[src[0]]]
        assert h - 1 in set(contacts.loc[contacts["rally_id"] == arrays.rally_id[src[0]], "c"])
        for t in (h - 1, h):
            v = (track[t - 1, BALL] - track[t - 2, BALL]) * fps
            pv = (track[t - 2, BALL] - track[t - 3, BALL]) * fps
            flown = physics_step_m(*(torch.as_tensor(a) for a in (track[t - 1, BALL], v, pv)),
                                   fps).numpy()
            assert np.allclose(track[t, BALL], flown, atol=1e-5)
            assert np.array_equal(track[t, :BALL], rec[t, :BALL])
        # The record had struck it by then (its contact is within half a frame of c).
        assert not np.allclose(track[h, BALL], rec[h, BALL], atol=1e-2)
