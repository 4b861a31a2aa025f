"""The compiled rally tracker (`sportsngen.tennis.rally_kernel`) against the numpy methods it
replaces (`RallyTracker.compiled = False`): the same state, to the bit, after every frame of
generated rallies, of the same rallies shaken by tracking noise and jumps, and of tracks with
missing frames, with rallies leaving the batch at different frames."""

from __future__ import annotations

import numpy as np
import pytest

from sportsngen.eval.rules import analyse_rally_data
from sportsngen.synth import generate_matches
from sportsngen.tennis.rally import RallyTracker

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")


@pytest.fixture(scope="module")
def generated():
    """(pos (B, T, 3, 3) NaN after each rally's end, length (B,), server_end, side, serve)."""
    from sportsngen.data.tokens import Vocab, rally_arrays

    data = generate_matches(["Roger Federer", "Rafael Nadal"], "hard", 40, seed=3, workers=1)
    arr = rally_arrays(data, Vocab.from_data(data, generic=True))
    n, t_max = len(arr), int(arr.length.max())
    pos = np.full((n, t_max, 3, 3), np.nan)
    cols = np.concatenate([np.arange(k) for k in arr.length])
    pos[np.repeat(np.arange(n), arr.length), cols] = arr.pos_m
    r = data.rallies.set_index("rally_id").loc[arr.rally_id]
    return (pos, np.asarray(arr.length), r["server_end"].to_numpy(), r["side"].to_numpy(),
            r["serve_number"].to_numpy(), data)


def _state(tr: RallyTracker) -> dict:
    return {k: v.copy() for k, v in vars(tr).items() if isinstance(v, np.ndarray)}


def _assert_same(a: RallyTracker, b: RallyTracker, t: int) -> None:
    sa, sb = _state(a), _state(b)
    assert sa.keys() == sb.keys()
    for key in sa:
        x, y = sa[key], sb[key]
        if x.shape != y.shape:            # the kernel makes room a frame early
            m = min(x.shape[1], y.shape[1])
            assert (x[:, m:] == -1).all() or np.isnan(x[:, m:]).all(), (key, t)
            assert (y[:, m:] == -1).all() or np.isnan(y[:, m:]).all(), (key, t)
            x, y = x[:, :m], y[:, :m]
        np.testing.assert_array_equal(x, y, err_msg=f"{key} at frame {t}", strict=True)


def _lockstep(pos, length, ends, sides, serves, cap_s: float = 120.0) -> RallyTracker:
    """Both trackers stepped over `pos` (rallies inactive after `length`), compared each frame."""
    ref = RallyTracker(ends, sides, serves, 25.0, cap_s)
    ref.compiled = False
    fast = RallyTracker(ends, sides, serves, 25.0, cap_s)
    assert fast.compiled
    for t in range(pos.shape[1]):
        active = length > t
        np.testing.assert_array_equal(fast.update(pos[:, t], active),
                                      ref.update(pos[:, t], active))
        _assert_same(fast, ref, t)
    return fast


def test_generated_rallies_judged_identically_frame_by_frame(generated):
    pos, length, ends, sides, serves, _ = generated
    fast = _lockstep(pos, length, ends, sides, serves)
    res = fast.results()
    # The generator's rallies are decided and realistic, so the comparison covered the rules
    # that end a rally, not only frames where nothing happens.
    assert res["ended"].mean() > 0.95 and res["realistic"].mean() > 0.95
    assert set(res["end_reason"]) >= {"fault", "winner", "error"}


def test_noisy_and_broken_tracks_judged_identically(generated):
    pos, length, ends, sides, serves, _ = generated
    rng = np.random.default_rng(0)
    noisy = pos + rng.normal(0.0, 0.05, pos.shape)          # tracking noise, 5 cm
    jumps = rng.random(pos.shape[:3]) < 0.004                # teleports and through-ground
    noisy[jumps] += rng.normal(0.0, 3.0, (int(jumps.sum()), 3))
    holes = rng.random(pos.shape[:2]) < 0.002                # missing frames
    noisy[holes] = np.nan
    res = _lockstep(noisy, length, ends, sides, serves, cap_s=8.0).results()
    # The broken tracks fail checks and some hit the (short) cap: those paths ran too.
    failed = {c for f in res["failed_checks"] for c in f}
    assert {"position_jump", "through_ground", "duration_cap"} <= failed


def test_analyse_rallies_reads_the_same_either_way(generated, monkeypatch):
    data = generated[-1]
    fast = analyse_rally_data(data)
    monkeypatch.setattr(RallyTracker, "compiled", False)
    ref = analyse_rally_data(data)
    assert fast.equals(ref)


def test_the_compiled_net_height_is_the_courts():
    from sportsngen.tennis.court import NET_POST_Y_M, net_height_m
    from sportsngen.tennis.rally_kernel import net_height_m as compiled

    ys = np.r_[np.linspace(-9.0, 9.0, 4001), 0.0, NET_POST_Y_M, -NET_POST_Y_M]
    got = np.array([compiled(y) for y in ys])
    np.testing.assert_array_equal(got, net_height_m(ys), strict=True)
    assert got[-3] == 0.914 and got[-2] == got[-1] == pytest.approx(1.07)
