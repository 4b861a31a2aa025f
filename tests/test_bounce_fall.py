"""The ball's fall after its bounces (`eval.bounce_fall`): exact on hand-made tracks, and the
generator's topspin read from its own rallies."""

import numpy as np
import pytest

from sportsngen.eval.bounce_fall import fall_after_bounces, format_bounce_fall, post_bounce_fall

FPS = 25.0


def _bounce_track(rise_mps2, n_after):
    """A ball falling (gravity) for 10 frames to a bounce at frame 10, then rising at 4 m/s and
    falling at `rise_mps2` (< 0) for `n_after` frames."""
    t_in = np.arange(-10, 1) / FPS
    down = 0.04 - 3.0 * t_in - 0.5 * 9.81 * t_in ** 2
    t_out = np.arange(1, n_after + 1) / FPS
    return np.concatenate([down, 0.04 + 4.0 * t_out + 0.5 * rise_mps2 * t_out ** 2])


def test_the_fall_after_a_bounce_is_read_exactly_and_stops_at_the_next_contact():
    z = _bounce_track(-13.0, 14)                       # frames 0..24, bounce at 10
    rows = fall_after_bounces(z, [10], [0, 19], (2, 4, 6, 8), FPS)
    # A quadratic's second difference is its acceleration exactly; 8 frames after the bounce
    # (frame 18) it would read frame 19, the contact.
    assert rows[:, 0].tolist() == [2, 4, 6]
    np.testing.assert_allclose(rows[:, 1], -13.0, atol=1e-9)
    # No contact after it: read to the end of the track (frame 24: j up to 13).
    assert fall_after_bounces(z, [10], [0], (8, 13, 14), FPS)[:, 0].tolist() == [8, 13]
    assert len(fall_after_bounces(z, [10], [0, 14], (2, 3), FPS)) == 1   # 13 reads 14
    assert len(fall_after_bounces(z, [], [0], (2,), FPS)) == 0
    with pytest.raises(ValueError, match="2 or more"):
        fall_after_bounces(z, [10], [0], (1, 2), FPS)


def test_the_generators_rally_balls_fall_faster_than_gravity_and_drag_after_a_bounce():
    """The bounce's friction gives the generator's balls topspin: two frames after a bounce
    they fall at a median 12.5-13.5 m/s^2 (gravity and drag alone about 10.3), easing as the
    ball slows."""
    from sportsngen.synth.generate import generate_matches

    data = generate_matches([("Roger Federer", "Rafael Nadal")], "hard", n_points=40, seed=3)
    out = post_bounce_fall(data)
    assert out["frames_after"].tolist() == [2, 4, 6, 8] and (out["n"] >= 20).all()
    assert -14.5 < out["median_mps2"].iloc[0] < -12.0
    assert out["median_mps2"].iloc[0] < out["median_mps2"].iloc[-1] < -10.5
    text = format_bounce_fall(out, out).splitlines()
    assert len(text) == 5 and f"{out['median_mps2'].iloc[0]:.2f} / " in text[1]
