"""The generator as expert on the model's own rollout states (one round of DAgger).

Teacher forcing shows the decoder recorded states only. In its rollouts a ball it launched
itself flies a few centimetres off every recorded flight and its receiver stands a few tenths
of a metre off, and there a model that never saw such states often lets the ball pass. The
generator's shot-cycle kernel can play a rally on from any state (`synth.cycle.continue_rally`),
so it can answer those states the way the data's players would:

1. branch points: a recorded rally of the training split, `after_contact_frames` after one of
   its racket contacts (the model then owns the flight it is launching and both players);
2. the model rolls each branch out at its own sampling (`Simulator`, its stored defaults) for
   `min_model_frames`-`max_model_frames` frames, never past the recorded next contact;
3. at that hand-over frame the rollout's state becomes a `RallyState`: the ball's position, and
   its velocity and spin from a quadratic through its last frames (`ball_state`); both players'
   positions and velocities; the recorded hitter, the time since his contact and the bounces
   since then. Branches whose rollout already made a contact, let the ball bounce twice or
   ended the rally are left out: there is no flight left to answer;
4. the kernel plays the rally on from there with the recorded players' generator profiles;
5. the training rally is the record up to the branch, the model's frames up to the hand-over
   and the expert's frames after it (`keep_frames` of them), with `learn_from` at the
   hand-over: only the expert's frames are targets, the model's own are inputs.

`expert_arrays` returns those rallies as `RallyArrays`; `save_expert` / `load_expert` keep them
in one .npz file that `train.py expert.path=...` mixes into the training windows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from sportsngen.data.tokens import CONTACT_TOL_FRAMES, RallyArrays, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.model.centre import physics_step_m
from sportsngen.model.inputs import BALL
from sportsngen.synth import physics
from sportsngen.synth.cycle import RallyState
from sportsngen.synth.profiles import PlayerProfile
from sportsngen.synth.rally import continue_rally

# The kernel strikes no earlier than 0.05 s after a hand-over (`find_intercept`'s first
# search time), so a late ball handed to it flies on one more frame before its strike; taught
# as a target, that frame said "not yet" on exactly the late states (docs/evaluation.md).
KERNEL_LEAD_FRAMES = 1
REVERSAL_MPS = 3.0      # an x-velocity this large the other way: someone struck the ball
BOUNCE_Z_M = 0.25       # a fall turning into a rise below this height is a bounce
KINK_M = 0.1            # a second difference of the height this large holds a bounce
MAX_SPIN_MPS = 20.0     # the generator's shots spin at most ~12 m/s


@dataclass(frozen=True)
class ExpertConfig:
    """How many branches, where they start and how long the model rolls before the expert."""

    n_branches: int = 3000
    after_contact_frames: int = 1   # the model takes over this many frames after a contact
    min_model_frames: int = 6       # frames the model rolls before the hand-over
    max_model_frames: int = 30
    keep_frames: int = 75           # expert frames kept after the hand-over (3 s at 25 Hz)
    fit_frames: int = 6             # frames of the quadratic that gives the ball's state
    seed: int = 0

    def __post_init__(self) -> None:
        if self.n_branches < 1:
            raise ValueError(f"n_branches must be at least 1, got {self.n_branches}")
        if not 1 <= self.min_model_frames <= self.max_model_frames:
            raise ValueError("need 1 <= min_model_frames <= max_model_frames, got "
                             f"{self.min_model_frames}, {self.max_model_frames}")
        if self.after_contact_frames < 0 or self.keep_frames < 2 or self.fit_frames < 3:
            raise ValueError("need after_contact_frames >= 0, keep_frames >= 2, fit_frames >= 3")


# -- the rollout's state ------------------------------------------------------------------------

def bounce_frames(z_m: np.ndarray) -> np.ndarray:
    """Frames of a ball height track where a fall turns into a rise near the ground."""
    dz = np.diff(z_m)
    turn = (dz[:-1] < 0) & (dz[1:] > 0) & (z_m[1:-1] < BOUNCE_Z_M)
    return np.flatnonzero(turn) + 1


def spin_from_lift(vel_mps: np.ndarray, acc_mps2: np.ndarray,
                   aero: physics.Aero = physics.DEFAULT_AERO) -> float:
    """The generator's v_spin (m/s, > 0 topspin) whose Magnus lift explains `acc_mps2` beyond
    gravity and drag at `vel_mps`: its lift is k v^2 (-s) / (2|s| + v) across the velocity in
    the vertical plane (`physics._accel`), solved for s; 0 for a ball too slow to read."""
    v = float(np.linalg.norm(vel_mps))
    vh = float(np.hypot(vel_mps[0], vel_mps[1]))
    if v < 3.0 or vh < 1e-6:
        return 0.0
    k = aero.k_per_m
    rest = acc_mps2 + k * aero.drag_coefficient * v * vel_mps
    rest[2] += aero.gravity_mps2
    # Unit vector across the velocity, in the vertical plane, pointing "up" for topspin's sign.
    across = np.array([-vel_mps[2] * vel_mps[0] / vh, -vel_mps[2] * vel_mps[1] / vh, vh]) / v
    lift = float(rest @ across) / (k * aero.lift_scale * v * v)
    lift = min(max(lift, -0.3), 0.3)
    return -lift * v / (1.0 + 2.0 * lift) if lift < 0 else -lift * v / (1.0 - 2.0 * lift)


def ball_state(track_m: np.ndarray, fps: float, fit_frames: int = 6
               ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The ball's last frame of `track_m` (n, 3), in free flight since its last bounce ->
    (position, velocity, spin). A least-squares quadratic through the last `fit_frames` frames
    (fewer after a bounce, at least three) gives the velocity at the last frame, and its
    acceleration with the velocity at the fit's middle frame the spin: a model's flight
    carries a bin's noise each frame, which a second difference of three frames would read as
    Magnus. None with fewer than three frames since a bounce (the flight is not readable yet)."""
    track_m = np.asarray(track_m, dtype=float)
    n = min(len(track_m), fit_frames)
    # A bounce between two frames kinks the height by far more than gravity does in a frame.
    kink = np.flatnonzero(np.abs(np.diff(track_m[-n:, 2], 2)) > KINK_M)
    if len(kink):
        n -= int(kink[-1]) + 1
    if n < 3:
        return None
    pos = track_m[-1].copy()
    t = (np.arange(n) - (n - 1)) / fps
    coef = np.polyfit(t, track_m[-n:], 2)           # (3 powers, 3 axes)
    acc = 2.0 * coef[0]
    mid_vel = coef[1] + acc * t[(n - 1) // 2]
    spin = spin_from_lift(mid_vel, acc)
    return pos, coef[1], float(np.clip(spin, -MAX_SPIN_MPS, MAX_SPIN_MPS))


def rally_state(pos_m: np.ndarray, frame: int, contact_frame: int, hitter: int, n_shots: int,
                fps: float, fit_frames: int = 6) -> RallyState | None:
    """A `RallyState` at `frame` of one rally's (T, 3 objects, 3) track whose ball was struck
    by role `hitter` at `contact_frame`, or None where it cannot be answered: a reversal of the
    ball (another contact), two bounces, or a ball on the ground."""
    ball = pos_m[contact_frame:frame + 1, BALL]
    vx = np.diff(ball[:, 0]) * fps
    if len(vx) < 3:
        return None
    way = math.copysign(1.0, vx[1])
    if (vx * way < -REVERSAL_MPS).any():
        return None
    bounces = len(bounce_frames(ball[:, 2]))
    if bounces > 1 or ball[-1, 2] < physics.BALL_RADIUS_M:
        return None
    # The flight is read from the frames after the contact's: the rules put a contact on the
    # nearer frame of its step, which may be the last before the racket, and a fit through it
    # read a rally ball handed over five frames after its contact up to 3.4 m off at its bounce
    # (p90; 9 % of them called in or out wrongly), 0.10 m without it (docs/evaluation.md).
    read = ball_state(ball[1:], fps, fit_frames)
    if read is None:
        return None
    pos, vel, spin = read
    players = pos_m[frame, :BALL, :2]
    players_vel = (pos_m[frame, :BALL, :2] - pos_m[frame - 1, :BALL, :2]) * fps
    return RallyState(ball_m=tuple(pos), ball_vel_mps=tuple(vel),
                      players_m=tuple(map(tuple, players)), last_hitter=int(hitter),
                      players_vel_mps=tuple(map(tuple, players_vel)), ball_spin_mps=spin,
                      t_contact_s=(contact_frame - frame) / fps, bounces=bounces,
                      n_shots=int(n_shots))


# -- branch points --------------------------------------------------------------------------------

def recorded_contacts(data: RallyData, arrays: RallyArrays, rally_pos: np.ndarray
                      ) -> pd.DataFrame:
    """The shots of the rallies at positions `rally_pos` of `arrays`, in order, with the
    rally's position `ri`, the contact's frame `contact` (from the rally's first frame) and
    the hitter's `role` (0 server, 1 receiver)."""
    first = data.frames.groupby("rally_id")["frame"].min()
    server = data.rallies.set_index("rally_id")["server"]
    pos_of = pd.Series(np.arange(len(arrays)), index=arrays.rally_id)
    shots = data.shots
    s = shots[shots["rally_id"].isin(arrays.rally_id[rally_pos])]
    s = s.sort_values(["rally_id", "shot_index"]).copy()
    s["ri"] = pos_of.reindex(s["rally_id"]).to_numpy()
    s["contact"] = (s["frame"] - first.reindex(s["rally_id"]).to_numpy()).astype(np.int64)
    s["role"] = np.where(s["hitter"].to_numpy() == server.reindex(s["rally_id"]).to_numpy(),
                         0, 1)
    return s

def branch_points(data: RallyData, arrays: RallyArrays, rally_pos: np.ndarray,
                  cfg: ExpertConfig) -> pd.DataFrame:
    """Up to `cfg.n_branches` random branch points among the rallies at positions `rally_pos`
    of `arrays` (the training split) -> one row each: the rally's position `ri`, the contact
    frame `contact` (from its first frame), the branch frame `start`, the latest hand-over
    `last` (two frames before the next recorded contact or the rally's end), the hitter's role
    and `n_shots` (contacts so far)."""
    s = recorded_contacts(data, arrays, rally_pos)
    nxt = s.groupby("rally_id")["contact"].shift(-1)
    s["last"] = np.where(nxt.notna(), nxt.fillna(0), arrays.length[s["ri"]]).astype(np.int64) - 2
    s["start"] = s["contact"] + 1 + cfg.after_contact_frames
    s = s[s["last"] - s["start"] >= cfg.min_model_frames]
    s = s.assign(n_shots=s["shot_index"] + 1)
    rng = np.random.default_rng(cfg.seed)
    pick = rng.choice(len(s), size=min(cfg.n_branches, len(s)), replace=False)
    cols = ["rally_id", "ri", "contact", "start", "last", "role", "n_shots"]
    out = s.iloc[np.sort(pick)][cols].rename(columns={"role": "hitter"})
    return out.reset_index(drop=True)


def _play_on(profiles: dict[str, PlayerProfile], rally: pd.Series, state: RallyState,
             rng: np.random.Generator, fps: float, render: bool = True):
    """The kernel playing on from `state` with the recorded rally's players and setting."""
    return continue_rally(profiles[rally["server"]], profiles[rally["receiver"]], state,
                          int(rally["server_end"]), str(rally["side"]),
                          int(rally["serve_number"]), str(rally["surface"]), rng, fps=fps,
                          render=render)


# -- the expert rallies ---------------------------------------------------------------------------

def _rollouts(sim, data: RallyData, arrays: RallyArrays, branches: pd.DataFrame,
              cfg: ExpertConfig, progress: bool = False) -> dict[int, np.ndarray]:
    """Branch row -> the model's rollout (T, 3, 3) from its branch frame, all branch frames in
    one set of batches (each rally keeps its own frames: `RolloutInputs.init_frames`)."""
    from sportsngen.sim.assemble import PLAN_COLUMNS
    from sportsngen.sim.rollout import pad_tracks

    if branches.empty:
        return {}
    rallies = data.rallies.set_index("rally_id")
    rows = branches.sort_values("start", kind="stable")
    plan = rallies.loc[rows["rally_id"].to_numpy()].reset_index()[PLAN_COLUMNS].copy()
    plan["rally_id"] = np.arange(len(plan))
    plan["match_id"] = "expert"
    starts = rows["start"].to_numpy(np.int64)
    init = pad_tracks([arrays.pos_m[arrays.start[i]:arrays.start[i] + k]
                       for i, k in zip(rows["ri"], starts)])
    rolled = sim.simulate_rallies(plan, seed=cfg.seed * 10_007, progress=progress,
                                  init_pos_m=init, init_frames=starts,
                                  max_duration_s=(starts + cfg.max_model_frames + 1) / sim.fps)
    arr = rally_arrays(rolled, sim.vocab, unknown="generic")
    by_id = dict(zip(arr.rally_id.tolist(), range(len(arr))))
    out: dict[int, np.ndarray] = {}
    for j, idx in enumerate(rows.index):
        k = by_id.get(j)
        if k is not None:
            out[int(idx)] = arr.pos_m[arr.start[k]:arr.start[k] + arr.length[k]]
    return out


def expert_arrays(sim, data: RallyData, arrays: RallyArrays, rally_pos: np.ndarray,
                  profiles: dict[str, PlayerProfile], cfg: ExpertConfig = ExpertConfig(),
                  progress: bool = False) -> tuple[RallyArrays, dict]:
    """The expert's rallies on `sim`'s own rollouts of the rallies at `rally_pos` (module doc)
    -> (arrays with `learn_from` at each hand-over, counts of what was kept and why not).
    `profiles` maps every player name of those rallies to his generator profile."""
    branches = branch_points(data, arrays, rally_pos, cfg)
    rolled = _rollouts(sim, data, arrays, branches, cfg, progress)
    rallies = data.rallies.set_index("rally_id")
    rng = np.random.default_rng(cfg.seed + 1)
    fps = float(arrays.fps)
    counts = {"branches": len(branches), "ended": 0, "no_flight": 0, "kernel_refused": 0,
              "kept": 0}
    kept: list[tuple] = []
    rows = branches.itertuples()
    if progress:
        from tqdm import tqdm
        rows = tqdm(list(rows), desc="expert", unit="branch")
    for b in rows:
        roll = rolled.get(int(b.Index))
        hi = min(int(b.last), int(b.start) + cfg.max_model_frames)
        if roll is None or len(roll) <= int(b.start) + cfg.min_model_frames:
            counts["ended"] += 1
            continue
        hi = min(hi, len(roll) - 1)
        if hi < int(b.start) + cfg.min_model_frames:
            counts["ended"] += 1
            continue
        h = int(rng.integers(int(b.start) + cfg.min_model_frames, hi + 1))
        state = rally_state(roll, h, int(b.contact), int(b.hitter), int(b.n_shots), fps,
                            cfg.fit_frames)
        if state is None:
            counts["no_flight"] += 1
            continue
        r = rallies.loc[int(b.rally_id)]
        try:
            res = _play_on(profiles, r, state, rng, fps)
        except ValueError as exc:   # a state the kernel cannot play on: counted, not fatal
            counts["kernel_refused"] += 1
            counts.setdefault("first_refusal", str(exc))
            continue
        ri = int(b.ri)
        kept.append((*_answered(roll[:h + 1], res, cfg.keep_frames, fps,
                                arrays.near_contact[arrays.start[ri]:arrays.start[ri] + b.start]),
                     h, ri))
        counts["kept"] += 1
    return _expert_rallies(arrays, kept, counts), counts


def _answered(head: np.ndarray, res, keep_frames: int, fps: float,
              near_head: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A training rally: the frames `head` up to the hand-over (its last frame), then the
    kernel's answer `res` (at most `keep_frames` frames) -> (track, near-contact flags: the
    record's `near_head` before, the kernel's contacts after)."""
    n_exp = min(res.n_frames, keep_frames + 1)
    exp = np.zeros((n_exp - 1, 3, 3), dtype=np.float32)
    exp[:, BALL] = res.ball_m[1:n_exp]
    exp[:, :BALL, :2] = np.transpose(res.players_m[:, 1:n_exp], (1, 0, 2))
    track = np.concatenate([head, exp]).astype(np.float32)
    flags = np.zeros(len(track), dtype=bool)
    flags[:len(near_head)] = near_head[:len(track)]
    h = len(head) - 1
    for shot in res.shots[1:]:
        f = h + int(round(shot.t_s * fps))
        flags[max(f - CONTACT_TOL_FRAMES, 0):f + CONTACT_TOL_FRAMES + 1] = True
    return track, flags


def _expert_rallies(arrays: RallyArrays, kept: list[tuple], counts: dict) -> RallyArrays:
    """The expert's (track, near-contact flags, hand-over frame, source rally position) as
    `RallyArrays` with the context of the rallies they came from."""
    if not kept:
        raise ValueError(f"no expert rally could be made ({counts})")
    parts, near, learn, src = (list(x) for x in zip(*kept))
    fps = float(arrays.fps)
    src_idx = np.asarray(src, dtype=np.int64)
    length = np.array([len(p) for p in parts], dtype=np.int64)
    base = arrays.select(src_idx)
    out = RallyArrays(
        pos_m=np.concatenate(parts), labels=np.zeros((int(length.sum()), base.labels.shape[1]),
                                                     dtype=np.int64),
        near_contact=np.concatenate(near),
        start=np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.int64), length=length,
        rally_id=-1 - np.arange(len(parts), dtype=np.int64), ident=base.ident,
        surface=base.surface, tournament=base.tournament, serve=base.serve, score=base.score,
        fps=fps, meta={"expert": counts}, learn_from=np.asarray(learn, dtype=np.int64))
    return out


def late_contact_arrays(data: RallyData, arrays: RallyArrays, rally_pos: np.ndarray,
                        profiles: dict[str, PlayerProfile], delays: tuple[int, ...] = (1, 2),
                        n_branches: int = 3000, keep_frames: int = 75, seed: int = 0,
                        progress: bool = False) -> tuple[RallyArrays, dict]:
    """The kernel's answer to a contact made late. The generator strikes every ball on the
    frame it planned, so the data never shows a ball its player has not struck on time still
    being struck, and a model that misses that frame in a rollout reads the ball as gone (the
    bundled file's P(contact) on a return: 0.73 on time, 0.66 a frame late, 0.50 three frames
    late; docs/evaluation.md). For recorded shots after the serve (rallies at `rally_pos`): the
    record up to the frame before the contact's frame c (the frame nearest the contact), the
    ball flown on unstruck by the physics step for d frames, d drawn from `delays` (the
    players' recorded frames kept), then the kernel plays on from that state. The contact
    lies within half a frame of c, so d = 1 is up to half a frame late (no later than the
    record half the time) and d = 2 half a frame to a frame and a half. Only the kernel's
    frames after its first are targets (`learn_from`, `KERNEL_LEAD_FRAMES`).
    -> (arrays, counts: branches, kept, no_flight, kernel_refused, struck (the kernel struck
    the late ball))."""
    rallies = data.rallies.set_index("rally_id")
    s = recorded_contacts(data, arrays, rally_pos)
    s["prev"] = s.groupby("rally_id")["contact"].shift(1)
    s["prev_role"] = s.groupby("rally_id")["role"].shift(1)
    s = s[s["prev"].notna() & (s["contact"] - s["prev"] > 8)]
    rng = np.random.default_rng(seed)
    s = s.iloc[np.sort(rng.choice(len(s), size=min(n_branches, len(s)), replace=False))]
    fps = float(arrays.fps)
    counts = {"branches": len(s), "no_flight": 0, "kernel_refused": 0, "kept": 0, "struck": 0}
    kept: list[tuple] = []
    rows = s.itertuples()
    if progress:
        from tqdm import tqdm
        rows = tqdm(list(rows), desc="late contacts", unit="branch")
    for b in rows:
        ri = int(b.ri)
        rec = arrays.pos_m[arrays.start[ri]:arrays.start[ri] + arrays.length[ri]]
        c, d = int(b.contact), int(rng.choice(delays))
        if c < 3 or c + d > len(rec):
            counts["no_flight"] += 1
            continue
        track = rec[:c + d].copy()
        for t in range(c, c + d):      # the ball flies on unstruck
            v = (track[t - 1, BALL] - track[t - 2, BALL]) * fps
            pv = (track[t - 2, BALL] - track[t - 3, BALL]) * fps
            track[t, BALL] = physics_step_m(torch.as_tensor(track[t - 1, BALL]),
                                            torch.as_tensor(v), torch.as_tensor(pv),
                                            fps).numpy()
        r = rallies.loc[int(b.rally_id)]
        h = c + d - 1
        state = rally_state(track, h, int(b.prev), int(b.prev_role), int(b.shot_index), fps)
        if state is None:
            counts["no_flight"] += 1
            continue
        try:
            res = _play_on(profiles, r, state, rng, fps)
        except ValueError:
            counts["kernel_refused"] += 1
            continue
        counts["struck"] += int(len(res.shots) > 1)
        kept.append((*_answered(track, res, keep_frames, fps,
                                arrays.near_contact[arrays.start[ri]:arrays.start[ri] + c - 1]),
                     h + KERNEL_LEAD_FRAMES, ri))
        counts["kept"] += 1
    return _expert_rallies(arrays, kept, counts), counts


def serve_return_fidelity(data: RallyData, arrays: RallyArrays, rally_pos: np.ndarray,
                          profiles: dict[str, PlayerProfile], frames_after: int,
                          n_branches: int = 1000, seed: int = 0) -> dict:
    """What the expert gets wrong before any model is involved: recorded serves that landed
    in play, handed to the kernel `frames_after` frames after their branch frame (the serve's
    contact + 2) with the record's own state. -> n, the share the record returned and the
    share the kernel returned from the same states (they should agree)."""
    cfg = ExpertConfig(n_branches=n_branches, seed=seed)
    br = branch_points(data, arrays, rally_pos, cfg)
    shots = data.shots
    returned = set(shots.loc[shots["shot_index"] == 1, "rally_id"])
    faults = set(shots.loc[(shots["shot_index"] == 0) & (shots["outcome"] == "error"),
                           "rally_id"])
    rallies = data.rallies.set_index("rally_id")
    rng = np.random.default_rng(seed + 1)
    rec, exp = [], []
    for b in br[br["n_shots"] == 1].itertuples():
        h = int(b.start) + int(frames_after)
        if int(b.rally_id) in faults or h > int(b.last):
            continue
        ri = int(b.ri)
        track = arrays.pos_m[arrays.start[ri]:arrays.start[ri] + arrays.length[ri]]
        state = rally_state(track, h, int(b.contact), 0, 1, float(arrays.fps), cfg.fit_frames)
        if state is None:
            continue
        r = rallies.loc[int(b.rally_id)]
        res = _play_on(profiles, r, state, rng, float(arrays.fps), render=False)
        rec.append(int(b.rally_id) in returned)
        exp.append(len(res.shots) > 1)
    n = len(rec)
    return {"frames_after": int(frames_after), "n": n,
            "recorded_returned": float(np.mean(rec)) if n else float("nan"),
            "expert_returned": float(np.mean(exp)) if n else float("nan")}


_FIELDS = ("pos_m", "labels", "near_contact", "start", "length", "rally_id", "ident", "surface",
           "tournament", "serve", "score", "learn_from")


def save_expert(arrays: RallyArrays, path: str | Path) -> Path:
    """Write expert rallies to one .npz file (identities as the model's vocabulary indices)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, fps=np.float64(arrays.fps),
                        **{k: getattr(arrays, k) for k in _FIELDS})
    return path


def load_expert(path: str | Path) -> RallyArrays:
    """Read expert rallies written by `save_expert`; clear errors for a missing or foreign
    file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"expert rallies {path} not found (make them with "
                                "scripts/expert_data.py)")
    with np.load(path) as z:
        missing = [k for k in (*_FIELDS, "fps") if k not in z]
        if missing:
            raise ValueError(f"{path} is not an expert-rally file: no {missing}")
        kw = {k: z[k] for k in _FIELDS}
        fps = float(z["fps"])
    return RallyArrays(fps=fps, **kw)
