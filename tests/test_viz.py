"""Court and rally plots (sportsngen.viz.court_plot) on a tiny hand-made rally."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from sportsngen.data.tracking import RallyData
from sportsngen.viz.court_plot import _bounce_indices, animate_rally, draw_court, plot_rally

N_FRAMES = 30
FPS = 25.0


def _tiny_rally() -> RallyData:
    """One serve from the -x baseline that bounces in the box; both players move a little."""
    t = np.arange(N_FRAMES) / FPS
    bx = -11.8 + 22.0 * t
    t_b = 0.7  # the ball bounces at t = 0.7 s, then rises
    bz = np.where(t < t_b, 2.8 - 3.96 * t, 0.04 + 4.0 * (t - t_b) - 4.9 * (t - t_b) ** 2)
    bz = np.maximum(bz, 0.04)
    by = 0.5 - 1.5 * t
    rows = []
    tracks = {"ball": (bx, by, bz), "Server": (np.full(N_FRAMES, -12.0) + 0.5 * t, 0.6 - t,
                                                np.zeros(N_FRAMES)),
              "Receiver": (12.0 - 0.8 * t, -3.0 + 0.5 * t, np.zeros(N_FRAMES))}
    for obj, (x, y, z) in tracks.items():
        for f in range(N_FRAMES):
            rows.append({"rally_id": 1, "frame": f, "t": t[f], "object": obj, "x": x[f],
                         "y": y[f], "z": z[f], "stroke": "serve", "direction": "T",
                         "outcome": "in_play", "error_kind": "none"})
    frames = pd.DataFrame(rows)
    rallies = pd.DataFrame([{
        "rally_id": 1, "match_id": "m1", "point": 1, "server": "Server", "receiver": "Receiver",
        "serve_number": 1, "side": "deuce", "server_end": -1, "surface": "clay",
        "tournament": "test", "set_no": 1, "server_sets": 0, "receiver_sets": 0,
        "server_games": 0, "receiver_games": 0, "server_points": 0, "receiver_points": 0,
        "in_tiebreak": False, "score": "0-0 0-0", "winner": "Server", "end_reason": "ace",
        "end_detail": "unreached", "serve_kmh": 180.0, "rally_length": 1}])
    shots = pd.DataFrame([{
        "rally_id": 1, "shot_index": 0, "frame": 0, "hitter": "Server", "stroke": "serve",
        "spin": "flat", "direction": "T", "outcome": "winner", "error_kind": "none",
        "contact_x": bx[0], "contact_y": by[0], "contact_z": bz[0], "speed_mps": 50.0,
        "bounce_x": 3.6, "bounce_y": -0.5}])
    return RallyData.from_tables(frames, rallies, shots, fps=FPS)


def test_draw_court_views():
    fig = Figure()
    ax_top, ax_side = fig.subplots(1, 2)
    draw_court(ax_top, "top")
    draw_court(ax_side, "side")
    # top: 4 sidelines + 2 baselines + 2 centre marks + 2 service lines + centre line + net
    assert len(ax_top.lines) == 12 and len(ax_top.patches) == 2
    xs = np.concatenate([ln.get_xdata() for ln in ax_top.lines])
    assert xs.min() == pytest.approx(-11.885) and xs.max() == pytest.approx(11.885)
    assert len(ax_side.lines) == 3
    with pytest.raises(ValueError, match="unknown view 'front'"):
        draw_court(ax_top, "front")


def test_bounce_detection():
    z = np.array([1.0, 0.5, 0.04, 0.4, 0.8, 0.5, 0.2, 0.5, 0.03, 0.03, 0.2, 0.9, 0.6, 0.7])
    frame = np.arange(z.size) + 100
    # minima at 2, 6 (0.2 m: a bounce seen between frames), 9 (last frame of a flat minimum);
    # the minimum at 12 is too high, and 6 is dropped when a racket contact is one frame away
    np.testing.assert_array_equal(_bounce_indices(z, frame, np.array([], int)), [2, 6, 9])
    np.testing.assert_array_equal(_bounce_indices(z, frame, np.array([107])), [2, 9])


def test_plot_rally_writes_a_png(tmp_path):
    data = _tiny_rally()
    path = tmp_path / "sub" / "rally.png"
    fig = plot_rally(data, 1, path=path)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    top, side = fig.axes
    assert "Server" in fig.axes[0].get_title() and "ace" in top.get_title()
    labels = [ln.get_label() for ln in top.lines]
    assert {"Server", "Receiver", "ball", "bounce", "contact"} <= set(labels)
    bounce = next(ln for ln in top.lines if ln.get_label() == "bounce")
    assert len(bounce.get_xdata()) == 1  # the one bounce of the hand-made serve
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
    with pytest.raises(ValueError, match="rally_id 7 not in the data"):
        plot_rally(data, 7)


def test_animate_rally_writes_a_gif(tmp_path):
    data = _tiny_rally()
    out = animate_rally(data, 1, tmp_path / "rally.gif", every=5)
    head = out.read_bytes()[:6]
    assert head in (b"GIF87a", b"GIF89a") and out.stat().st_size > 5_000
    from PIL import Image

    with Image.open(out) as im:
        assert im.n_frames == N_FRAMES // 5
