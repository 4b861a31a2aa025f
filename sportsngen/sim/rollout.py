"""Batched rollouts of the decoder f: B rallies at once, frame by frame, until each one ends.

Each step turns the newest frame of every live rally into object tokens, runs them through the
decoder with the ring key/value cache (`SportsNGEN.forward_step`), samples the next frame
(nucleus per object kind, then uniform inside the bin: `SportsNGEN.sample_next`) and hands it
to a rally tracker (`sportsngen.tennis.rally.RallyTracker`, or anything with the same
`update` / `select`) which says which rallies just ended. Finished rallies leave the batch (the
cache, the tracker and the sampling state are compacted), so a batch costs what its live
rallies cost.

`mode` picks how the decoder sees the past, for tests and benchmarks:

- ``"cache"`` (default): the ring cache; exact for the band-attention model at any length.
- ``"recompute"``: re-run `forward` on the whole rally so far at every step (the same model,
  the slow way: what the cache must equal).
- ``"window"``: re-run `forward` on the last `window_frames` frames only (the naive rolling
  window: the same as the others until a rally outgrows the window, a truncated history after).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch
from tqdm.auto import tqdm

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL, object_features
from sportsngen.model.receiver_start import receiver_waiting, wait_frames
from sportsngen.sim.frame_draws import Constraint, FrameDraws, Tracker
from sportsngen.sim.kinematics import PlayerLimits

MODES = ("cache", "recompute", "window")
# Up to this many rallies a rollout runs on one CPU thread: a step is then ~100 tiny operations
# whose thread hand-offs cost more than the second thread gives (docs/benchmarks.md).
SINGLE_THREAD_ROWS = 8


@contextmanager
def cpu_threads(n: int | None) -> Iterator[None]:
    """Run the block with at most `n` torch CPU threads (None: unchanged), then restore."""
    old = torch.get_num_threads()
    if n is None or n >= old:
        yield
        return
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)


@dataclass
class RolloutInputs:
    """One row per rally: its first frames and its context (vocabulary indices)."""

    init_pos_m: np.ndarray   # (B, T0, 3, 3) server, receiver, ball; frame 0 = rally start
    ident: np.ndarray        # (B, 3) int64
    surface: np.ndarray      # (B,) int64
    tournament: np.ndarray   # (B,) int64
    serve: np.ndarray        # (B,) int64: 0 first serve, 1 second serve
    score: np.ndarray        # (B, 7) float32 (`sportsngen.model.inputs.score_vector`)
    # (B,) each row's own count of initial frames (at most T0; the rest of its row is not
    # read): rallies branched at different frames share one rollout. None: T0 for every row.
    init_frames: np.ndarray | None = None

    def __post_init__(self) -> None:
        b = len(self.init_pos_m)
        if self.init_pos_m.ndim != 4 or self.init_pos_m.shape[2:] != (3, 3):
            raise ValueError(f"init_pos_m must be (B, T0, 3, 3), got {self.init_pos_m.shape}")
        t0 = self.init_pos_m.shape[1]
        if t0 < 1:
            raise ValueError("rollouts need at least one initial frame")
        kept = np.ones((b, t0), dtype=bool)
        if self.init_frames is not None:
            k = np.asarray(self.init_frames)
            if k.shape != (b,) or not np.issubdtype(k.dtype, np.integer) or \
                    (k < 1).any() or (k > t0).any():
                raise ValueError(f"init_frames must be (B,) = ({b},) integers in 1..{t0}")
            kept = np.arange(t0) < k[:, None]
        if not np.isfinite(self.init_pos_m[kept]).all():
            raise ValueError("init_pos_m holds NaN or infinite positions")
        for name in ("ident", "surface", "tournament", "serve", "score"):
            if len(getattr(self, name)) != b:
                raise ValueError(f"{name} has {len(getattr(self, name))} rows, expected {b}")

    def __len__(self) -> int:
        return len(self.init_pos_m)


@dataclass
class Rollout:
    """Simulated tracks: rally i is pos_m[i, :length[i]] (NaN after)."""

    pos_m: np.ndarray        # (B, T, 3, 3) float32
    length: np.ndarray       # (B,) frames, initial frames included
    ended: np.ndarray        # (B,) bool: the tracker ended it (False: stopped at max_frames)
    n_steps: int             # decoder steps taken (the longest rally's sampled frames)
    frames_simulated: int    # sampled frames summed over rallies
    resampled: np.ndarray | None = None  # (B,) frames drawn again (a constraint rejected them)
    forced_strikes: np.ndarray | None = None  # (B,) strikes asked for where a constraint gave up


def _wait_step(tracker, alive: np.ndarray, pos: torch.Tensor, vel: torch.Tensor,
               wait: torch.Tensor) -> torch.Tensor:
    """The live rows' receivers' waits for the serve after the frame `pos`, `vel`
    (`model.receiver_start`): a frame more where he waits and, where the tracker counts shots,
    the return is not yet struck (`n_shots` at most 1, the serve)."""
    shots = getattr(tracker, "n_shots", None)
    if shots is None:
        return wait_frames(wait, receiver_waiting(pos, vel))
    pending = np.asarray(shots)[alive] <= 1
    if not pending.any():        # most frames: every return struck, nobody waits
        return torch.zeros_like(wait)
    return wait_frames(wait, receiver_waiting(pos, vel) &
                       torch.as_tensor(pending, device=pos.device))


class _NoTracker:
    """Never ends a rally: rollouts then run to max_frames (benchmarks, tests)."""

    def update(self, pos_m: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        return np.zeros(len(pos_m), dtype=bool)


def _check_forced(forced_pos_m: np.ndarray, b: int, dev: torch.device) -> torch.Tensor:
    """`rollout`'s `forced_pos_m` checked -> a float32 tensor, each object's three coordinates
    all NaN (free) or all finite (forced)."""
    f = np.asarray(forced_pos_m, dtype=np.float32)
    if f.ndim != 4 or f.shape[0] != b or f.shape[2:] != (3, 3):
        raise ValueError(f"forced_pos_m must be ({b}, T, 3, 3), got {f.shape}")
    free = np.isnan(f)
    if (free.any(axis=3) != free.all(axis=3)).any():
        raise ValueError("forced_pos_m: an object's x, y and z must be all NaN or all finite")
    if not np.isfinite(f[~free]).all():
        raise ValueError("forced_pos_m holds infinite positions")
    if (~free[:, :, BALL]).any():
        raise ValueError("forced_pos_m forces players only: the ball's column must be NaN")
    return torch.as_tensor(f, device=dev)


def pad_tracks(tracks: list[np.ndarray]) -> np.ndarray:
    """(T_i, 3, 3) tracks -> (n, max T_i, 3, 3) float32, NaN after each one's end: the
    initial frames of rallies branched at different frames (with `RolloutInputs.init_frames`
    their lengths) or forced tracks of different lengths."""
    out = np.full((len(tracks), max([1, *(len(t) for t in tracks)]), 3, 3), np.nan,
                  dtype=np.float32)
    for i, t in enumerate(tracks):
        out[i, :len(t)] = t
    return out


def step_features(hist: torch.Tensor, n: int, fps: float) -> torch.Tensor:
    """Object tokens of frame n-1 given positions hist[:, :n] -> (B, 3, F)."""
    pos = hist[:, n - 1]
    vel = (pos - hist[:, n - 2]) * fps if n >= 2 else torch.zeros_like(pos)
    t = torch.full((len(pos),), (n - 1) / fps, dtype=pos.dtype, device=pos.device)
    return object_features(pos[:, None], vel[:, None], t[:, None])[:, 0]


def window_features(hist: torch.Tensor, lo: int, n: int, fps: float) -> torch.Tensor:
    """Tokens of frames lo..n-1 of positions hist (B, T, 3, 3) -> (B, n - lo, 3, F), velocities
    from the frame before lo (0 at the rally's first frame), times from the rally's start: the
    tokens a training window starting at lo holds."""
    pos = hist[:, lo:n]
    first_prev = max(lo - 1, 0)  # the rally's first frame has no predecessor: velocity 0
    prev = torch.cat([hist[:, first_prev:first_prev + 1], hist[:, lo:n - 1]], dim=1)
    t = (torch.arange(lo, n, dtype=pos.dtype, device=pos.device) / fps).expand(len(pos), -1)
    return object_features(pos, (pos - prev) * fps, t)


@torch.inference_mode()
def rollout(model: SportsNGEN, inputs: RolloutInputs, max_frames: int,
            tracker: Tracker | None = None, top_p_player: float = 1.0,
            top_p_ball: float = 1.0, seed: int | None = 0,
            generator: torch.Generator | None = None, mode: str = "cache",
            progress: bool = False, constraint: Constraint | None = None,
            contact_odds: bool = False, top_p_contact: float | None = None,
            refresh_frames: int | None = None, top_p_serve: float = 1.0,
            bounce_surfaces: np.ndarray | None = None,
            player_limits: PlayerLimits | None = None,
            player_top_speed_mps: np.ndarray | None = None,
            forced_pos_m: np.ndarray | None = None,
            player_quantiles: torch.Tensor | None = None) -> Rollout:
    """Roll `inputs` forward until the tracker ends each rally or it has `max_frames` frames.

    The tracker sees every frame of every rally in order, the initial ones included, and
    keeps each finished rally's result (read it after the rollout). `constraint` restricts the
    sampled frames (counterfactuals): rows whose sample it rejects are sampled again from the
    same distribution, which samples the distribution restricted to the accepted set.
    `generator` (or `seed`) makes the rollout reproducible: the same inputs, seed and batch
    give the same tracks. `contact_odds`: the ball's nucleus keeps the model's odds of a racket
    contact (`SportsNGEN.sample_next`), with `top_p_contact` the nucleus of a struck ball
    (default `top_p_ball`). `refresh_frames` (cache mode): once a rally is longer than the
    model's window, every this many frames the cache is filled again from the last window
    alone, so the next tokens read the rally as training windows do; without it the band's
    lower layers reach back over the whole rally (`sportsngen.eval.long_rallies`). 1 is the
    "window" mode's view at the cost of a window's pass a frame. `top_p_serve`: the serve head's
    nucleus, with one (`SportsNGEN.place_strikes`). `bounce_surfaces` (B,) surface names: the
    ball's bounces are the surface's physics, not the model's draw (`sim.bounce`).
    `player_limits` (`sim.kinematics.PlayerLimits`): every sampled frame changes a player's
    velocity by at most its acceleration, a change near it is set to it and a flat-out one near
    a running player's heading is turned onto it; `player_top_speed_mps` (B, 2): the server's
    and the receiver's top speed, which no frame of theirs exceeds (`sim.top_speed`).
    `forced_pos_m` (B, T, 3, 3), NaN where free: a player's finite position at frame n (counted
    as `init_pos_m`'s) replaces his sampled one, after every rule, so the others react to a
    track chosen by hand (an intervention: does the receiver read the server?). Players only:
    the ball's flight stays the model's and the physics'. `player_quantiles`: where inside
    their bins the players' draws land (`SportsNGEN.sample_next`). Cached rollouts of up to
    `SINGLE_THREAD_ROWS` rallies run on one CPU thread.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if bounce_surfaces is not None and model.strike_head is None and model.serve_head is None:
        raise ValueError("bounce_surfaces plans the frame after a bounce as a strike's "
                         "launch frames are: it needs a model with a strike or serve head")
    if max_frames < inputs.init_pos_m.shape[1]:
        raise ValueError(f"max_frames ({max_frames}) is shorter than the initial frames "
                         f"({inputs.init_pos_m.shape[1]})")
    small = (mode == "cache" and len(inputs.init_pos_m) <= SINGLE_THREAD_ROWS
             and next(model.parameters()).device.type == "cpu")
    with cpu_threads(1 if small else None):
        model.eval()
        dev = next(model.parameters()).device
        b = len(inputs.init_pos_m)
        if generator is None:
            generator = torch.Generator(device=dev)
            generator.manual_seed(0 if seed is None else int(seed))
        top_all = None
        if player_top_speed_mps is not None:
            top_all = _tensor(player_top_speed_mps, torch.float32, dev)
            if top_all.shape != (b, 2):
                raise ValueError(f"player_top_speed_mps must be ({b}, 2), got "
                                 f"{tuple(top_all.shape)}")
        forced_all = None if forced_pos_m is None else _check_forced(forced_pos_m, b, dev)
        draws = FrameDraws(model, tracker or _NoTracker(), generator, top_p_player, top_p_ball,
                       contact_odds, top_p_contact, top_p_serve, constraint, bounce_surfaces,
                       player_limits, player_quantiles, resampled=np.zeros(b, dtype=np.int64),
                       forced_strikes=np.zeros(b, dtype=np.int64))
        decoder = _CachedDecoder(model, refresh_frames) if mode == "cache" else \
            _ForwardDecoder(model, model.cfg.window_frames if mode == "window" else None)
        return _roll(draws, decoder, inputs, max_frames, top_all, forced_all, progress)


def _tensor(x, dtype: torch.dtype, dev: torch.device) -> torch.Tensor:
    return torch.as_tensor(np.array(x), dtype=dtype, device=dev)


@dataclass
class _Live:
    """The live rallies of a rollout: their rows as first given (`alive`) and their tensors,
    compacted as rallies end."""

    alive: np.ndarray
    hist: torch.Tensor            # (L, max_frames, 3, 3) positions so far, NaN after
    ident: torch.Tensor
    ctx: torch.Tensor             # context tokens
    serve: torch.Tensor
    surface: torch.Tensor
    plan: torch.Tensor            # (L, 2, 3) a struck ball's next frames, NaN where none
    wait: torch.Tensor | None     # the receivers' waits for the serve (`model.receiver_start`)

    def keep(self, keep: np.ndarray) -> torch.Tensor:
        """Keep the batch rows `keep` -> them as a tensor (to compact a cache alike)."""
        self.alive = self.alive[keep]
        kt = torch.as_tensor(keep, device=self.hist.device)
        self.hist, self.ident, self.ctx, self.plan = (self.hist[kt], self.ident[kt],
                                                      self.ctx[kt], self.plan[kt])
        self.serve, self.surface = self.serve[kt], self.surface[kt]
        self.wait = None if self.wait is None else self.wait[kt]
        return kt


class _CachedDecoder:
    """Mode "cache": the ring key/value cache filled from the initial frames, then one token
    step a frame; with `refresh_frames`, filled again from the last window alone every that many
    frames once a rally outgrows the window."""

    def __init__(self, model: SportsNGEN, refresh_frames: int | None):
        self.model, self.refresh_frames = model, refresh_frames
        self.cache, self.h = None, None

    def start(self, live: _Live, t0: int) -> None:
        hs, self.cache = self.model(window_features(live.hist, 0, t0, self.model.cfg.fps),
                                    live.ident, live.ctx, return_cache=True)
        self.h = hs[:, -1]

    def keep(self, kt: torch.Tensor) -> None:
        self.cache, self.h = self.cache.select(kt), self.h[kt]

    def hidden(self, live: _Live, n: int, first: bool) -> torch.Tensor:
        """The decoder's output at frame n-1 (the first step's is the filling's)."""
        fps, window = self.model.cfg.fps, self.model.cfg.window_frames
        if first:
            return self.h
        if self.refresh_frames and n > window and n % self.refresh_frames == 0:
            hs, self.cache = self.model(window_features(live.hist, n - window, n, fps),
                                        live.ident, live.ctx, return_cache=True)
            self.h = hs[:, -1]
        else:
            self.h = self.model.forward_step(step_features(live.hist, n, fps), self.cache)[0]
        return self.h


class _ForwardDecoder:
    """Modes "recompute" (`window` None: the whole rally so far) and "window" (its last
    `window` frames): `forward` run again at every step, nothing kept between steps."""

    def __init__(self, model: SportsNGEN, window: int | None):
        self.model, self.window = model, window

    def start(self, live: _Live, t0: int) -> None:
        pass

    def keep(self, kt: torch.Tensor) -> None:
        pass

    def hidden(self, live: _Live, n: int, first: bool) -> torch.Tensor:
        lo = 0 if self.window is None else max(0, n - self.window)
        return self.model(window_features(live.hist, lo, n, self.model.cfg.fps), live.ident,
                          live.ctx)[:, -1]


def _start(model: SportsNGEN, inputs: RolloutInputs, max_frames: int, t0: int,
           tracker: Tracker) -> tuple[_Live, np.ndarray]:
    """The batch's tensors and its first `t0` frames fed to the tracker -> (live rallies,
    (B,) bool: ended within them)."""
    dev = next(model.parameters()).device
    b, fps = len(inputs.init_pos_m), model.cfg.fps
    ctx = model.context_tokens(_tensor(inputs.surface, torch.long, dev),
                               _tensor(inputs.tournament, torch.long, dev),
                               _tensor(inputs.serve, torch.long, dev),
                               _tensor(inputs.score, torch.float32, dev))
    hist = torch.full((b, max_frames, 3, 3), float("nan"), device=dev)
    hist[:, :t0] = _tensor(inputs.init_pos_m[:, :t0], torch.float32, dev)
    # The receivers' waits for the serve (`model.receiver_start`), counted over the initial
    # frames but the last, which the loop's first step counts.
    wait = None if model.receiver_start is None else torch.zeros(b, dtype=torch.long, device=dev)
    done = np.zeros(b, dtype=bool)
    for k in range(t0):
        done = tracker.update(inputs.init_pos_m[:, k], ~done)
        if wait is not None and k < t0 - 1:
            prev_k = hist[:, k - 1] if k else hist[:, 0]
            wait = _wait_step(tracker, np.arange(b), hist[:, k], (hist[:, k] - prev_k) * fps,
                              wait)
    live = _Live(np.arange(b), hist, _tensor(inputs.ident, torch.long, dev), ctx,
                 _tensor(inputs.serve, torch.long, dev), _tensor(inputs.surface, torch.long, dev),
                 torch.full((b, 2, 3), float("nan"), device=dev), wait)
    return live, done


def _next_frame(draws: FrameDraws, live: _Live, h: torch.Tensor, n: int, inputs: RolloutInputs,
                starts: np.ndarray | None, top_all: torch.Tensor | None) -> torch.Tensor:
    """Frame n of the live rallies: drawn (`FrameDraws.draw`), or the recorded one for rows still
    inside their own initial frames (`RolloutInputs.init_frames`; their strike plans stay
    empty)."""
    model, hist, alive, fps = draws.model, live.hist, live.alive, draws.model.cfg.fps
    dev = hist.device
    pos = hist[:, n - 1]
    prev = hist[:, n - 2] if n >= 2 else pos
    vel = (pos - prev) * fps
    prev_vel = (prev - hist[:, n - 3]) * fps if n >= 3 else torch.zeros_like(vel)
    p_bias = None
    if live.wait is not None:
        live.wait = _wait_step(draws.tracker, alive, pos, vel, live.wait)
        # No receiver waiting: every shift is 0, which the heads may as well not add.
        if bool(live.wait.any()):
            p_bias = model.receiver_start_bias(live.ident[:, 0], live.serve, live.wait)
    top = None if top_all is None else top_all[torch.as_tensor(alive, device=dev)]
    drawing = None if starts is None else np.flatnonzero(starts[alive] <= n)
    if drawing is None or len(drawing) == len(alive):
        nxt, live.plan = draws.draw(alive, n, h, pos, vel, prev_vel, p_bias, top, live.plan,
                                    live.serve, live.ident, live.surface)
        return nxt
    nxt = _tensor(inputs.init_pos_m[alive, n], torch.float32, dev)
    if len(drawing):
        d = torch.as_tensor(drawing, device=dev)
        nxt[d], live.plan[d] = draws.draw(alive[drawing], n, h[d], pos[d], vel[d], prev_vel[d],
                                          None if p_bias is None else p_bias[d],
                                          None if top is None else top[d], live.plan[d],
                                          live.serve[d], live.ident[d], live.surface[d])
    return nxt


def _roll(draws: FrameDraws, decoder: _CachedDecoder | _ForwardDecoder, inputs: RolloutInputs,
          max_frames: int, top_all: torch.Tensor | None, forced_all: torch.Tensor | None,
          progress: bool) -> Rollout:
    """`rollout`'s loop: a frame of every live rally a step, finished rallies dropped."""
    b = len(inputs.init_pos_m)
    # Rows with initial frames of their own count start together at the fewest; the others
    # take their recorded frames until theirs run out (`RolloutInputs.init_frames`).
    starts = None if inputs.init_frames is None else np.asarray(inputs.init_frames)
    t0 = inputs.init_pos_m.shape[1] if starts is None else int(starts.min())
    live, done = _start(draws.model, inputs, max_frames, t0, draws.tracker)
    decoder.start(live, t0)
    out = np.full((b, max_frames, 3, 3), np.nan, dtype=np.float32)
    out[:, :t0] = inputs.init_pos_m[:, :t0]
    length = np.full(b, t0, dtype=np.int64)
    ended = np.zeros(b, dtype=bool)
    latest = inputs.init_pos_m[:, t0 - 1].astype(np.float32)   # every rally's newest frame
    n, steps, frames = t0, 0, 0
    bar = tqdm(total=max_frames - t0, desc="frames", disable=not progress, leave=False)
    while True:
        if done.any():
            ended[live.alive[done]] = True
            keep = np.flatnonzero(~done)
            if len(keep) == 0:
                break
            decoder.keep(live.keep(keep))
        if n >= max_frames:
            break
        h = decoder.hidden(live, n, first=steps == 0)
        nxt = _next_frame(draws, live, h, n, inputs, starts, top_all)
        alive = live.alive
        if forced_all is not None and n < forced_all.shape[1]:
            f = forced_all[torch.as_tensor(alive, device=nxt.device), n]
            nxt = torch.where(torch.isnan(f), nxt, f)
        live.hist[:, n] = nxt
        nxt_np = nxt.cpu().numpy()
        out[alive, n] = nxt_np
        length[alive] = n + 1
        latest[alive] = nxt_np
        active = np.zeros(b, dtype=bool)
        active[alive] = True
        done = draws.tracker.update(latest, active)[alive]
        n += 1
        steps += 1
        frames += len(alive)
        bar.update(1)
    bar.close()
    return Rollout(out[:, :int(length.max())], length, ended, steps, frames, draws.resampled,
                   draws.forced_strikes)
