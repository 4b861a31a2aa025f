"""Rally-end rules from tracking: who won a rally and why, judged from the positions alone.

`RallyTracker` follows B rallies at once, one `update` a frame, as the simulator rolls a model
forward; `analyse_rallies` runs the same tracker over whole recorded tracks
(`sportsngen.eval.rules.analyse_rally_data` over a `RallyData`).
A rally is one serve and what follows; its track starts at the toss. Objects are in the order
[server, receiver, ball], positions in metres in the `court` frame.

Events come from the ball's finite-difference velocity. At the frame t, the segment between
frames t-2 and t-1 is judged from the velocities just before (t-3 -> t-2) and just after
(t-1 -> t) it, so an impulse inside the segment sees clean flight on both sides (a lag of two
frames). The segment's own velocity tells where inside it the impulse fell (it has moved that
share of the way from before to after), which places the event in exactly one segment.

- racket contact: the horizontal velocity reverses from away-from-the-net to toward it on the
  side of the player due to hit (for the serve, it jumps from toss speed to serve speed toward
  the receiver); the contact is where the flights before and after meet;
- net: the hitter's ball, low and near the net, stops heading over it (unless a player within
  reach hit it);
- bounce: the ball, low, goes from falling to rising (or rolling) without reversing; the bounce
  point is the incoming flight extrapolated as a parabola (acceleration measured, so drag and
  spin count) down to one ball radius.

Rules, with `hitter` the player of the last contact: the net ends the rally (the hitter loses,
a fault on a serve); a first bounce outside the right service box (serve) or the opponent's
singles court (any other shot), including one on the hitter's own side, is out (the hitter loses;
a fault, or a double fault on a second serve); a second bounce on the far side, or the ball
passing behind the far baseline out of the opponent's reach after a good bounce, is a winner (an
ace if only the serve was struck); a ball at rest decides like what it stands for (at the net
on the hitter's side: the net; elsewhere without a good bounce: out; after one: a winner). The
centre of the ball decides in/out, as in the generator.

Conventions of the results: roles 0 server, 1 receiver, -1 none. `winner` is -1 for a first-serve
fault and for rallies stopped without a decision (duration cap, no serve, track too short).
`end_reason` is one of `END_CLASSES` or "none": the rules cannot tell a forced from an unforced
error, so both are "error" ("error, kind unknown"); `end_class` maps the schema's
`END_REASONS` onto these classes. `end_detail` is one of `END_DETAILS`.

A rally breaking physics is still judged and kept, with `realistic` False and the failed checks
named (`CHECKS`): "through_net", "through_ground", "position_jump", "contact_out_of_reach",
"serve_position", "no_serve" and "duration_cap".
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.tennis import court
from sportsngen.tennis.court import BALL_RADIUS_M, BASELINE_X_M, SINGLES_HALF_WIDTH_M

SERVER, RECEIVER, BALL = 0, 1, 2
GRAVITY_MPS2 = 9.81

# Event detection (thresholds leave slack for the model's binned, noisier tracks).
BOUNCE_MAX_Z_M = 0.6            # lower of the two frames around a bounce at 25 Hz is below this
BOUNCE_MIN_VZ_IN_MPS = 1.0      # falling at least this fast before a bounce ...
BOUNCE_MIN_VZ_OUT_MPS = 0.5     # ... and rising at least this fast after it (or rolling:
ROLL_MAX_Z_M = 0.1              # staying this low, at a vertical speed below that)
SHOT_MIN_VX_MPS = 1.0           # a contact reverses vx, at least this fast both ways
TOSS_MAX_HSPEED_MPS = 5.0       # horizontal ball speed while tossed ...
SERVE_MIN_HSPEED_MPS = 12.0     # ... and just after the serve is struck
CONTACT_REACH_M = 2.5           # horizontal distance from a player's centre to a ball he hits
CONTACT_MAX_Z_M = 3.5
CONTACT_GAP_FRAMES = 3          # segments between two contacts, or two bounces, at least
EVENT_MIN_SHARE = 0.1           # share of the velocity change seen inside the event's segment
SERVE_SLIVER_MIN_MPS = 2.0      # a serve's sliver, above tracking noise, read back to its contact
BOUNCE_AFTER_CONTACT_FRAMES = 2  # no bounce this soon after a contact (velocities still mixed)
BOUNCE_MAX_ACC_H_MPS2 = 40.0    # drag on a fast ball; measured accelerations are clipped to
BOUNCE_MAX_ACC_DOWN_G = 2.0     # these bounds (down: between 0.5 g and 2 g, gravity plus
BOUNCE_MIN_ACC_DOWN_G = 0.5     # Magnus) when extrapolating to the bounce
LINE_ALLOWANCE_M = 0.0          # the ball's centre decides in/out, as in the generator
NET_ZONE_M = 1.0                # a ball this close to the net plane ...
NET_ZONE_ABOVE_M = 0.3          # ... and at most this far above the cord may be touching it
NET_STOP_VX_MPS = 0.5           # toward the net slower than this after the touch
PASS_BEYOND_BASELINE_M = 2.0    # a ball this far behind the baseline and out of reach is past
REST_SPEED_MPS = 1.5            # a ball slower than this ...
REST_FRAMES = 8                 # ... for this many frames is at rest
NO_SERVE_S = 4.0                # no serve struck by then: the rally is stopped
# A rally still going after this long is stopped and flagged (a safety net, not a rule): the
# generator's clay rallies last over 30 s 1.06 % of the time (mean 26 shots; the longest 83 s
# of 16,413). At the former 30 s the simulator stopped its own long rallies there, and the
# statistics, which drop flagged points, lost them while the truth kept its own: the simulated
# mean rally read 0.10-0.17 shots short (docs/evaluation.md, fifty-first part).
MAX_RALLY_S = 120.0

# Realism checks.
NET_THROUGH_TOL_M = 0.10        # crossing with the ball's bottom this far below the cord
NET_CARRY_M = 0.5               # ... and going on this far past the net: through the net
GROUND_MIN_Z_M = -0.1
BALL_MAX_SPEED_MPS = 75.0       # faster than the fastest serve: a jump in the track
PLAYER_MAX_SPEED_MPS = 12.0     # faster than any sprinter
SERVE_INSIDE_TOL_M = 1.0        # the serve's contact may be this far inside the baseline (the
SERVE_CENTRE_TOL_M = 0.3        # server leans in), this far over the centre mark's line
SERVE_WIDE_TOL_M = 1.5          # and this far beyond the singles sideline

END_CLASSES = ("fault", "ace", "double_fault", "winner", "error")
REASONS = ("none",) + END_CLASSES
CHECKS = ("through_net", "through_ground", "position_jump", "contact_out_of_reach",
          "serve_position", "no_serve", "duration_cap")
_R = {name: i for i, name in enumerate(REASONS)}
# How a recorded rally ended (the tracking schema's `end_reason` / `end_detail` columns).
END_REASONS = ("fault", "ace", "double_fault", "winner", "forced_error", "unforced_error")
END_DETAILS = ("none", "net", "out", "unreached")
_D = {name: i for i, name in enumerate(END_DETAILS)}
_C = {name: 1 << i for i, name in enumerate(CHECKS)}
_HIST = 6  # frames of history: t-5 .. t


def end_class(end_reason):
    """Schema end reasons (`END_REASONS`) -> `END_CLASSES`: forced and unforced errors are
    "error"; anything else passes through. Scalar or array-like of str."""
    r = np.asarray(end_reason, dtype=object)
    unknown = set(r.ravel().tolist()) - set(END_REASONS) - set(REASONS)
    if unknown:
        raise ValueError(f"unknown end reasons {sorted(map(str, unknown))}")
    out = np.where(np.isin(r, ("forced_error", "unforced_error")), "error", r).astype(str)
    return out.item() if out.ndim == 0 else out


def _deuce_flags(side, n: int) -> np.ndarray:
    s = np.broadcast_to(np.asarray(side), (n,))
    if s.dtype == bool:
        return s.copy()
    bad = set(s.astype(str).tolist()) - set(court.SERVING_SIDES)
    if bad:
        raise ValueError(f"side must be 'deuce'/'ad' or bool (True = deuce), got {sorted(bad)}")
    return s.astype(str) == "deuce"


def _in_service_box(x, y, server_end: np.ndarray, deuce: np.ndarray) -> np.ndarray:
    out = np.zeros(len(x), dtype=bool)
    for end in (-1, 1):
        for is_deuce, side in ((True, "deuce"), (False, "ad")):
            m = (server_end == end) & (deuce == is_deuce)
            if m.any():
                out[m] = court.is_in_service_box(x[m], y[m], end, side, LINE_ALLOWANCE_M)
    return out


def _share(before: np.ndarray, during: np.ndarray, after: np.ndarray) -> np.ndarray:
    """How far a segment's velocity has moved from the velocity before it to the one after."""
    return (during - before) / np.where(after != before, after - before, np.nan)


