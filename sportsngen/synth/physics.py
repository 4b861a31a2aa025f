"""Tennis ball physics for the synthetic generator: flight, bounce, net, launch solver.

Flight (Vid2Player's 2-D model, applied in the vertical plane that contains the velocity):

    a = -g z_hat - k C_d |v| v + k C_L |v| n,   k = rho pi R^2 / (2 m),
    C_L = -spin / (2 |spin| + |v|)   (i.e. 1 / (2 + |v| / v_spin), sign flipped for topspin)

`n` is `v` turned 90 degrees upward in its vertical plane (|n| = |v|). `spin_mps` is the model's
v_spin = R omega, signed relative to the horizontal direction of travel: > 0 topspin (Magnus
pushes down), < 0 backspin/slice (lift), 0 flat. All forces lie in that vertical plane, so a
flight stays in it: we integrate in 2-D (u along the ground track, z up) with plain floats and
map to 3-D. Spin does not decay in the air. Constants (`Aero`): mass 0.057 kg, radius 0.0335 m,
air 1.21 kg/m^3, C_d 0.55, so k = 0.0374 /m; `NO_AIR` switches drag and lift off.

Integration: classic RK4, fixed 20 ms step (`STEP_S`); ground and net events are located inside
a step by a cubic Hermite root and reached by an exact RK4 sub-step; `Flight.at` is cubic
Hermite on the nodes. Measured against a 0.5 ms step (serves 42-55 m/s, groundstrokes, slice,
lob; two bounces): bounce positions within 2e-7 m, positions at 25 Hz within 2e-7 m. With
`NO_AIR` the flight matches the exact parabola to 5e-14 m (RK4 and Hermite are exact there).
A 1.5 s flight costs 0.13-0.22 ms, `solve_launch` 0.15-0.35 ms (Python 3.11, by machine load).

Bounce (`SurfaceBounce` per surface), with normal impulse N = (1 + e) |v_z| per unit mass:
normal restitution e; a ploughing impulse p N that slows the horizontal motion without torque
(the dented surface tilts the reaction, which still passes through the centre); then Coulomb
friction mu N on the slip of the contact point (u - spin) until the ball rolls: Cross's
slide-or-grip model with I = 0.55 m R^2. The ITF Court Pace Rating measures mu + p as friction:
CPR = 100 (1 - mu - p) + 150 (0.81 - e) = clay 15 (slow), hard 41.5 (medium-fast), grass 48
(fast). The speed ratio after/before a bounce is mostly the horizontal speed kept. Clay keeps
least (highest mu + p). Grass and hard lose about the same horizontal speed per vertical speed
((mu + p)(1 + e) = 1.10 vs 1.08) but grass returns less vertical speed (e 0.73 vs 0.80), and its
ploughing also slows gripping (topspin) balls, where friction alone cannot tell surfaces apart.
So the median ratio orders clay < grass < hard (the SportsNGEN paper's finding) for serves and
groundstrokes alike (measured medians in tests/test_physics.py and the report), while grass
keeps the lowest, skidding bounce.

The net is the plane x = 0 over all y; a ball hits it when its leading surface reaches the plane
(centre at |x| = R) with its bottom below the cord (z - R < net_height_m(y)), then drops dead on
the hitter's side (10 % rebound, spin lost).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sportsngen.tennis.court import net_height_m

GRAVITY_MPS2 = 9.81
BALL_RADIUS_M = 0.0335
BALL_MASS_KG = 0.057
BALL_INERTIA_FACTOR = 0.55  # I = 0.55 m R^2 for a hollow tennis ball (Cross)
STEP_S = 0.02               # RK4 step; events are located exactly inside a step
ROLL_BELOW_MPS = 0.3        # a rebound slower than this ends the bouncing: the ball rolls
ROLLING_RESISTANCE = 0.05   # rolling deceleration / g
NET_REBOUND = 0.1           # fraction of the speed towards the net kept (backwards) after a net hit
MAX_FLIGHT_S = 10.0         # the launch solver gives up on flights longer than this


@dataclass(frozen=True)
class Aero:
    """Air and ball constants. `drag_coefficient=0` and `lift_scale=0` switch drag/Magnus off."""

    drag_coefficient: float = 0.55
    lift_scale: float = 1.0
    air_density_kgpm3: float = 1.21
    ball_mass_kg: float = BALL_MASS_KG
    ball_radius_m: float = BALL_RADIUS_M
    gravity_mps2: float = GRAVITY_MPS2

    @property
    def k_per_m(self) -> float:
        """k = rho pi R^2 / (2 m): acceleration per (speed^2 * coefficient)."""
        r = self.ball_radius_m
        return self.air_density_kgpm3 * math.pi * r * r / (2.0 * self.ball_mass_kg)


DEFAULT_AERO = Aero()
NO_AIR = Aero(drag_coefficient=0.0, lift_scale=0.0)


@dataclass(frozen=True)
class SurfaceBounce:
    """Bounce constants of a surface: normal restitution `e`, sliding friction `mu`, and the
    ploughing coefficient (horizontal impulse per normal impulse from the surface deforming)."""

    restitution: float
    friction: float
    plough: float = 0.0

    @property
    def court_pace_rating(self) -> float:
        """ITF Court Pace Rating, with mu + plough as the measured friction."""
        return 100.0 * (1.0 - self.friction - self.plough) + 150.0 * (0.81 - self.restitution)


SURFACE_BOUNCE: dict[str, SurfaceBounce] = {
    "hard": SurfaceBounce(restitution=0.80, friction=0.60, plough=0.0),
    "clay": SurfaceBounce(restitution=0.83, friction=0.62, plough=0.20),
    "grass": SurfaceBounce(restitution=0.73, friction=0.50, plough=0.14),
}


def _surface(surface: str) -> SurfaceBounce:
    try:
        return SURFACE_BOUNCE[surface]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown surface {surface!r}; known surfaces: {sorted(SURFACE_BOUNCE)}") from None


def _bounce_2d(vu: float, vz: float, spin: float, sb: SurfaceBounce) -> tuple[float, float, float]:
    """Bounce in the plane: (u speed, z speed < 0, spin about the fixed axis) -> after."""
    n = (1.0 + sb.restitution) * -vz               # normal impulse per unit mass
    plough = min(sb.plough * n, abs(vu))          # never reverses the ball by itself
    vu = vu - math.copysign(plough, vu)
    slip = vu - spin                              # speed of the contact point over the ground
    a = BALL_INERTIA_FACTOR
    j = min(abs(slip) * a / (1.0 + a), sb.friction * n)   # grip (roll) or slide throughout
    j = math.copysign(j, slip)
    return vu - j, sb.restitution * -vz, spin + j / a


def bounce(vel_in_mps: np.ndarray, spin_mps: float, surface: str) -> tuple[np.ndarray, float]:
    """Velocity (3,) and spin just after a bounce on `surface` of a ball arriving at `vel_in_mps`
    (z < 0) with `spin_mps` (> 0 topspin, relative to the horizontal direction of travel).
    The returned spin is relative to the outgoing direction of travel."""
    sb = _surface(surface)
    vx, vy, vz = (float(c) for c in np.asarray(vel_in_mps, dtype=float).reshape(3))
    if not vz < 0.0:
        raise ValueError(f"bounce needs a ball moving down (vel z < 0), got vel_in_mps z = {vz}")
    vh = math.hypot(vx, vy)
    cx, cy = (vx / vh, vy / vh) if vh > 0.0 else (1.0, 0.0)
    vu, vz_out, spin = _bounce_2d(vh, vz, float(spin_mps), sb)
    return np.array([vu * cx, vu * cy, vz_out]), (spin if vu >= 0.0 else -spin)


@dataclass
class FlightEvent:
    """A bounce or a net hit: where and when, and the velocity just before and after."""

    kind: str  # "bounce" | "net"
    t_s: float
    pos_m: np.ndarray
    vel_in_mps: np.ndarray
    vel_out_mps: np.ndarray
    spin_out_mps: float = 0.0


@dataclass
class Flight:
    """Integrated ball flight. `t_s` is non-decreasing: an event appears as two nodes at the same
    time (velocity in, then velocity out). `stop_reason`: "t_max", "bounces" or "stop_when"."""

    t_s: np.ndarray
    pos_m: np.ndarray
    vel_mps: np.ndarray
    events: list[FlightEvent] = field(default_factory=list)
    stop_reason: str = "t_max"

    def at(self, t_s) -> np.ndarray:
        """Positions (M, 3) at times `t_s` in [t0, t_end] (cubic Hermite on the RK4 nodes:
        error ~1e-7 m). A scalar time gives (3,)."""
        t = np.asarray(t_s, dtype=float)
        t0, t1 = self.t_s[0], self.t_s[-1]
        if t.size and (t.min() < t0 - 1e-9 or t.max() > t1 + 1e-9):
            raise ValueError(f"times outside the flight [{t0:.4f}, {t1:.4f}] s: "
                             f"[{t.min():.4f}, {t.max():.4f}]")
        tt = np.clip(t.reshape(-1), t0, t1)
        n = len(self.t_s)
        if n == 1:
            out = np.repeat(self.pos_m[:1], tt.size, axis=0)
            return out.reshape(3) if t.ndim == 0 else out
        i = np.clip(np.searchsorted(self.t_s, tt, side="right") - 1, 0, n - 2)
        h = self.t_s[i + 1] - self.t_s[i]
        s = np.where(h > 0, (tt - self.t_s[i]) / np.where(h > 0, h, 1.0), 0.0)[:, None]
        h = h[:, None]
        s2, s3 = s * s, s * s * s
        out = ((2 * s3 - 3 * s2 + 1) * self.pos_m[i] + (s3 - 2 * s2 + s) * h * self.vel_mps[i]
               + (-2 * s3 + 3 * s2) * self.pos_m[i + 1] + (s3 - s2) * h * self.vel_mps[i + 1])
        return out.reshape(3) if t.ndim == 0 else out

    def first_bounce(self) -> FlightEvent | None:
        """The first bounce event, or None if the ball never reached the ground."""
        return next((e for e in self.events if e.kind == "bounce"), None)

    @property
    def t_end_s(self) -> float:
        return float(self.t_s[-1])


# ---------------------------------------------------------------------------------------------
# The integrator: one RK4 step of the in-plane state. Position does not enter the forces, so a
# step needs four accelerations of the velocity only.

def _accel(vu: float, vz: float, kcd: float, kl: float, two_abs_spin: float,
           g: float) -> tuple[float, float]:
    v = math.sqrt(vu * vu + vz * vz)
    cl = kl / (two_abs_spin + v) if kl != 0.0 else 0.0   # kl = -k * lift_scale * spin
    return -v * (kcd * vu + cl * vz), v * (cl * vu - kcd * vz) - g


def _rk4(u: float, z: float, vu: float, vz: float, h: float, kcd: float, kl: float,
         tas: float, g: float) -> tuple[float, float, float, float]:
    a1u, a1z = _accel(vu, vz, kcd, kl, tas, g)
    v2u, v2z = vu + 0.5 * h * a1u, vz + 0.5 * h * a1z
    a2u, a2z = _accel(v2u, v2z, kcd, kl, tas, g)
    v3u, v3z = vu + 0.5 * h * a2u, vz + 0.5 * h * a2z
    a3u, a3z = _accel(v3u, v3z, kcd, kl, tas, g)
    v4u, v4z = vu + h * a3u, vz + h * a3z
    a4u, a4z = _accel(v4u, v4z, kcd, kl, tas, g)
    h6 = h / 6.0
    return (u + h6 * (vu + 2.0 * (v2u + v3u) + v4u), z + h6 * (vz + 2.0 * (v2z + v3z) + v4z),
            vu + h6 * (a1u + 2.0 * (a2u + a3u) + a4u), vz + h6 * (a1z + 2.0 * (a2z + a3z) + a4z))


def _hermite_root(p0: float, d0: float, p1: float, d1: float, h: float, target: float) -> float:
    """Fraction s in [0, 1] of a step where the cubic Hermite through (p0, d0) -> (p1, d1)
    reaches `target` (Newton from the linear guess; the cubic is monotone there in practice)."""
    s = (p0 - target) / (p0 - p1) if p0 != p1 else 0.0
    for _ in range(4):
        s2, s3 = s * s, s * s * s
        p = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * d0 + (-2 * s3 + 3 * s2) * p1
             + (s3 - s2) * h * d1)
        dp = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * h * d0 + (-6 * s2 + 6 * s) * p1
              + (3 * s2 - 2 * s) * h * d1)
        if dp == 0.0:
            break
        s = min(1.0, max(0.0, s - (p - target) / dp))
    return s


def _coeffs(spin: float, aero: Aero) -> tuple[float, float, float, float]:
    k = aero.k_per_m
    return k * aero.drag_coefficient, -k * aero.lift_scale * spin, 2.0 * abs(spin), \
        aero.gravity_mps2


def fly(pos0_m, vel0_mps, spin_mps: float, surface: str, t_max_s: float, max_bounces: int = 2,
        stop_when=None, aero: Aero = DEFAULT_AERO, step_s: float = STEP_S,
        net: bool = True) -> Flight:
    """Integrate a ball from `pos0_m` with `vel0_mps` and `spin_mps` for up to `t_max_s` seconds
    (times start at 0), stopping at the `max_bounces`-th bounce or as soon as
    `stop_when(t, pos, vel)` (called after every step with 3-tuples of floats) returns True.
    Bounces on `surface`, hits the net (see the module doc), rolls when it stops bouncing.
    `net=False` flies through the net: the flight a player reads from the launch before he can
    see that the ball will meet the cord."""
    sb = _surface(surface)
    p = [float(c) for c in np.asarray(pos0_m, dtype=float).reshape(3)]
    v = [float(c) for c in np.asarray(vel0_mps, dtype=float).reshape(3)]
    if not all(map(math.isfinite, p + v + [spin_mps, t_max_s])):
        raise ValueError(f"non-finite input: pos0_m={p}, vel0_mps={v}, spin={spin_mps}, "
                         f"t_max_s={t_max_s}")
    if t_max_s <= 0 or max_bounces < 1 or step_s <= 0:
        raise ValueError(f"need t_max_s > 0, max_bounces >= 1 and step_s > 0, got {t_max_s}, "
                         f"{max_bounces}, {step_s}")
    r = aero.ball_radius_m
    if p[2] < r - 1e-9:
        raise ValueError(f"ball centre below the ground: pos0_m z = {p[2]} < radius {r}")
    ox, oy, z = p
    vh = math.hypot(v[0], v[1])
    cx, cy = (v[0] / vh, v[1] / vh) if vh > 0.0 else (1.0, 0.0)
    u, vu, vz, spin = 0.0, vh, v[2], float(spin_mps)
    kcd, kl, tas, g = _coeffs(spin, aero)
    rolling = z <= r and abs(vz) < ROLL_BELOW_MPS
    if rolling:
        z, vz = r, 0.0
    t, bounces, events, reason = 0.0, 0, [], "t_max"
    nodes = [(0.0, ox, oy, z, vu * cx, vu * cy, vz)]

    def net_target(ox: float, cx: float) -> float | None:
        # u at which the ball's leading surface reaches the net plane, if it heads there
        side = 1.0 if ox > 0 else -1.0
        if not net or abs(ox) <= r or side * cx >= 0:
            return None
        return (side * r - ox) / cx

    u_net = net_target(ox, cx)
    while t < t_max_s - 1e-12:
        h = min(step_s, t_max_s - t)
        if rolling:
            vu1 = vu - h * (kcd * abs(vu) * vu + math.copysign(ROLLING_RESISTANCE * g, vu))
            vu1 = vu1 if vu1 * vu > 0 else 0.0
            u1, z1, vz1 = u + 0.5 * h * (vu + vu1), r, 0.0
            if u_net is not None and u1 >= u_net:  # rolled into the net: it stops there
                u1, vu1 = u_net, 0.0
        else:
            u1, z1, vu1, vz1 = _rk4(u, z, vu, vz, h, kcd, kl, tas, g)
        event = None
        if not rolling:
            s_g = _hermite_root(z, vz, z1, vz1, h, r) if z1 <= r else 2.0
            s_n = 2.0
            if u_net is not None and (u - u_net) * (u1 - u_net) <= 0.0 and u != u_net:
                s_n = _hermite_root(u, vu, u1, vu1, h, u_net)
            if s_n < s_g:
                un, zn, vun, vzn = _rk4(u, z, vu, vz, s_n * h, kcd, kl, tas, g)
                if zn - r < net_height_m(oy + un * cy):
                    event, s_ev = "net", s_n
                    u1, z1, vu1, vz1 = un, zn, vun, vzn
                u_net = None  # passed or hit: no second look at the net from this segment
            if event is None and s_g <= 1.0:
                event, s_ev = "bounce", s_g
                u1, z1, vu1, vz1 = _rk4(u, z, vu, vz, s_g * h, kcd, kl, tas, g)
                z1 = r
        if event is not None:
            h = s_ev * h
        t, u, z, vu, vz = t + h, u1, z1, vu1, vz1
        x, y = ox + u * cx, oy + u * cy
        nodes.append((t, x, y, z, vu * cx, vu * cy, vz))
        if event is not None:
            v_in = np.array([vu * cx, vu * cy, vz])
            if event == "bounce":
                vu, vz, spin = _bounce_2d(vu, vz, spin, sb)
                bounces += 1
                if vz < ROLL_BELOW_MPS:
                    rolling, vz = True, 0.0
                new_vx, new_vy = vu * cx, vu * cy
                if vu < 0.0:  # checked back: same rotation, opposite sign about the new axis
                    spin = -spin
            else:  # the net: drop dead on the hitter's side, spin lost
                new_vx, new_vy = -NET_REBOUND * vu * cx, 0.3 * vu * cy
                vz, spin = 0.3 * vz, 0.0
            # a new in-plane segment starts at the event
            ox, oy, u, vu = x, y, 0.0, math.hypot(new_vx, new_vy)
            if vu > 0.0:
                cx, cy = new_vx / vu, new_vy / vu
            kcd, kl, tas, g = _coeffs(spin, aero)
            u_net = net_target(ox, cx)
            nodes.append((t, x, y, z, vu * cx, vu * cy, vz))
            events.append(FlightEvent(event, t, np.array([x, y, z]), v_in,
                                      np.array([vu * cx, vu * cy, vz]), spin))
            if bounces >= max_bounces:
                reason = "bounces"
                break
        if rolling and vu == 0.0:  # at rest: hold until t_max
            if t < t_max_s:
                nodes.append((t_max_s, x, y, z, 0.0, 0.0, 0.0))
            break
        if stop_when is not None and stop_when(t, (x, y, z), (vu * cx, vu * cy, vz)):
            reason = "stop_when"
            break
    arr = np.array(nodes)
    return Flight(arr[:, 0], arr[:, 1:4], arr[:, 4:7], events, reason)


def speed_after_bounce_ratio(flight: Flight) -> float:
    """|v_out| / |v_in| at the first bounce of `flight`."""
    ev = flight.first_bounce()
    if ev is None:
        raise ValueError("flight has no bounce")
    return float(np.linalg.norm(ev.vel_out_mps) / np.linalg.norm(ev.vel_in_mps))


# ---------------------------------------------------------------------------------------------
# Launch solver. The flight stays in the vertical plane through contact and target, so only the
# elevation is unknown: a 1-D root of "range to the first bounce = distance to the target".

def _range_2d(z0: float, vu: float, vz: float, spin: float, u_net: float | None,
              aero: Aero) -> tuple[float, float]:
    """(u at the first ground contact, centre height when u passes `u_net`) of an in-plane
    flight, with exactly the steps and event location of `fly` (NaN when not reached)."""
    kcd, kl, tas, g = _coeffs(spin, aero)
    r, h = aero.ball_radius_m, STEP_S
    u, z, t, z_net = 0.0, z0, 0.0, math.nan
    while t < MAX_FLIGHT_S:
        u1, z1, vu1, vz1 = _rk4(u, z, vu, vz, h, kcd, kl, tas, g)
        if u_net is not None and u < u_net <= u1 and math.isnan(z_net):
            s = _hermite_root(u, vu, u1, vu1, h, u_net)
            un, z_net, _, _ = _rk4(u, z, vu, vz, s * h, kcd, kl, tas, g)
            if un > u1:  # the ground came first inside this step
                z_net = math.nan
        if z1 <= r:
            s = _hermite_root(z, vz, z1, vz1, h, r)
            ug = _rk4(u, z, vu, vz, s * h, kcd, kl, tas, g)[0]
            if u_net is not None and ug < u_net:
                z_net = math.nan
            return ug, z_net
        u, z, vu, vz, t = u1, z1, vu1, vz1, t + h
    return math.nan, math.nan


_TABLE_SPEEDS = np.arange(3.0, 75.01, 3.0)
_TABLE_SPINS = np.arange(-20.0, 20.01, 4.0)
_TABLE_ELEV = np.radians(np.arange(-60.0, 80.01, 1.5))
_TABLE_DROPS = np.arange(0.0, 4.01, 0.1)
_TABLES: dict[Aero, np.ndarray] = {}


def _range_table(aero: Aero) -> np.ndarray:
    """range[speed, spin, elevation, drop]: horizontal distance at which a ball launched from
    height 0 first descends to -drop (the ODE does not depend on height, so one integration per
    launch serves every contact height). Vectorised numpy; built once per `Aero` (~0.5 s)."""
    if aero in _TABLES:
        return _TABLES[aero]
    V, S, E = np.meshgrid(_TABLE_SPEEDS, _TABLE_SPINS, _TABLE_ELEV, indexing="ij")
    V, S, E = V.ravel(), S.ravel(), E.ravel()
    n, n_drop = V.size, _TABLE_DROPS.size
    out = np.full((n, n_drop), np.nan)
    k = aero.k_per_m
    kcd, g = k * aero.drag_coefficient, aero.gravity_mps2
    alive = np.arange(n)
    kl, tas = -k * aero.lift_scale * S, 2.0 * np.abs(S) + 1e-12
    u, z = np.zeros(n), np.zeros(n)
    vu, vz = V * np.cos(E), V * np.sin(E)
    nxt = np.zeros(n, dtype=int)  # next drop level to record

    def acc(vu, vz, kl, tas):
        v = np.sqrt(vu * vu + vz * vz)
        cl = kl / (tas + v)
        return -v * (kcd * vu + cl * vz), v * (cl * vu - kcd * vz) - g

    h, t = STEP_S, 0.0
    while alive.size and t < 6.0:
        a1 = acc(vu, vz, kl, tas)
        v2 = (vu + 0.5 * h * a1[0], vz + 0.5 * h * a1[1])
        a2 = acc(*v2, kl, tas)
        v3 = (vu + 0.5 * h * a2[0], vz + 0.5 * h * a2[1])
        a3 = acc(*v3, kl, tas)
        v4 = (vu + h * a3[0], vz + h * a3[1])
        a4 = acc(*v4, kl, tas)
        u1 = u + h / 6 * (vu + 2 * (v2[0] + v3[0]) + v4[0])
        z1 = z + h / 6 * (vz + 2 * (v2[1] + v3[1]) + v4[1])
        vu = vu + h / 6 * (a1[0] + 2 * (a2[0] + a3[0]) + a4[0])
        vz = vz + h / 6 * (a1[1] + 2 * (a2[1] + a3[1]) + a4[1])
        while True:  # record every drop level crossed in this step (linear inside the step)
            lvl = -_TABLE_DROPS[np.minimum(nxt, n_drop - 1)]
            hit = (nxt < n_drop) & (z1 <= lvl)
            if not hit.any():
                break
            f = (z[hit] - lvl[hit]) / np.maximum(z[hit] - z1[hit], 1e-12)
            out[alive[hit], nxt[hit]] = u[hit] + f * (u1[hit] - u[hit])
            nxt[hit] += 1
        u, z, t = u1, z1, t + h
        keep = nxt < n_drop
        if not keep.all():
            alive, u, z, vu, vz, kl, tas, nxt = (a[keep] for a in (alive, u, z, vu, vz, kl, tas,
                                                                   nxt))
    table = out.reshape(_TABLE_SPEEDS.size, _TABLE_SPINS.size, _TABLE_ELEV.size, n_drop)
    _TABLES[aero] = table
    return table


def _lerp_index(grid: np.ndarray, x: float) -> tuple[int, float]:
    i = int(np.clip(np.searchsorted(grid, x) - 1, 0, grid.size - 2))
    w = (x - grid[i]) / (grid[i + 1] - grid[i])
    return i, min(1.0, max(0.0, w))


def _range_curve(speed: float, spin: float, drop: float, aero: Aero) -> np.ndarray:
    """Range over the elevation grid at (speed, spin, drop), trilinear in the table."""
    tab = _range_table(aero)
    iv, wv = _lerp_index(_TABLE_SPEEDS, speed)
    js, ws = _lerp_index(_TABLE_SPINS, spin)
    kd, wd = _lerp_index(_TABLE_DROPS, drop)
    block = tab[iv:iv + 2, js:js + 2, :, kd:kd + 2]
    w = (np.array([1 - wv, wv])[:, None, None] * np.array([1 - ws, ws])[None, :, None]
         * np.array([1 - wd, wd])[None, None, :])
    return np.einsum("ijek,ijk->e", block, w)


def _guess_elevation(curve: np.ndarray, dist: float, lob: bool) -> tuple[float, float] | None:
    """(elevation, d range / d elevation) on the low (or lob) branch, or None if out of reach."""
    if not np.isfinite(curve).any():
        return None
    peak = int(np.nanargmax(curve))
    if lob:
        br_e, br_d = _TABLE_ELEV[peak:][::-1], curve[peak:][::-1]
    else:
        br_e, br_d = _TABLE_ELEV[:peak + 1], curve[:peak + 1]
    ok = np.isfinite(br_d)
    br_e, br_d = br_e[ok], br_d[ok]
    if br_d.size < 2 or dist > br_d[-1] or dist < br_d[0]:
        return None
    i = int(np.clip(np.searchsorted(br_d, dist) - 1, 0, br_d.size - 2))
    slope = (br_d[i + 1] - br_d[i]) / (br_e[i + 1] - br_e[i])
    e = br_e[i] + (dist - br_d[i]) / slope if slope != 0 else br_e[i]
    return float(e), float(slope)


def _solve(contact_m, target_xy_m, speed_mps: float, spin_mps: float, net_clearance_m: float,
           lob: bool, aero: Aero) -> tuple[np.ndarray | None, float]:
    """(launch velocity or None, net margin in m: centre height at the net plane minus what
    clearing needs; +inf when the ball does not cross the net, NaN when no landing solution)."""
    x0, y0, z0 = (float(c) for c in np.asarray(contact_m, dtype=float).reshape(3))
    tx, ty = (float(c) for c in np.asarray(target_xy_m, dtype=float).reshape(2))
    if not speed_mps > 0 or not math.isfinite(speed_mps):
        raise ValueError(f"speed_mps must be positive and finite, got {speed_mps}")
    if not net_clearance_m >= 0:
        raise ValueError(f"net_clearance_m must be >= 0, got {net_clearance_m}")
    r = aero.ball_radius_m
    if z0 < r - 1e-9:
        raise ValueError(f"contact below the ground: contact_m z = {z0} < radius {r}")
    dist = math.hypot(tx - x0, ty - y0)
    if dist < 0.05:
        return None, math.nan
    cx, cy = (tx - x0) / dist, (ty - y0) / dist
    side = 1.0 if x0 > 0 else -1.0
    u_net, need = None, 0.0
    if abs(x0) > r and side * cx < 0:
        u = (side * r - x0) / cx
        if u < dist:
            u_net = u
            need = net_height_m(y0 + u * cy) + r + net_clearance_m
    guess = _guess_elevation(_range_curve(speed_mps, spin_mps, z0 - r, aero), dist, lob)
    if guess is None:
        return None, math.nan
    e, slope = guess
    prev = None
    for _ in range(8):
        land, z_net = _range_2d(z0, speed_mps * math.cos(e), speed_mps * math.sin(e), spin_mps,
                                u_net, aero)
        if math.isnan(land):
            return None, math.nan
        err = land - dist
        if abs(err) < 0.002:
            margin = math.inf if u_net is None else z_net - need
            if not margin >= 0:
                return None, margin
            return np.array([speed_mps * math.cos(e) * cx, speed_mps * math.cos(e) * cy,
                             speed_mps * math.sin(e)]), margin
        if prev is not None and prev[0] != e and prev[1] != err:
            slope = (err - prev[1]) / (e - prev[0])  # secant once two flights are known
        prev = (e, err)
        if slope == 0 or not math.isfinite(slope):
            break
        e = min(_TABLE_ELEV[-1], max(_TABLE_ELEV[0], e - err / slope))
    return None, math.nan


def solve_launch(contact_m, target_xy_m, speed_mps: float, spin_mps: float,
                 net_clearance_m: float = 0.0, lob: bool = False,
                 aero: Aero = DEFAULT_AERO) -> np.ndarray | None:
    """Launch velocity (3,) of magnitude `speed_mps` whose first bounce lands on `target_xy_m`
    (within 2 mm with `fly`'s integrator), passing the net with its bottom at least
    `net_clearance_m` above the cord if it crosses x = 0. The low trajectory unless `lob`.
    None when impossible at this speed (too slow to reach, or too fast to drop in over the net).
    """
    return _solve(contact_m, target_xy_m, speed_mps, spin_mps, net_clearance_m, lob, aero)[0]


def max_speed_to_land(contact_m, target_xy_m, spin_mps: float, net_clearance_m: float = 0.0,
                      aero: Aero = DEFAULT_AERO) -> float:
    """The fastest speed (m/s, within 0.05) for which `solve_launch` (low trajectory) succeeds:
    the speed at which the ball just clears the net and still drops onto the target.
    `math.inf` when the net never limits (no crossing, or still clear at 75 m/s); 0.0 when no
    speed works. Costs ~5-10 solves."""
    args = (contact_m, target_xy_m)
    top = float(_TABLE_SPEEDS[-1])
    vel, margin = _solve(*args, top, spin_mps, net_clearance_m, False, aero)
    if vel is not None:
        return math.inf
    # The slowest grid speed that reaches the target (its low root is near the highest arc).
    lo = None
    for v in np.arange(2.0, top, 1.0):
        vel, m_lo = _solve(*args, float(v), spin_mps, net_clearance_m, False, aero)
        if vel is not None:
            lo = float(v)
            break
        if not math.isnan(m_lo):  # reaches, but into the net already: nothing faster works
            return 0.0
    if lo is None:
        return 0.0
    hi = top
    while hi - lo > 0.05:  # bisection on "lands in over the net"
        mid = 0.5 * (lo + hi)
        if _solve(*args, mid, spin_mps, net_clearance_m, False, aero)[0] is not None:
            lo = mid
        else:
            hi = mid
    return lo
