"""Court drawings, rally plots and rally animations (matplotlib, safe on the Agg backend).

Figures are built with `matplotlib.figure.Figure` directly, not pyplot, so nothing here needs
or changes a GUI backend and figures are freed when dropped.

Everything is drawn in the project frame: x along the court (baselines at +-11.885 m), y across
it, z up, origin at the centre of the net.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from sportsngen.tennis.court import (
    BASELINE_X_M,
    DOUBLES_HALF_WIDTH_M,
    NET_HEIGHT_CENTRE_M,
    NET_HEIGHT_POST_M,
    NET_POST_Y_M,
    SERVICE_LINE_X_M,
    SINGLES_HALF_WIDTH_M,
)

COURT_COLOURS = {"hard": "#3a6ea5", "clay": "#c8643c", "grass": "#4f8f3a"}
LINE_KW = {"color": "white", "lw": 1.2, "zorder": 1}
PLAYER_COLOURS = ("tab:red", "tab:blue", "tab:purple", "tab:orange")
# A local minimum of sampled ball height below this is drawn as a bounce: at 25 Hz the frame
# nearest a bounce can sit ~0.3 m above the ground, so the threshold is loose, and minima at a
# racket contact (a low half-volley) are excluded by frame.
BOUNCE_MAX_Z_M = 0.5


def draw_court(ax, view: str = "top", surface: str = "hard") -> None:
    """Draw the court on `ax`: "top" (x, y: singles and doubles lines, service lines, centre
    line and marks, net) or "side" (x, z: ground and the net at its centre height)."""
    colour = COURT_COLOURS.get(surface, COURT_COLOURS["hard"])
    bx, sx = BASELINE_X_M, SERVICE_LINE_X_M
    sw, dw = SINGLES_HALF_WIDTH_M, DOUBLES_HALF_WIDTH_M
    if view == "top":
        ax.add_patch(Rectangle((-bx - 4, -dw - 2.5), 2 * bx + 8, 2 * dw + 5,
                                   color=colour, alpha=0.35, zorder=0, lw=0))
        ax.add_patch(Rectangle((-bx, -dw), 2 * bx, 2 * dw, color=colour, zorder=0, lw=0))
        for y in (-dw, dw, -sw, sw):  # sidelines
            ax.plot([-bx, bx], [y, y], **LINE_KW)
        for x in (-bx, bx):  # baselines and centre marks
            ax.plot([x, x], [-dw, dw], **LINE_KW)
            ax.plot([x, x - np.sign(x) * 0.2], [0, 0], **LINE_KW)
        for x in (-sx, sx):  # service lines
            ax.plot([x, x], [-sw, sw], **LINE_KW)
        ax.plot([-sx, sx], [0, 0], **LINE_KW)  # centre service line
        ax.plot([0, 0], [-NET_POST_Y_M, NET_POST_Y_M], color="0.15", lw=2.0, zorder=2)
        ax.set_xlim(-bx - 4, bx + 4)
        ax.set_ylim(-dw - 2.5, dw + 2.5)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    elif view == "side":
        ax.plot([-bx, bx], [0, 0], color=colour, lw=3, zorder=1)
        ax.plot([0, 0], [0, NET_HEIGHT_CENTRE_M], color="0.15", lw=2.0, zorder=2)
        ax.plot([0, 0], [NET_HEIGHT_CENTRE_M, NET_HEIGHT_POST_M], color="0.15", lw=0.8, ls=":",
                zorder=2)  # the cord rises to the posts
        ax.set_xlim(-bx - 4, bx + 4)
        ax.set_ylim(-0.2, 4.0)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
    else:
        raise ValueError(f"unknown view {view!r}; use 'top' or 'side'")


def _rally_tables(rally_data, rally_id: int):
    """(rally row, frames of the rally sorted by object/frame, shots of the rally)."""
    rid = int(rally_id)
    rallies = rally_data.rallies
    sel = rallies["rally_id"] == rid
    if not sel.any():
        known = rallies["rally_id"].tolist()
        head = ", ".join(str(r) for r in known[:10]) + (" ..." if len(known) > 10 else "")
        raise ValueError(f"rally_id {rid} not in the data; rally ids: {head}")
    frames = rally_data.frames[rally_data.frames["rally_id"] == rid].sort_values(
        ["object", "frame"], kind="stable")
    shots = rally_data.shots[rally_data.shots["rally_id"] == rid].sort_values("shot_index")
    return rallies[sel].iloc[0], frames, shots


def _bounce_indices(z: np.ndarray, frame: np.ndarray, contact_frames: np.ndarray) -> np.ndarray:
    """Indices where the ball height has a local minimum near the ground away from a contact."""
    if z.size < 3:
        return np.array([], dtype=int)
    i = np.flatnonzero((z[1:-1] <= z[:-2]) & (z[1:-1] < z[2:]) & (z[1:-1] < BOUNCE_MAX_Z_M)) + 1
    near_contact = np.isin(frame[i], contact_frames) | np.isin(frame[i] - 1, contact_frames) \
        | np.isin(frame[i] + 1, contact_frames)
    return i[~near_contact]


def _title(row) -> str:
    serve = "1st" if int(row["serve_number"]) == 1 else "2nd"
    winner = row["winner"] if row["winner"] else "-"
    detail = f" ({row['end_detail']})" if row["end_detail"] not in ("", "none") else ""
    return (f"rally {int(row['rally_id'])}: {row['server']} serves ({serve}) to "
            f"{row['receiver']} at {row['score']} on {row['surface']}\n"
            f"{row['end_reason']}{detail}, point to {winner}")


def plot_rally(rally_data, rally_id: int, path: str | Path | None = None) -> Figure:
    """Top view (both players' tracks, the ball track with bounces and racket contacts) above a
    side view of ball height against time with the net height; saved to `path` if given."""
    row, frames, shots = _rally_tables(rally_data, rally_id)
    fig = Figure(figsize=(9, 8.2), layout="constrained")
    top, side = fig.subplots(2, 1, height_ratios=[2.2, 1])
    draw_court(top, "top", str(row["surface"]))
    ball = frames[frames["object"] == "ball"]
    bt, bx, by, bz = (ball[c].to_numpy(float) for c in ("t", "x", "y", "z"))
    players = [p for p in frames["object"].unique() if p != "ball"]
    for k, pid in enumerate(players):
        tr = frames[frames["object"] == pid]
        col = PLAYER_COLOURS[k % len(PLAYER_COLOURS)]
        top.plot(tr["x"], tr["y"], color=col, lw=1.6, label=str(pid), zorder=3)
        top.plot(tr["x"].iat[0], tr["y"].iat[0], "o", color=col, ms=6, zorder=4)
    top.plot(bx, by, color="yellow", lw=1.0, zorder=3, label="ball")
    bounce = _bounce_indices(bz, ball["frame"].to_numpy(), shots["frame"].to_numpy())
    top.plot(bx[bounce], by[bounce], "x", color="black", ms=7, mew=2, zorder=5,
             label="bounce")
    top.plot(shots["contact_x"], shots["contact_y"], "*", color="gold", mec="black", ms=11,
             zorder=5, label="contact")
    top.legend(loc="upper left", fontsize=7, ncol=3, framealpha=0.8)
    top.set_title(_title(row), fontsize=9)

    side.axhline(NET_HEIGHT_CENTRE_M, color="0.3", ls="--", lw=1, label="net height (centre)")
    side.plot(bt, bz, color="darkgoldenrod", lw=1.4, label="ball height")
    side.plot(bt[bounce], bz[bounce], "x", color="black", ms=7, mew=2, label="bounce")
    cross = np.flatnonzero(np.sign(bx[:-1]) * np.sign(bx[1:]) < 0)
    for i in cross:  # ball over the net: dotted marker at the crossing time
        side.axvline(0.5 * (bt[i] + bt[i + 1]), color="0.6", ls=":", lw=0.8)
    frame_t = dict(zip(ball["frame"].to_numpy(), bt))
    ct = [frame_t.get(f, np.nan) for f in shots["frame"].to_numpy()]
    side.plot(ct, shots["contact_z"], "*", color="gold", mec="black", ms=11, label="contact")
    side.set_xlabel("t (s)")
    side.set_ylabel("ball z (m)")
    side.set_ylim(0, max(3.5, float(np.nanmax(bz)) + 0.3) if bz.size else 3.5)
    side.legend(loc="upper right", fontsize=7, ncol=4)
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig


def animate_rally(rally_data, rally_id: int, path: str | Path, every: int = 2, dpi: int = 60,
                  fps: float | None = None) -> Path:
    """Write a top-view GIF of the rally to `path` (players and ball moving, ball size growing
    with height, a short ball trail). `every` keeps every n-th frame; the GIF plays in real
    time unless `fps` is given."""
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    row, frames, _ = _rally_tables(rally_data, rally_id)
    objects = ["ball"] + [p for p in frames["object"].unique() if p != "ball"]
    table = frames.pivot_table(index="frame", columns="object", values=["x", "y", "z"])
    table = table.sort_index().ffill().bfill()
    keep = table.index.to_numpy()[::every]
    fig = Figure(figsize=(8, 4.6), layout="constrained")
    ax = fig.subplots()
    draw_court(ax, "top", str(row["surface"]))
    ax.set_title(_title(row), fontsize=8)
    dots = {}
    for k, obj in enumerate(objects):
        if obj == "ball":
            dots[obj] = ax.scatter([], [], s=30, color="yellow", edgecolors="black", zorder=6)
        else:
            col = PLAYER_COLOURS[(k - 1) % len(PLAYER_COLOURS)]
            dots[obj] = ax.scatter([], [], s=90, color=col, edgecolors="white", zorder=5,
                                   label=str(obj))
    (trail,) = ax.plot([], [], color="yellow", lw=1, alpha=0.7, zorder=4)
    clock = ax.text(0.01, 0.02, "", transform=ax.transAxes, fontsize=8, color="white")
    ax.legend(loc="upper left", fontsize=7)

    def update(i: int):
        f = keep[i]
        for obj, dot in dots.items():
            dot.set_offsets([[table.at[f, ("x", obj)], table.at[f, ("y", obj)]]])
        z = table.at[f, ("z", "ball")]
        dots["ball"].set_sizes([20 + 25 * max(z, 0.0)])
        recent = table.loc[keep[max(0, i - 8)]:f]
        trail.set_data(recent[("x", "ball")], recent[("y", "ball")])
        clock.set_text(f"frame {f}  t = {(f - keep[0]) / rally_data.fps:.2f} s")
        return [*dots.values(), trail, clock]

    # Lay the figure out once, at the GIF's dpi: every frame has the same decorations, and the
    # constrained layout recomputed at each frame's save was a third of the GIF's time.
    fig.set_dpi(dpi)
    fig.draw_without_rendering()
    fig.set_layout_engine("none")
    anim = FuncAnimation(fig, update, frames=len(keep), blit=False)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(path, writer=PillowWriter(fps=fps or rally_data.fps / every), dpi=dpi)
    return path
