"""A struck ball's speed read off a sampled track the same way wherever the contact fell
between two frames.

A track samples the flight every 1/fps s, and the contact falls anywhere in a frame's interval:
the first frame after it lies between 0 and 1 frame times into the flight. Read as "the speed
over the first (or second) whole frame after the contact frame", a serve's speed then depends
on that fraction, by up to a frame's worth of drag (about 5 km/h on a 160 km/h serve). The
generator strikes each player's serves at the same fraction of a frame (Williams 0.16 of a
frame after a frame, the men and Sharapova 0.25-0.34 before one), so the serve head's labels,
read over the second and third frames after the contact, read Williams' serves 0.84 of a frame
later in their flight than a simulator that strikes on a frame places its own, the others'
0.25-0.34: a per-player bias of the serve's speed, learned by the head and carried into its
rollouts as serves physically slower than the record's. Reading
every track at the same time after the contact (one to two frame times, where a serve placed
on a frame is read) removes it.
"""

from __future__ import annotations

import numpy as np


def speed_frame_after_contact_mps(contact_m: np.ndarray, after_m: np.ndarray, fps: float,
                                  first_offset: tuple[float, float] = (0.0, 1.0)
                                  ) -> np.ndarray:
    """(N, 3) where each ball was struck (or its last frame before the contact, a toss near
    it), (N, 3, 3) three consecutive frames of its flight after the contact -> (N,) its speed
    (m/s) over the interval from one to two frame times after the contact.

    The speed is taken as changing linearly in time over the three frames (exact under a
    constant deceleration; drag changes it by 3 % a frame at serve speeds); the first frame's
    time since the contact, in frames, is then the one that covers its distance from the
    contact along the flight (clipped to `first_offset`), and the speeds over the two steps
    are interpolated (or extrapolated) to the interval. A ball flying at a constant speed reads
    that speed whatever the offset; a contact not known (NaN) is taken one frame time before
    the first frame, which reads the speed between the first two."""
    contact = np.asarray(contact_m, dtype=float)
    after = np.asarray(after_m, dtype=float)
    step_a = after[:, 1] - after[:, 0]
    len_a = np.linalg.norm(step_a, axis=-1)
    len_b = np.linalg.norm(after[:, 2] - after[:, 1], axis=-1)
    along = (step_a * (after[:, 0] - contact)).sum(-1) / np.maximum(len_a, 1e-9)
    slope = len_b - len_a                  # metres a frame, per frame
    # The distance covered in the offset's frames before the first frame, at the step's
    # speed less the slope over the half-offset and half-step between their centres:
    # along = offset * (len_a - slope * (offset + 1) / 2), its smaller root.
    half = len_a - 0.5 * slope
    offset = 2.0 * along / np.maximum(half + np.sqrt(np.maximum(half * half - 2.0 * slope * along,
                                                                0.0)), 1e-9)
    offset = np.clip(np.where(np.isfinite(offset), offset, 1.0), *first_offset)
    return (len_a + slope * (1.0 - offset)) * fps