def _bounce_point(p_a, p_b, p_c, fps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where (x, y) and when (s after frame c) the flight through frames a, b, c (B, 3 each)
    reaches the ground (centre one radius up), extrapolated as a parabola.

    The acceleration is measured from the three frames because drag and spin move the bounce
    by centimetres, enough to turn line calls (gravity alone lands 2 cm long on average on
    generated serves, the measured one 0.3 cm short); it is clipped to what a ball can do so
    that noisy tracks do not throw the bounce far. Without frame a (NaN) it is gravity."""
    dt = 1.0 / fps
    v = (p_c - p_b) * fps
    acc = (p_c - 2.0 * p_b + p_a) * fps * fps
    acc = np.where(np.isfinite(acc), acc, np.array([0.0, 0.0, -GRAVITY_MPS2]))
    h = np.hypot(acc[:, 0], acc[:, 1])
    acc[:, :2] *= (np.minimum(h, BOUNCE_MAX_ACC_H_MPS2) / np.maximum(h, 1e-9))[:, None]
    acc[:, 2] = np.clip(acc[:, 2], -BOUNCE_MAX_ACC_DOWN_G * GRAVITY_MPS2,
                        -BOUNCE_MIN_ACC_DOWN_G * GRAVITY_MPS2)
    v0 = v + 0.5 * dt * acc
    c = np.maximum(p_c[:, 2] - BALL_RADIUS_M, 0.0)
    a_half, b = 0.5 * acc[:, 2], v0[:, 2]
    s = 2.0 * c / (-b + np.sqrt(np.maximum(b * b - 4.0 * a_half * c, 0.0)))
    s = np.clip(np.nan_to_num(s, nan=0.0, posinf=3.0 * dt), 0.0, 3.0 * dt)
    at = p_c[:, :2] + v0[:, :2] * s[:, None] + 0.5 * acc[:, :2] * (s * s)[:, None]
    return at[:, 0], at[:, 1], s


def awaiting_return(n_shots: np.ndarray) -> np.ndarray:
    """(N,) bool: rallies whose next contact is the return, from their contacts so far
    (`RallyTracker.n_shots`: only the serve struck)."""
    return np.asarray(n_shots) == 1


class RallyTracker:
    """Incremental rally-end rules for B rallies (see the module doc).

    `server_end` (B,) +-1: sign of x of the server's baseline; `side` (B,) "deuce"/"ad" (or bool,
    True = deuce); `serve_number` (B,) 1 or 2; `fps` frames per second; rallies still going after
    `max_duration_s` (one for all or (B,), each its own) are stopped and flagged. Call `update`
    once a frame from the first frame.
    """

    # `update` by the compiled kernel (`rally_kernel`); False: by the numpy methods, its
    # reference (the tests compare them).
    compiled = True

    def __init__(self, server_end, side, serve_number, fps: float,
                 max_duration_s: float = MAX_RALLY_S):
        end = np.atleast_1d(np.asarray(server_end)).astype(int)
        if not np.isin(end, (-1, 1)).all():
            raise ValueError(f"server_end must be +1 or -1, got {np.unique(end).tolist()}")
        n = len(end)
        serve = np.broadcast_to(np.asarray(serve_number), (n,)).astype(int)
        if not np.isin(serve, (1, 2)).all():
            raise ValueError(f"serve_number must be 1 or 2, got {np.unique(serve).tolist()}")
        cap_s = np.broadcast_to(np.asarray(max_duration_s, dtype=float), (n,))
        if not fps > 0 or not (cap_s > 0).all():
            raise ValueError(f"fps and max_duration_s must be positive, got {fps}, "
                             f"{max_duration_s}")
        self.fps = float(fps)
        self.max_frames = np.round(cap_s * fps).astype(np.int64)    # each rally's own cap
        self.server_end = end
        self.deuce = _deuce_flags(side, n)
        self.serve_number = serve.copy()
        i0 = lambda v: np.full(n, v, dtype=np.int64)  # noqa: E731
        self._hist = np.full((n, _HIST, 3, 3), np.nan)
        self.seen = i0(0)                 # frames received
        self.ended = np.zeros(n, dtype=bool)
        self.end_frame = i0(-1)
        self.winner = i0(-1)
        self._reason = i0(0)
        self._detail = i0(0)
        self.hitter = i0(-1)              # role of the last contact, -1 before the serve
        self.n_shots = i0(0)
        self.n_bounces = i0(0)            # bounces on the far side since the last contact
        self._last_contact = i0(-10 ** 6)  # segment index of the last contact / bounce
        self._last_bounce = i0(-10 ** 6)
        self._serve_next = np.zeros(n, dtype=bool)  # the serve's sliver seen: read it next
        self._rest = i0(0)
        self._through = np.zeros(n)       # side a ball that crossed below the cord went to
        self.flags = i0(0)                # bit i set: CHECKS[i] failed
        cap = 8
        self.contact_frame = np.full((n, cap), -1, dtype=np.int64)
        self.contact_hitter = np.full((n, cap), -1, dtype=np.int64)
        self.contact_m = np.full((n, cap, 3), np.nan)
        self.contact_gap_m = np.full((n, cap), np.nan)  # hitter's centre to ball, horizontal
        self.bounce_frame = np.full((n, cap), -1, dtype=np.int64)
        self.bounce_m = np.full((n, cap, 2), np.nan)
        self.n_bounces_total = i0(0)

    def __len__(self) -> int:
        return len(self.server_end)

    def recent_frames(self, rows: np.ndarray) -> np.ndarray:
        """(rows, 6, 3, 3) the last frames fed for these rallies, oldest first (NaN before
        the first)."""
        return self._hist[np.asarray(rows)].copy()

    def frames_since_contact(self, rows: np.ndarray) -> np.ndarray:
        """(rows,) frames from the last racket contact to the newest frame fed (a large
        number before the serve)."""
        rows = np.asarray(rows)
        last = self.contact_frame[rows, np.clip(self.n_shots[rows] - 1, 0, None)]
        return np.where(self.n_shots[rows] > 0, self.seen[rows] - 1 - last, 10 ** 6)

    # -- results -----------------------------------------------------------------------------
    @property
    def end_reason(self) -> np.ndarray:
        """(B,) str: one of `REASONS` ("none" while going on or stopped undecided)."""
        return np.asarray(REASONS, dtype=object)[self._reason].astype(str)

    @property
    def end_detail(self) -> np.ndarray:
        """(B,) str: one of `END_DETAILS`."""
        return np.asarray(END_DETAILS, dtype=object)[self._detail].astype(str)

    @property
    def realistic(self) -> np.ndarray:
        return self.flags == 0

    @property
    def failed_checks(self) -> list[list[str]]:
        return [[c for c in CHECKS if f & _C[c]] for f in self.flags.tolist()]

    def results(self) -> pd.DataFrame:
        """One row a rally (in the tracker's order): outcome, shots, bounces, realism."""
        n = len(self)
        ns, nb = self.n_shots, self.n_bounces_total
        return pd.DataFrame({
            "ended": self.ended.copy(), "end_frame": self.end_frame.copy(),
            "winner": self.winner.copy(), "end_reason": self.end_reason,
            "end_detail": self.end_detail, "n_shots": ns.copy(),
            "contact_frames": [self.contact_frame[i, :ns[i]].tolist() for i in range(n)],
            "hitters": [self.contact_hitter[i, :ns[i]].tolist() for i in range(n)],
            "contacts_m": [self.contact_m[i, :ns[i]].tolist() for i in range(n)],
            "contact_gaps_m": [self.contact_gap_m[i, :ns[i]].tolist() for i in range(n)],
            "bounce_frames": [self.bounce_frame[i, :nb[i]].tolist() for i in range(n)],
            "bounces_m": [self.bounce_m[i, :nb[i]].tolist() for i in range(n)],
            "realistic": self.realistic, "failed_checks": self.failed_checks,
        })

    def select(self, idx) -> RallyTracker:
        """Keep only the rallies at positions `idx`, in that order (in place); returns self.
        Read the results of the rallies being dropped before."""
        idx = np.asarray(idx, dtype=np.int64)
        n = len(self)
        for name, value in list(vars(self).items()):
            if isinstance(value, np.ndarray) and value.ndim >= 1 and len(value) == n:
                setattr(self, name, value[idx])
        return self

    # -- bookkeeping ---------------------------------------------------------------------------
    def _room(self, counts: np.ndarray, names: tuple[str, ...]) -> None:
        cap = getattr(self, names[0]).shape[1]
        if counts.size and counts.max() >= cap:
            for name in names:
                a = getattr(self, name)
                pad = np.full((a.shape[0], cap) + a.shape[2:],
                              np.nan if a.dtype.kind == "f" else -1, dtype=a.dtype)
                setattr(self, name, np.concatenate([a, pad], axis=1))

    def _flag(self, mask: np.ndarray, check: str) -> None:
        self.flags[mask] |= _C[check]

    def _end(self, mask: np.ndarray, winner, reason, detail, frame) -> None:
        if not mask.any():      # most frames end nothing: skip the five selections
            return
        self.ended |= mask
        self.winner = np.where(mask, winner, self.winner)
        self._reason = np.where(mask, reason, self._reason)
        self._detail = np.where(mask, detail, self._detail)
        self.end_frame = np.where(mask, frame, self.end_frame)

    def _hitter_loses(self, mask: np.ndarray, detail: str, frame) -> None:
        if not mask.any():
            return
        serve = self.n_shots == 1
        second = self.serve_number == 2
        reason = np.where(serve, np.where(second, _R["double_fault"], _R["fault"]), _R["error"])
        winner = np.where(serve, np.where(second, RECEIVER, -1), 1 - self.hitter)
        self._end(mask, winner, reason, _D[detail], frame)

    def _hitter_wins(self, mask: np.ndarray, frame) -> None:
        if not mask.any():
            return
        reason = np.where(self.n_shots == 1, _R["ace"], _R["winner"])
        self._end(mask, self.hitter, reason, _D["unreached"], frame)

    def _end_of(self, role: np.ndarray) -> np.ndarray:
        """Sign of x of the baseline of `role` (0 server, 1 receiver)."""
        return np.where(role == SERVER, self.server_end, -self.server_end)

    # -- the frame step ------------------------------------------------------------------------
    def update(self, pos_m, active=None) -> np.ndarray:
        """Feed the next frame, `pos_m` (B, 3, 3) [server, receiver, ball] in metres. Rallies
        already over, or not in the optional (B,) bool mask `active`, are left as they are.
        Returns `ended` (B,) bool: which rallies are over. A rally is known to be over two
        frames after its deciding event (`end_frame`), eight after a ball comes to rest."""
        pos = np.asarray(pos_m, dtype=float)
        if pos.shape != (len(self), 3, 3):
            raise ValueError(f"pos_m must have shape ({len(self)}, 3, 3), got {pos.shape}")
        live = ~self.ended if active is None else ~self.ended & np.asarray(active, dtype=bool)
        if not live.any():
            return self.ended.copy()
        if self.compiled:
            self._update_compiled(pos, live)
            return self.ended.copy()
        self._hist[live, :-1] = self._hist[live, 1:]
        self._hist[live, -1] = pos[live]
        self.seen[live] += 1
        with np.errstate(invalid="ignore", divide="ignore"):
            self._impulses(live & (self.seen >= 4))
            self._frame_rules(live & ~self.ended)
        return self.ended.copy()

    def _update_compiled(self, pos: np.ndarray, live: np.ndarray) -> None:
        """`update`'s step by `rally_kernel.update_rows` (the numpy methods below are its
        reference), after making room for one more contact and bounce a rally."""
        from sportsngen.tennis import rally_kernel

        self._room(self.n_shots, ("contact_frame", "contact_hitter", "contact_m",
                                  "contact_gap_m"))
        self._room(self.n_bounces_total, ("bounce_frame", "bounce_m"))
        rally_kernel.update_rows(
            np.ascontiguousarray(pos), live, self.fps, self._hist, self.seen, self.ended,
            self.end_frame, self.winner, self._reason, self._detail, self.hitter, self.n_shots,
            self.n_bounces, self._last_contact, self._last_bounce, self._serve_next, self._rest,
            self._through, self.flags, self.contact_frame, self.contact_hitter, self.contact_m,
            self.contact_gap_m, self.bounce_frame, self.bounce_m, self.n_bounces_total,
            self.server_end, self.deuce, self.serve_number, self.max_frames)

    def _impulses(self, live: np.ndarray) -> None:
        """Contacts and bounces inside the segment (t-2, t-1)."""
        fps, dt = self.fps, 1.0 / self.fps
        ball = self._hist[:, :, BALL]
        va = (ball[:, -3] - ball[:, -4]) * fps        # flight before the segment
        vb = (ball[:, -1] - ball[:, -2]) * fps        # flight after it
        vm = (ball[:, -2] - ball[:, -3]) * fps        # the segment itself
        seg = self.seen - 3                            # frame index of the segment's start
        p0 = ball[:, -3]

        # Where the flights before and after the segment meet (along x): the contact time.
        dvx = va[:, 0] - vb[:, 0]
        s1 = np.where(np.abs(dvx) > 1e-9, (ball[:, -2, 0] - vb[:, 0] * dt - p0[:, 0]) / dvx,
                      0.5 * dt)
        s1 = np.clip(np.nan_to_num(s1, nan=0.5 * dt), 0.0, dt)
        contact = p0 + va * s1[:, None]
        frac = (s1 * fps)[:, None]
        before, after = self._hist[:, -3, :2, :2], self._hist[:, -2, :2, :2]
        players = before + (after - before) * frac[:, :, None]
        half = np.where(contact[:, 0] >= 0.0, 1, -1)
        who = np.where(half == self.server_end, SERVER, RECEIVER)
        hs_a, hs_b = np.hypot(va[:, 0], va[:, 1]), np.hypot(vb[:, 0], vb[:, 1])
        # The event must lie in this segment, not the next: the segment's own velocity has
        # already moved part of the way from before to after (else a fast serve struck early
        # in the next segment would be caught one segment too soon).
        spaced = seg - self._last_contact >= CONTACT_GAP_FRAMES
        in_segment = _share(va[:, 0], vm[:, 0], vb[:, 0]) > EVENT_MIN_SHARE
        free = spaced & in_segment
        served = live & (self.n_shots == 0) & (hs_b > SERVE_MIN_HSPEED_MPS) & \
            (vb[:, 0] * self.server_end < 0)
        # A serve struck in the last tenth of a segment shows only a sliver of its flight there
        # (a fast one, faster than a toss): it is read in the next segment, whose flight before
        # is that sliver, and its contact found back along the flight by the sliver's length.
        late = served & free & self._serve_next & (np.abs(va[:, 0]) > SERVE_SLIVER_MIN_MPS)
        serve = served & free & ((hs_a < TOSS_MAX_HSPEED_MPS) | self._serve_next)
        self._serve_next = np.where(live, served & spaced & ~in_segment &
                                    (hs_a < TOSS_MAX_HSPEED_MPS), self._serve_next)
        if late.any():
            back_s = np.abs(va[:, 0]) / np.maximum(np.abs(vm[:, 0]), 1e-9) * dt
            contact = np.where(late[:, None], p0 - vm * back_s[:, None], contact)
            frac = np.where(late[:, None], 0.0, frac)
            players = np.where(late[:, None, None], before, players)
            half = np.where(contact[:, 0] >= 0.0, 1, -1)
            who = np.where(half == self.server_end, SERVER, RECEIVER)
        role = np.where(serve, SERVER, who)
        mine = players[np.arange(len(self)), role]
        gap = np.hypot(*(contact[:, :2] - mine).T)
        reach = (gap <= CONTACT_REACH_M) & (contact[:, 2] <= CONTACT_MAX_Z_M)
        # A reversal at the net with nobody there is the ball bouncing off the net (noise may
        # put the meeting point just over it), not a shot.
        at_net = (np.abs(contact[:, 0]) < NET_ZONE_M) & ~reach
        reverse = (va[:, 0] * half > SHOT_MIN_VX_MPS) & (vb[:, 0] * half < -SHOT_MIN_VX_MPS)
        shot = live & free & (self.n_shots > 0) & reverse & (who != self.hitter) & ~at_net
        hit = serve | shot
        if hit.any():
            self._flag(hit & ~reach, "contact_out_of_reach")
            e = self.server_end
            sy = contact[:, 1] * np.where(self.deuce, e, -e)  # >= 0 on the correct half
            placed = (contact[:, 0] * e >= BASELINE_X_M - SERVE_INSIDE_TOL_M) & \
                (sy >= -SERVE_CENTRE_TOL_M) & (sy <= SINGLES_HALF_WIDTH_M + SERVE_WIDE_TOL_M)
            self._flag(serve & ~placed, "serve_position")
            self._room(self.n_shots[hit], ("contact_frame", "contact_hitter", "contact_m",
                                           "contact_gap_m"))
            i = np.flatnonzero(hit)
            k = self.n_shots[i]
            self.contact_frame[i, k] = seg[i] + (frac[i, 0] >= 0.5)
            self.contact_hitter[i, k] = role[i]
            self.contact_m[i, k] = contact[i]
            self.contact_gap_m[i, k] = gap[i]
            self.n_shots[i] += 1
            self.hitter[i] = role[i]
            self.n_bounces[i] = 0
            self._last_contact[i] = seg[i]

        # Rising again, or landing dead (rolling on from there, as the generator's balls do
        # after their second bounce).
        dead = (np.maximum(ball[:, -2, 2], ball[:, -1, 2]) < ROLL_MAX_Z_M) & \
            (np.abs(vb[:, 2]) <= BOUNCE_MIN_VZ_OUT_MPS)
        # A ball that comes back off the bottom of the net rises again too, but the ground
        # never turns it around: near the net, a turn is the net's (a return driven into it
        # 6 cm up read as landing 9 cm past it, in play).
        off_net = (np.abs(p0[:, 0]) < NET_ZONE_M) & (va[:, 0] * vb[:, 0] < 0.0)
        bounce = live & ~hit & ~off_net & (self.hitter >= 0) & \
            (va[:, 2] < -BOUNCE_MIN_VZ_IN_MPS) & \
            ((vb[:, 2] > BOUNCE_MIN_VZ_OUT_MPS) | dead) & \
            (np.minimum(p0[:, 2], ball[:, -2, 2]) < BOUNCE_MAX_Z_M) & \
            (seg - self._last_bounce >= CONTACT_GAP_FRAMES) & \
            (seg - self._last_contact >= BOUNCE_AFTER_CONTACT_FRAMES) & \
            (_share(va[:, 2], vm[:, 2], vb[:, 2]) > EVENT_MIN_SHARE)
        if bounce.any():
            self._bounce(bounce, ball, va, vm, vb, seg)
        # The net: the hitter's ball, near the net, stops heading over it (checked after a
        # bounce in the same segment: a ball landing short on its own side may then reach it).
        e_h = self._end_of(self.hitter)
        net = live & ~hit & ~self.ended & (self.hitter >= 0) & (np.abs(p0[:, 0]) < NET_ZONE_M) & \
            (p0[:, 2] < court.net_height_m(p0[:, 1]) + NET_ZONE_ABOVE_M) & \
            (va[:, 0] * e_h < -SHOT_MIN_VX_MPS) & (vb[:, 0] * e_h > -NET_STOP_VX_MPS)
        self._hitter_loses(net, "net", seg)

    def _bounce(self, bounce: np.ndarray, ball: np.ndarray, va: np.ndarray, vm: np.ndarray,
                vb: np.ndarray, seg: np.ndarray) -> None:
        """Locate the bounces in `bounce` (B,) and apply the bounce rules."""
        fps = self.fps
        # From frame t-2, or from t-3 when the bounce sits at the very start of the segment
        # (frame t-2 may then be just past it).
        late = (_share(va[:, 2], vm[:, 2], vb[:, 2]) > 1.0 - EVENT_MIN_SHARE)[:, None]
        start = np.where(late, ball[:, -4], ball[:, -3])
        bx, by, s = _bounce_point(np.where(late, ball[:, -6], ball[:, -5]),
                                  np.where(late, ball[:, -5], ball[:, -4]), start, fps)
        frame = seg - late[:, 0] + np.round(s * fps).astype(np.int64)
        self._room(self.n_bounces_total[bounce], ("bounce_frame", "bounce_m"))
        i = np.flatnonzero(bounce)
        self.bounce_frame[i, self.n_bounces_total[i]] = frame[i]
        self.bounce_m[i, self.n_bounces_total[i]] = np.stack([bx[i], by[i]], axis=1)
        self.n_bounces_total[i] += 1
        self._last_bounce[i] = seg[i]

        side = np.where(bx >= 0.0, 1, -1)
        own = bounce & (side == self._end_of(self.hitter))
        first = bounce & ~own & (self.n_bounces == 0)
        second = bounce & ~own & (self.n_bounces >= 1)
        good = np.where(self.n_shots == 1,
                        _in_service_box(bx, by, self.server_end, self.deuce),
                        court.is_in_singles(bx, by, side, LINE_ALLOWANCE_M))
        self._hitter_loses(own | (first & ~good), "out", frame)
        self.n_bounces[first & good] = 1
        self._hitter_wins(second, frame)

    def _frame_rules(self, live: np.ndarray) -> None:
        """Checks on the newest frame t: jumps, ground, net, a passed or resting ball, caps."""
        fps = self.fps
        now, prev = self._hist[:, -1], self._hist[:, -2]
        t = self.seen - 1
        moved = live & (self.seen >= 2)
        step = np.linalg.norm(now[:, :, :2] - prev[:, :, :2], axis=-1) * fps  # (B, 3)
        ball_v = np.linalg.norm(now[:, BALL] - prev[:, BALL], axis=-1) * fps
        jump = (ball_v > BALL_MAX_SPEED_MPS) | (step[:, :2] > PLAYER_MAX_SPEED_MPS).any(axis=1)
        self._flag(moved & jump, "position_jump")
        self._flag(live & (now[:, BALL, 2] < GROUND_MIN_Z_M), "through_ground")

        # Through the net: a crossing below the cord that carries on to the other side.
        x0, x1 = prev[:, BALL, 0], now[:, BALL, 0]
        cross = moved & (np.sign(x0) != np.sign(x1)) & (x1 != 0.0)
        w = np.abs(x0) / (np.abs(x0) + np.abs(x1))
        y_net = prev[:, BALL, 1] + w * (now[:, BALL, 1] - prev[:, BALL, 1])
        z_net = prev[:, BALL, 2] + w * (now[:, BALL, 2] - prev[:, BALL, 2])
        below = cross & (z_net - BALL_RADIUS_M < court.net_height_m(y_net) - NET_THROUGH_TOL_M)
        back = cross & (np.sign(x1) != self._through)
        self._through = np.where(below, np.sign(x1), np.where(back, 0.0, self._through))
        through = live & (self._through != 0) & (x1 * self._through > NET_CARRY_M)
        self._flag(through, "through_net")
        self._through[through] = 0.0

        played = live & (self.hitter >= 0)
        # A ball behind the opponent's baseline and out of his reach after a good bounce.
        opp = 1 - self.hitter
        e = self._end_of(opp)
        opp_xy = now[np.arange(len(self)), np.clip(opp, 0, 1), :2]
        gap = np.hypot(now[:, BALL, 0] - opp_xy[:, 0], now[:, BALL, 1] - opp_xy[:, 1])
        past = played & (self.n_bounces >= 1) & \
            (x1 * e > BASELINE_X_M + PASS_BEYOND_BASELINE_M) & (x1 * e > opp_xy[:, 0] * e) & \
            (gap > CONTACT_REACH_M)
        self._hitter_wins(past, t)

        # A ball at rest decides like the bounce it stands for.
        still = moved & (ball_v < REST_SPEED_MPS)
        self._rest = np.where(still, self._rest + 1, 0)
        rest = played & ~past & (self._rest >= REST_FRAMES)
        own = np.where(x1 >= 0.0, 1, -1) == self._end_of(self.hitter)
        at_net = (np.abs(x1) < NET_ZONE_M) & (np.abs(now[:, BALL, 1]) < court.NET_POST_Y_M)
        self._hitter_loses(rest & own & at_net, "net", t)
        self._hitter_loses(rest & ((own & ~at_net) | (~own & (self.n_bounces == 0))), "out", t)
        self._hitter_wins(rest & ~own & (self.n_bounces >= 1), t)

        undecided = live & ~self.ended
        no_serve = undecided & (self.hitter < 0) & (self.seen >= NO_SERVE_S * fps)
        self._flag(no_serve, "no_serve")
        capped = undecided & ~no_serve & (self.seen >= self.max_frames)
        self._flag(capped, "duration_cap")
        self._end(no_serve | capped, -1, _R["none"], _D["none"], t)


MIN_COMPACT_RALLIES = 16   # `analyse_rallies` compacts batches of at least this many rallies


def analyse_rallies(pos_m, length, server_end, side, serve_number, fps: float,
                    max_duration_s: float = MAX_RALLY_S) -> pd.DataFrame:
    """The rules over whole tracks: `pos_m` (B, T, 3, 3) [server, receiver, ball] padded after
    `length` (B,) frames. One row a rally (columns of `RallyTracker.results`); a rally whose
    track ends undecided has ended False."""
    pos = np.asarray(pos_m, dtype=float)
    if pos.ndim != 4 or pos.shape[2:] != (3, 3):
        raise ValueError(f"pos_m must have shape (B, T, 3, 3), got {pos.shape}")
    length = np.broadcast_to(np.asarray(length, dtype=np.int64), (pos.shape[0],))
    if (length > pos.shape[1]).any() or (length < 0).any():
        raise ValueError(f"length must lie in [0, {pos.shape[1]}]")
    tracker = RallyTracker(server_end, side, serve_number, fps, max_duration_s)
    rows = np.arange(pos.shape[0])     # the tracker's rallies, as rows of `pos_m`
    t0, parts = 0, []
    for t in range(int(length.max(initial=0))):
        active = length[rows] > t
        done = tracker.update(pos[:, t - t0], active) | ~active
        if done.all():
            break
        # A rally ended (or whose track ended) changes no more: once half the batch is such,
        # its rows are read out and the rest stepped on alone, so a frame costs what the rallies
        # still going cost, not the longest's batch (3,000 generated rallies: about half the time).
        if 2 * done.sum() >= len(rows) >= MIN_COMPACT_RALLIES:
            res = tracker.results()
            parts.append(res[done].set_axis(rows[done]))
            going = np.flatnonzero(~done)
            tracker.select(going)
            rows, pos, t0 = rows[going], pos[going, t - t0 + 1:], t + 1
    parts.append(tracker.results().set_axis(rows))
    if len(parts) == 1:
        return parts[0].reset_index(drop=True)
    return pd.concat(parts).sort_index().reset_index(drop=True)
