"""Where the rally balls are met (`sportsngen.eval.strike_states`)."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from sportsngen.eval.strike_states import (
    format_state_bands,
    high_contact_share,
    state_bands,
    strike_states,
)

BASE = 11.885


def _points() -> SimpleNamespace:
    """Rally 0: A serves (+x end), B returns, A, then B errs at shot 3; rally 1 (not
    realistic): A serves, B returns, A errs at shot 2."""
    rallies = pd.DataFrame({"rally_id": [0, 1], "realistic": [True, False]})
    shots = pd.DataFrame({
        "rally_id": [0, 0, 0, 0, 1, 1, 1], "shot_index": [0, 1, 2, 3, 0, 1, 2],
        "hitter": ["A", "B", "A", "B", "A", "B", "A"], "frame": [10, 30, 50, 70, 10, 30, 50],
        "outcome": ["in_play", "in_play", "in_play", "error", "in_play", "in_play", "error"],
        "bounce_x": [-5.0, 9.0, -BASE + 1.0, np.nan, -5.0, 8.0, np.nan]})
    rows = []
    for rid in (0, 1):
        for f, ball_z, a_x, b_x in ((10, 2.8, BASE + 0.5, -BASE - 2.0),
                                    (30, 0.9, BASE + 1.0, -BASE - 2.5),
                                    (50, 1.3, BASE + 2.4, -BASE - 1.0),
                                    (70, 0.7, BASE + 1.0, -BASE + 0.4)):
            rows += [(rid, f, "ball", 0.0, ball_z), (rid, f, "A", a_x, 0.0),
                     (rid, f, "B", b_x, 0.0)]
    frames = pd.DataFrame(rows, columns=["rally_id", "frame", "object", "x", "z"])
    return SimpleNamespace(rallies=rallies, shots=shots, frames=frames)


def test_each_rally_strike_gets_its_height_its_hitters_depth_and_the_balls_landing():
    got = strike_states(_points())
    assert got["shot_index"].tolist() == [2, 3] and got["hitter"].tolist() == ["A", "B"]
    assert got["contact_z_m"].tolist() == [1.3, 0.7]
    np.testing.assert_allclose(got["hitter_behind_m"], [2.4, -0.4])
    # A answers B's return (landed 9 m out: 2.885 m inside his baseline); B answers A's ball
    # landed a metre inside his.
    np.testing.assert_allclose(got["incoming_depth_m"], [BASE - 9.0, 1.0])
    assert got["error"].tolist() == [False, True]
    every = strike_states(_points(), realistic_only=False)
    assert len(every) == 3 and every["error"].tolist() == [False, True, True]
    assert strike_states(_points(), first_shot=1)["shot_index"].tolist() == [1, 2, 3]
    assert high_contact_share(got) == 0.5


def test_the_bands_count_share_and_error_by_state():
    bands = state_bands(strike_states(_points(), realistic_only=False))
    z = bands.loc["contact_z_m"]
    assert z.index.tolist() == ["< 0.8", "0.8-0.95", "0.95-1.05", "1.05-1.2", "1.2-1.4",
                                ">= 1.4"]
    assert z["n"].tolist() == [1, 0, 0, 0, 2, 0]
    assert z.loc["1.2-1.4", "error"] == 0.5
    assert z.loc["1.2-1.4", "error_se"] == pytest.approx(0.5 / np.sqrt(2))
    assert z.loc["< 0.8", "share"] == pytest.approx(1 / 3)
    assert np.isnan(z.loc["0.8-0.95", "error"])
    behind = bands.loc["hitter_behind_m"]
    assert behind["n"].tolist() == [1, 0, 0, 2]           # inside the court; 2.4 m twice
    text = format_state_bands(bands, bands).splitlines()
    assert len(text) == 1 + len(bands) and "0.500 / 0.500" in text[5]
    assert text[5].endswith("nan")                          # two strikes: no z


def test_a_shot_frame_after_the_contact_reads_the_ball_of_the_frame_before():
    """A's shot 2 (he stands at +x) at frame 50: the ball at frame 49 at x 11.0 and 0.95 m; at
    frame 50 it is at x 0, already going away from him, so the frame before is his ball. Coming
    toward him into frame 50 (from x -1.0) it is read at frame 50 itself."""
    away, toward = _points(), _points()
    for pts, x_before in ((away, 11.0), (toward, -1.0)):
        pts.frames = pd.concat([pts.frames, pd.DataFrame(
            [(0, 49, "ball", x_before, 0.95)], columns=pts.frames.columns)])
    assert strike_states(away)["contact_z_m"].tolist() == [0.95, 0.7]
    assert strike_states(toward)["contact_z_m"].tolist() == [1.3, 0.7]
