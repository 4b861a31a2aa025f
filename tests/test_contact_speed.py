"""A struck ball's speed read the same wherever its contact fell between frames
(`sportsngen.tennis.contact_speed`), in the serve head's labels and the statistics."""

from __future__ import annotations

import numpy as np
import pytest

from sportsngen.model import strike as S
from sportsngen.tennis.contact_speed import speed_frame_after_contact_mps

FPS = 25.0


def _decelerating(offset: float, v0: float = 50.0, decel: float = 100.0) -> np.ndarray:
    """Three frames of a ball flying along -x from the contact at the origin at v0 m/s, slowing
    by `decel` m/s^2, the first frame `offset` frame times after the contact."""
    t = (offset + np.arange(3)) / FPS
    x = -(v0 * t - 0.5 * decel * t ** 2)
    return np.stack([x, 0.1 * x, np.zeros(3)], axis=-1)


@pytest.mark.parametrize("offset", [0.05, 0.16, 0.5, 0.84, 1.0])
def test_the_speed_one_to_two_frames_after_the_contact_whatever_the_offset(offset):
    after = _decelerating(offset)[None]
    got = speed_frame_after_contact_mps(np.zeros((1, 3)), after, FPS)[0]
    # Under a constant deceleration the mean speed over [1, 2] frame times is v(1.5 frames),
    # and the ball moves along (1, 0.1, 0).
    expected = (50.0 - 100.0 * 1.5 / FPS) * np.hypot(1.0, 0.1)
    assert got == pytest.approx(expected, rel=1e-9)
    # Read over the second and third frames, as the labels were, it is `offset` frames of
    # deceleration slower: right only for a contact just before a frame.
    old = np.linalg.norm(after[0, 2] - after[0, 1]) * FPS
    assert old == pytest.approx(expected - 100.0 * offset / FPS * np.hypot(1.0, 0.1), rel=1e-9)


def test_a_constant_speed_reads_whatever_the_contact_and_the_offset_is_clipped():
    after = np.stack([[-1.0 * k, 0.0, 1.0] for k in (1, 2, 3)])[None]
    for contact in ([0.0, 0.0, 1.0], [30.0, 5.0, 1.0], [-1.0, 0.0, 1.0]):
        assert speed_frame_after_contact_mps(np.array([contact]), after, FPS)[0] == \
            pytest.approx(FPS)
    # A contact read far off the flight extrapolates no further than the offsets allow.
    slow = _decelerating(0.5)[None]
    step_a, step_b = (np.linalg.norm(np.diff(slow[0], axis=0), axis=-1) * FPS)
    far = speed_frame_after_contact_mps(np.array([[30.0, 3.0, 0.0]]), slow, FPS, (0.5, 1.5))[0]
    assert far == pytest.approx(step_a - 0.5 * (step_b - step_a))
    # A contact not known reads the first two frames, as a contact a frame before them would.
    unknown = speed_frame_after_contact_mps(np.full((1, 3), np.nan), slow, FPS, (0.5, 1.5))[0]
    assert unknown == pytest.approx(step_a)


@pytest.mark.parametrize("late", [0.05, 0.16, 0.5, 0.84])
def test_a_serve_struck_between_frames_is_labelled_as_one_struck_on_a_frame(late):
    # A first serve flown by the physics at 20 steps a frame from its contact; its track
    # sampled at the frame rate with the first frame `late` frame times after the contact.
    contact = np.array([[11.4, 0.7, 2.9]])
    side = np.sign(contact[:, 0])
    asked = np.array([[6.0, 0.3, 50.0, -0.06]])
    v0, found = S.solve_serve(contact, side, asked, FPS)
    assert found.all()
    launch = S.launch_frames(contact, v0, asked[:, 3], 20 * FPS)
    fine = np.concatenate([contact[:, None], launch, S.fly_on(launch, 20 * FPS, 60)], 1)[0]
    at = lambda t_frames: fine[int(round(20 * t_frames))]   # noqa: E731
    on_frame = np.linalg.norm(at(2.0) - at(1.0)) * FPS
    after = np.stack([at(late), at(late + 1), at(late + 2)])[None]
    toss = contact - np.array([[0.0, 0.0, 0.02]])   # the toss's frame before, just under it
    label = S.serve_labels(after, side, FPS, contact_m=toss)[0]
    assert label[2] == pytest.approx(on_frame, abs=0.05)     # 0.2 km/h
    # Read over its second and third frames, as the labels were, `late` frames of drag slower.
    assert np.linalg.norm(after[0, 2] - after[0, 1]) * FPS < on_frame - 0.3 * late
