"""Court geometry in the project frame.

Frame: origin on the ground at the centre of the net; x along the length of the court
(baselines at x = +-11.885 m), y across it (singles sidelines at y = +-4.115 m), z up.
All lengths in metres.
"""

from __future__ import annotations

BASELINE_X_M = 11.885
SERVICE_LINE_X_M = 6.40
SINGLES_HALF_WIDTH_M = 4.115
DOUBLES_HALF_WIDTH_M = 5.485
NET_HEIGHT_CENTRE_M = 0.914
NET_HEIGHT_POST_M = 1.07
NET_POST_Y_M = 6.40  # doubles posts, as on a show court


def net_height_m(y_m):
    """Height of the net cord at lateral position `y_m` (scalar or array), in metres.

    0.914 m at the centre strap, 1.07 m at the posts (y = +-6.40 m); the cord sags between
    them, modelled as a parabola. Beyond the posts the height stays at the post height.
    """
    import numpy as np

    y = np.minimum(np.abs(np.asarray(y_m, dtype=float)), NET_POST_Y_M)
    h = NET_HEIGHT_CENTRE_M + (NET_HEIGHT_POST_M - NET_HEIGHT_CENTRE_M) * (y / NET_POST_Y_M) ** 2
    return float(h) if np.ndim(h) == 0 else h
