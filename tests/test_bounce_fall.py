"""The ball's fall after its bounces (`eval.bounce_fall`) on hand-made tracks."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.bounce_fall import format_bounce_fall, post_bounce_fall

FPS = 25.0


def _rally(rid, z, contacts):
    n = len(z)
    frames = pd.DataFrame({"rally_id": rid, "frame": np.arange(n), "object": "ball",
                           "x": 0.0, "y": 0.0, "z": z})
    shots = pd.DataFrame({"rally_id": rid, "frame": contacts})
    return frames, shots


def _bounce_track(fall_mps2, rise_mps2, n_after):
    """A ball falling (gravity) for 10 frames to a bounce at frame 10, then rising at 4 m/s and
    falling at `rise_mps2` (< 0) for `n_after` frames."""
    t_in = np.arange(-10, 1) / FPS
    down = 0.04 - 3.0 * t_in + 0.5 * fall_mps2 * t_in ** 2     # frame 10 at 4 cm, falling
    t_out = np.arange(1, n_after + 1) / FPS
    up = 0.04 + 4.0 * t_out + 0.5 * rise_mps2 * t_out ** 2
    return np.concatenate([down, up])


def test_the_fall_after_a_bounce_is_read_exactly_and_stops_at_the_next_contact():
    z = _bounce_track(-9.81, -13.0, 14)                 # frames 0..24, bounce at 10
    f1, s1 = _rally(1, z, [0, 19])                      # the next contact at frame 19
    roll = np.full(25, 0.0335)                          # a rolling ball: no bounce
    f2, s2 = _rally(2, roll, [0])
    data = SimpleNamespace(frames=pd.concat([f1, f2]), shots=pd.concat([s1, s2]))
    out = post_bounce_fall(data, after_frames=(2, 4, 6, 8))
    got = out.set_index("frames_after")
    # A quadratic's second difference is its acceleration exactly.
    for j in (2, 4, 6):
        assert got.loc[j, "n"] == 1
        assert got.loc[j, "median_mps2"] == pytest.approx(-13.0, abs=1e-9)
    # 8 frames after the bounce (frame 18) the second difference reads frame 19, the contact.
    assert got.loc[8, "n"] == 0 and np.isnan(got.loc[8, "median_mps2"])
    text = format_bounce_fall(out.iloc[:3], out.iloc[:3])
    assert "-13.00 / -13.00" in text


def test_a_contact_right_after_the_bounce_leaves_no_frame_and_j_below_two_is_refused():
    z = _bounce_track(-9.81, -12.0, 10)
    f, s = _rally(3, z, [0, 14])                       # contact 4 frames after the bounce
    out = post_bounce_fall(SimpleNamespace(frames=f, shots=s), after_frames=(2, 3, 4))
    assert out["n"].tolist() == [1, 0, 0]              # frame 13 reads 14, the contact
    with pytest.raises(ValueError, match="2 or more"):
        post_bounce_fall(SimpleNamespace(frames=f, shots=s), after_frames=(1, 2))
