"""Where the ball is going: its flight forecast from its current position and velocity.

A player who runs to a ball reads its flight: where it will bounce and where it will be when
he can reach it. The decoder sees the ball's position and velocity and has had to learn that
reading itself; rolled out (with the sharper strike head), its players answered 0.83-0.88 of
the good balls that passed 3-5 m from where they stood and 0.66-0.71 of those 5-7 m away,
where the generator's players answered 0.93-0.99 and 0.82-0.92, while moving toward them
about as fast on average (docs/evaluation.md, fifteenth part). The forecast hands them the
reading: the ball flown on by gravity, drag and the spin's lift read from the track's last
three frames (as the physics centre reads it, `centre.read_lift_mps2`; none where that reading
is no flight, and none after the bounce) with a bounce (`BOUNCE_RESTITUTION` of the vertical speed,
`BOUNCE_KEEP_XY` of the horizontal), in steps of `STEP_S`. It uses nothing but the last
three frames, so a player acting on it acts on what he could have seen.

Outputs (`FORECAST_FEATURES` columns, metres and seconds): the ball's position `HORIZONS_S`
ahead (x, y, z each) and its next bounce (x, y, and the time to it, `HORIZON_S` at most; the
position at that horizon where it does not come down by then), in steps of `STEP_S`.
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.model.centre import (
    BOUNCE_RESTITUTION,
    flight_acceleration_mps2,
    lift_coefficient,
    lift_direction,
    magnus_ratio,
    read_lift_mps2,
    split_lift,
)
from sportsngen.model.flight_kernel import feature_columns_rows, flight_rows
from sportsngen.model.inputs import BALL, POS_SCALE_M, TIME_SCALE_S, VEL_SCALE_MPS
from sportsngen.model.packed import kernel_inputs
from sportsngen.tennis.court import BALL_RADIUS_M

STEP_S = 0.04
HORIZONS_S = (0.4, 0.8)       # positions this far ahead (whole steps)
HORIZON_S = 1.2               # the bounce searched for this far ahead
# Horizontal speed a hard-court bounce keeps (the generator's sliding friction 0.6 with
# restitution 0.8 takes a 25 m/s groundstroke arriving at 12 degrees to 17-18 m/s).
BOUNCE_KEEP_XY = 0.7
FORECAST_FEATURES = 3 * len(HORIZONS_S) + 3
# The playable ball nearest each player (`nearest_playable`): searched this far ahead, at a
# height a groundstroke meets (the generator's players take it at 0.15-2.3 m after its bounce).
INTERCEPT_HORIZON_S = 1.6
PLAYABLE_Z_M = (0.2, 2.3)
INTERCEPT_FEATURES = 3
# Made once, not on every rollout frame: what a bounce keeps of each velocity component, and
# the scales of the columns (positions as the features' positions, the bounce's time over the
# horizon).
_BOUNCE_KEEP = torch.tensor([BOUNCE_KEEP_XY, BOUNCE_KEEP_XY, -BOUNCE_RESTITUTION])
_COLUMN_SCALE = torch.tensor([*POS_SCALE_M * len(HORIZONS_S), *POS_SCALE_M[:2], HORIZON_S])
_INTERCEPT_SCALE = torch.tensor([*POS_SCALE_M[:2], INTERCEPT_HORIZON_S])


def ball_forecast(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                  prev_vel_mps: torch.Tensor | None = None, fps: float = 25.0,
                  path: bool = False):
    """(..., 3) ball positions and velocities (and the frame before's velocities, for the spin;
    None or NaN rows: no spin) -> (..., FORECAST_FEATURES): the positions `HORIZONS_S` ahead,
    then the next bounce's x, y and time (s). With `path`, also the flight flown on to
    `INTERCEPT_HORIZON_S`, (..., N, 3), one row a `STEP_S` from `STEP_S` on (the columns are
    the same either way). Computed by the compiled loop (`flight_kernel`) in float32, on the
    CPU whatever the tensors' device; `ball_forecast_torch` is the same loop in torch
    operations, the reference it is tested against."""
    shape, dev = pos_m.shape[:-1], pos_m.device

    def rows(x: torch.Tensor):
        return np.ascontiguousarray(x.detach().reshape(-1, 3).to("cpu", torch.float32).numpy())

    columns, track = forecast_rows(rows(pos_m), rows(vel_mps),
                                   None if prev_vel_mps is None else rows(prev_vel_mps), fps,
                                   path)
    out = torch.from_numpy(columns).reshape(*shape, FORECAST_FEATURES).to(dev, pos_m.dtype)
    if not path:
        return out
    return out, torch.from_numpy(track).reshape(*shape, -1, 3).to(dev, pos_m.dtype)


def forecast_rows(pos_m: np.ndarray, vel_mps: np.ndarray, prev_vel_mps: np.ndarray | None,
                  fps: float = 25.0, path: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """`ball_forecast` of (n, 3) contiguous float32 arrays -> the columns (n,
    `FORECAST_FEATURES`) and the path (n, N, 3) (`HORIZON_S`'s steps only, without `path`):
    the compiled loop without torch, for callers that hold numpy rows."""
    n_steps = int(round(HORIZON_S / STEP_S))
    n_path = max(n_steps, int(round(INTERCEPT_HORIZON_S / STEP_S))) if path else n_steps
    marks = [int(round(h / STEP_S)) for h in HORIZONS_S]
    columns = np.empty((len(pos_m), FORECAST_FEATURES), dtype=np.float32)
    track = np.empty((len(pos_m), n_path, 3), dtype=np.float32)
    prev = pos_m if prev_vel_mps is None else prev_vel_mps
    flight_rows(pos_m, vel_mps, prev, prev_vel_mps is not None, float(fps), STEP_S,
                n_steps, n_path, marks[0], marks[1], HORIZON_S, BOUNCE_KEEP_XY, columns, track)
    return columns, track


def ball_forecast_torch(pos_m: torch.Tensor, vel_mps: torch.Tensor,
                        prev_vel_mps: torch.Tensor | None = None, fps: float = 25.0,
                        path: bool = False):
    """`ball_forecast` in torch operations: the readable statement of the loop and the
    reference the compiled one is tested against; arguments and results as `ball_forecast`'s."""
    dt = STEP_S
    n_steps = int(round(HORIZON_S / dt))
    n_path = max(n_steps, int(round(INTERCEPT_HORIZON_S / dt))) if path else n_steps
    track = []
    marks = {int(round(h / dt)): i for i, h in enumerate(HORIZONS_S)}
    p, v = pos_m.clone(), vel_mps.clone()
    if prev_vel_mps is None:
        lift = torch.zeros_like(v)
    else:
        # Rows whose previous velocity is NaN (a window's first frame) have no spin read.
        known = torch.isfinite(prev_vel_mps).all(dim=-1, keepdim=True)
        lift, flight = read_lift_mps2(v, torch.where(known, prev_vel_mps, v), fps)
        lift = torch.where(flight & known, lift, torch.zeros_like(lift))
    bounce_xy = torch.zeros_like(p[..., :2])
    bounce_t = torch.full_like(p[..., 0], HORIZON_S)
    found = torch.zeros_like(p[..., 0], dtype=torch.bool)
    keep = _BOUNCE_KEEP.to(device=p.device, dtype=p.dtype)
    ahead = [p] * len(HORIZONS_S)
    # This loop runs at every rollout frame and took more time than the decoder's layers (3.9
    # against 2.4 s over 40 simulated points): the lift's turning and the bounce's bookkeeping
    # are skipped on steps where no row needs them (a zero lift turns to zero; no row down,
    # nothing to change), which keeps every value and cuts a third of its time for one ball.
    spin = bool(lift.any())
    if spin:
        # The lift split once (`split_lift`): its part across the flight, a coefficient on
        # `lift_direction` sized at each step as the generator's Magnus at the spin it reads
        # as (`magnus_ratio`), and the sideways rest, kept; its part along the velocity
        # dropped. Turned at every step instead (`turned_lift_mps2`), the forecast cost 40 %
        # more of a rollout's time.
        across, side = split_lift(lift, v, v)
        speed0 = torch.linalg.vector_norm(v, dim=-1, keepdim=True).clamp_min(1e-6)
        coefficient = lift_coefficient(across, speed0)
        lift = side + across * lift_direction(v)
    at_horizon = p
    for k in range(1, n_path + 1):
        v_new = v + (flight_acceleration_mps2(v) + lift) * dt
        p = p + 0.5 * (v + v_new) * dt     # the trapezoid: exact for constant acceleration
        if spin:
            speed = torch.linalg.vector_norm(v_new, dim=-1, keepdim=True)
            lift = across * magnus_ratio(coefficient, speed0, speed) * lift_direction(v_new) \
                + side
        v = v_new
        down = (p[..., 2] < BALL_RADIUS_M) & (v[..., 2] < 0)
        if bool(down.any()):
            first = down & ~found
            if k <= n_steps:   # the columns' bounce: the first within `HORIZON_S`
                bounce_xy = torch.where(first[..., None], p[..., :2], bounce_xy)
                bounce_t = torch.where(first, torch.full_like(bounce_t, k * dt), bounce_t)
            found = found | down
            v = torch.where(down[..., None], v * keep, v)
            # A bounce changes the spin in ways the track has not shown yet: flown on without.
            if spin:
                across = torch.where(down[..., None], torch.zeros_like(across), across)
                side = torch.where(down[..., None], torch.zeros_like(side), side)
                lift = torch.where(down[..., None], torch.zeros_like(lift), lift)
                spin = bool(lift.any())
            p = torch.cat([p[..., :2], torch.where(down, 2 * BALL_RADIUS_M - p[..., 2],
                                                   p[..., 2])[..., None]], dim=-1)
        if k in marks:
            ahead[marks[k]] = p
        if k == n_steps:
            at_horizon, found_by_horizon = p, found
        if path:
            track.append(p)
    bounce_xy = torch.where(found_by_horizon[..., None], bounce_xy, at_horizon[..., :2])
    columns = torch.cat([*ahead, bounce_xy, bounce_t[..., None]], dim=-1)
    if not path:
        return columns
    return columns, torch.stack(track, dim=-2)


_OUTSIDE_GRAPH = None


def forecast_outside_graph():
    """`ball_forecast` wrapped to run as it is under `torch.compile` (`SportsNGEN.compile_step`),
    outside the graph: dynamo cannot trace into numba, and tracing the torch loop instead took
    minutes. Made on the first call, by the step's compilation: `torch.compiler.disable`
    imports dynamo, 0.9 s of every process's start when it decorated the function."""
    global _OUTSIDE_GRAPH
    if _OUTSIDE_GRAPH is None:
        _OUTSIDE_GRAPH = torch.compiler.disable(ball_forecast)
    return _OUTSIDE_GRAPH


def random_flights(n: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """`n` random balls in flight over the court (positions, velocities and the frame before's
    velocities, (n, 3) each) for tests and benchmarks of the forecast: some about to bounce,
    every seventh with no frame before (NaN), spins of either sign."""
    g = torch.Generator().manual_seed(seed)
    pos = torch.tensor([-10.0, 1.0, 1.2]) + torch.randn(n, 3, generator=g) * \
        torch.tensor([8.0, 4.0, 1.0])
    pos[:, 2] = pos[:, 2].abs() + 0.05
    vel = torch.tensor([25.0, -2.0, 3.0]) + 6 * torch.randn(n, 3, generator=g)
    prev = vel + torch.tensor([0.0, 0.0, 0.4]) + 0.03 * torch.randn(n, 3, generator=g)
    prev[::7] = float("nan")
    return pos, vel, prev


TIME_COLUMN = 7  # the elapsed time's column of the object features (`inputs.object_features`)


def clock_columns(feats: torch.Tensor, clock_s: float) -> torch.Tensor:
    """Object features (..., N_FEATURES) -> (..., 1): the rally's elapsed time (s) clipped at
    `clock_s` (`ModelConfig.clock_s`), on the scale of a second rather than the features'
    ten."""
    return (feats[..., TIME_COLUMN:TIME_COLUMN + 1] * TIME_SCALE_S).clamp(max=clock_s)


def extra_columns(cfg) -> int:
    """The number of input columns a model config's forecast (and its clock, `clock_s`)
    adds to each token."""
    clock = 1 if getattr(cfg, "clock_s", 0.0) > 0 else 0
    if not cfg.ball_forecast:
        return clock
    return FORECAST_FEATURES + (INTERCEPT_FEATURES if cfg.ball_intercept else 0) + clock


def nearest_playable(track_m: torch.Tensor, players_xy_m: torch.Tensor,
                     z_range_m: tuple[float, float] = PLAYABLE_Z_M) -> torch.Tensor:
    """(..., N, 3) a flight one `STEP_S` a row, (..., P, 2) players -> (..., P, 3): for each
    player, the point of the flight nearest him (x, y less his own, m) among those on his side
    of the net, flying toward his end, at a height he can strike (`z_range_m`, by default
    `PLAYABLE_Z_M`), and the time to it (s; the earliest of equals); (0, 0, -1) where the
    flight offers him none (the hitter's own ball going away)."""
    z = track_m[..., 2]
    playable = (z >= z_range_m[0]) & (z <= z_range_m[1])                     # (..., N)
    side = torch.sign(players_xy_m[..., 0])                                   # (..., P)
    step_x = torch.diff(track_m[..., 0], dim=-1)
    step_x = torch.cat([step_x[..., :1], step_x], dim=-1)                     # (..., N)
    # On his side of the net, flying toward his end: a ball coming to him.
    mine = playable[..., None, :] & (track_m[..., None, :, 0] * side[..., None] > 0.5) & \
        (step_x[..., None, :] * side[..., None] > 0)
    rel = track_m[..., None, :, :2] - players_xy_m[..., :, None, :]          # (..., P, N, 2)
    gap = torch.linalg.vector_norm(rel, dim=-1).masked_fill(~mine, float("inf"))
    k = gap.argmin(dim=-1, keepdim=True)                                      # (..., P, 1)
    best = torch.gather(rel, -2, k[..., None].expand(*k.shape, 2))[..., 0, :]
    t_s = (k[..., 0] + 1).to(track_m.dtype) * STEP_S
    found = mine.any(dim=-1)
    best = torch.where(found[..., None], best, torch.zeros_like(best))
    t_s = torch.where(found, t_s, torch.full_like(t_s, -1.0))
    return torch.cat([best, t_s[..., None]], dim=-1)


def forecast_columns(feats: torch.Tensor, prev_feats: torch.Tensor | None,
                     fps: float, intercept: bool = False) -> torch.Tensor:
    """Object features (..., 3, N_FEATURES) (and the frame before's, NaN rows or None where
    there is none) -> the forecast as each player's token sees it (..., 3, FORECAST_FEATURES):
    the forecast positions less his own, scaled as the features' positions (the bounce's time
    over `HORIZON_S`); zeros on the ball's own token, whose bins follow its flight already.
    With `intercept`, `INTERCEPT_FEATURES` more columns: the playable ball nearest him
    (`nearest_playable`, scaled the same way, its time over `INTERCEPT_HORIZON_S`)."""
    if not intercept and prev_feats is not None and kernel_inputs(feats, prev_feats):
        return _forecast_columns_compiled(feats, prev_feats, fps)
    scale = _COLUMN_SCALE.to(feats.device)
    ball = feats[..., BALL, :].float()
    prev = None if prev_feats is None else prev_feats[..., BALL, 3:6].float() * VEL_SCALE_MPS
    forecast = _OUTSIDE_GRAPH if _OUTSIDE_GRAPH is not None and torch.compiler.is_compiling() \
        else ball_forecast
    flown = forecast(ball[..., 0:3] * scale[:3], ball[..., 3:6] * VEL_SCALE_MPS, prev, fps,
                     path=intercept)
    ahead = (flown[0] if intercept else flown) / scale
    own = feats[..., :BALL, 0:3].float()
    own = torch.cat([own] * len(HORIZONS_S) + [own[..., :2], torch.zeros_like(own[..., :1])],
                    dim=-1)
    columns = [ahead[..., None, :] - own]
    if intercept:
        near = nearest_playable(flown[1], own[..., :2] * scale[:2])
        columns = [torch.cat([columns[0], near / _INTERCEPT_SCALE.to(feats.device)], dim=-1)]
    out = torch.cat([*columns, torch.zeros_like(columns[0][..., :1, :])], dim=-2)
    return out.to(feats.dtype)


_COLUMN_SCALE_NP = _COLUMN_SCALE.numpy()


def _forecast_columns_compiled(feats: torch.Tensor, prev_feats: torch.Tensor,
                               fps: float) -> torch.Tensor:
    """`forecast_columns` without the intercept in one compiled call
    (`flight_kernel.feature_columns_rows`): at a rally's one frame its tensor glue around the
    flight loop was 5 % of a simulated frame (py-spy, docs/benchmarks.md, issue 19). The same
    float32 operations in the same order: equal to the torch path to the bit."""
    lead = feats.shape[:-2]
    rows = feats.reshape(-1, *feats.shape[-2:]).contiguous().numpy()
    before = prev_feats.reshape(-1, *prev_feats.shape[-2:]).contiguous().numpy()
    out = np.empty((len(rows), 3, FORECAST_FEATURES), dtype=np.float32)
    n_steps = int(round(HORIZON_S / STEP_S))
    marks = [int(round(h / STEP_S)) for h in HORIZONS_S]
    feature_columns_rows(rows, before, _COLUMN_SCALE_NP, np.float32(VEL_SCALE_MPS), float(fps),
                         STEP_S, n_steps, marks[0], marks[1], HORIZON_S, BOUNCE_KEEP_XY, out)
    return torch.from_numpy(out).reshape(*lead, 3, FORECAST_FEATURES)
