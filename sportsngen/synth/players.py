"""Player movement: 2-D centre-of-mass kinematics with speed and acceleration limits.

A player is a point on the ground (x, y) with a velocity. Each frame the player steers toward a
target with a "brake in time" law: the desired velocity points at the target with magnitude
min(v_max, sqrt(2 a_max d)) (so the player can still stop there), and the velocity moves toward
it by at most a_max * dt. Positions advance with the *new* velocity, so the finite differences
of the track obey the limits exactly: |p[k+1] - p[k]| / dt <= v_max and
|p[k+1] - 2 p[k] + p[k-1]| / dt^2 <= a_max. This is what the tests check on generated data.

`min_time_s` is the matching closed form (accelerate, cruise, brake, starting at rest), used by
the decisions to tell which contact points a player can reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ARRIVE_TOLERANCE_M = 0.02


def min_time_s(distance_m, max_speed_mps: float, max_accel_mps2: float):
    """Least time to cover `distance_m` from rest, arriving at speed (a player hits on the run).

    Vectorised over `distance_m`: accelerate at a_max, then cruise at v_max once reached.
    """
    d = np.maximum(np.asarray(distance_m, dtype=float), 0.0)
    v, a = float(max_speed_mps), float(max_accel_mps2)
    short = d <= v * v / (2.0 * a)
    return np.where(short, np.sqrt(2.0 * d / a), d / v + v / (2.0 * a))


def max_distance_m(time_s, max_speed_mps: float, max_accel_mps2: float):
    """Inverse of `min_time_s`: the furthest a player at rest can go in `time_s`."""
    t = np.maximum(np.asarray(time_s, dtype=float), 0.0)
    v, a = float(max_speed_mps), float(max_accel_mps2)
    short = t <= v / a
    return np.where(short, 0.5 * a * t * t, v * (t - v / (2.0 * a)))


@dataclass
class Mover:
    """One player's kinematic state and the track written so far (one row a frame)."""

    x: float
    y: float
    max_speed_mps: float
    max_accel_mps2: float
    dt_s: float
    vx: float = 0.0
    vy: float = 0.0

    def __post_init__(self) -> None:
        self.track: list[tuple[float, float]] = [(self.x, self.y)]

    @property
    def pos(self) -> np.ndarray:
        return np.array([self.x, self.y])

    @property
    def n_frames(self) -> int:
        return len(self.track)

    def run_to(self, frame: int, target_x: float, target_y: float, hurry: bool = False,
               arrive_by: int | None = None) -> None:
        """Steer toward the target until the track has `frame + 1` rows (frame index `frame`).

        `hurry`: the target must be reached by frame `arrive_by` (default `frame`; a ball to
        play), so the player runs at the average speed that gets him there in time when
        braking would be too late; past that frame he runs flat out to it."""
        v_max, a_max, dt = self.max_speed_mps, self.max_accel_mps2, self.dt_s
        dv_max = a_max * dt
        x, y, vx, vy = self.x, self.y, self.vx, self.vy
        append = self.track.append
        steps = frame + 1 - len(self.track)
        due = (frame if arrive_by is None else arrive_by) + 1 - len(self.track)
        for i in range(steps):
            ex, ey = target_x - x, target_y - y
            dist = math.hypot(ex, ey)
            if dist < ARRIVE_TOLERANCE_M:
                dx_, dy_ = -vx, -vy
            else:
                # Braking law, discounted by one step so the discrete player stops in time.
                speed = math.sqrt(max(2.0 * a_max * (dist - dv_max * dt), 0.0))
                if hurry:
                    speed = max(speed, dist / (max(due - i, 1) * dt))
                speed = min(v_max, speed, dist / dt)
                dx_, dy_ = ex / dist * speed - vx, ey / dist * speed - vy
            dv = math.hypot(dx_, dy_)
            if dv > dv_max:
                scale = dv_max / dv
                dx_, dy_ = dx_ * scale, dy_ * scale
            vx, vy = vx + dx_, vy + dy_
            x, y = x + vx * dt, y + vy * dt
            append((x, y))
        self.x, self.y, self.vx, self.vy = x, y, vx, vy

    def position_after(self, n_steps: int, target_x: float, target_y: float) -> np.ndarray:
        """Where the player would be after `n_steps` frames toward a target (no track written)."""
        probe = Mover(self.x, self.y, self.max_speed_mps, self.max_accel_mps2, self.dt_s,
                      self.vx, self.vy)
        probe.run_to(max(n_steps, 0), target_x, target_y)
        return probe.pos

    def stop_point(self) -> tuple[float, float]:
        """Where the player, braking now at full deceleration, comes to rest (m)."""
        v = math.hypot(self.vx, self.vy)
        if v < 1e-6:
            return self.x, self.y
        d = v * v / (2.0 * self.max_accel_mps2)
        return self.x + self.vx / v * d, self.y + self.vy / v * d

    def as_array(self) -> np.ndarray:
        return np.asarray(self.track, dtype=float)
