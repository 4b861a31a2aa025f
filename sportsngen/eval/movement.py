"""How a hitter moves after his own shot: teacher-forced and rolled out, against the record.

After a rally ball the hitter runs back to where he waits for the next, each player to his own
depth (in the generator, `synth.behaviour.rally_depth_m`: Nadal about 2.2 m behind his baseline
on hard, Federer about 0.9 m). The run is a few tenths of a second of full acceleration and then
braking, and when the braking starts is all that sets the depth he reaches, so a model that
brakes a few frames early leaves its player a metre short, and he plays the next shots from
there. `recovery_curves` lays three views of that run side by side, frame by frame after the
contact of shot `shot` (1 the return):

- the record: how far behind his baseline the hitter stands, his speed away from the net, and
  the next frame's change of that speed;
- teacher-forced: the model's expected change of that speed at the record's own states (the
  mean over `draws` samples of its next frame), which shows a bias one frame at a time;
- rolled out: the same depth and speed in the model's branches of the same recorded points,
  rolled out from 3 frames after shot `shot - 1` (after the serve itself for shot 0, the
  server's run back from his serve), measured after the branch's own shot.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.diagnostics import serve_branches
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_branches import shot_branches, shot_outcomes
from sportsngen.tennis.court import BASELINE_X_M
from sportsngen.train.metrics import window_states
from sportsngen.train.windows import WindowDataset

RECOVERY_FRAMES = 45      # 1.8 s: the run back and the next ball's approach
CHASE_FRAMES = 35         # 1.4 s: a return's flight to the server, and a rally ball's
CHASE_MIN_M = 0.3         # a player who moves less than this to his strike has no direction
BIN_FRAMES = 5
BRANCH_HORIZON_S = 4.0    # the next shot's flight and the run after it


def _player_runs(data: RallyData, rules: pd.DataFrame, slot: int, min_contacts: int):
    """(rally_id, the (T, 2) track of player `slot` (0 the server, 1 the receiver), the
    rally's contact frames) for each rally with at least `min_contacts` contacts."""
    f = data.frames.merge(data.rallies[["rally_id", "server", "receiver"]], on="rally_id")
    who = "server" if slot == 0 else "receiver"
    f = f[f["object"] == f[who]].sort_values(["rally_id", "frame"])
    for rid, g in f.groupby("rally_id", sort=False):
        if rid not in rules.index:
            continue
        contacts = [int(c) for c in rules.loc[rid, "contact_frames"]]
        if len(contacts) >= min_contacts:
            yield rid, g[["x", "y"]].to_numpy(float), contacts


def _hitter_tracks(data: RallyData, rules: pd.DataFrame, shot: int, frames: int,
                   ids=None) -> pd.DataFrame:
    """Per rally that played shot `shot`: the hitter's distance behind his baseline and speed
    away from the net at each of the `frames` frames from the contact (long form)."""
    rows = []
    for rid, xy, contacts in _player_runs(data, rules, shot % 2, shot + 1):
        if ids is not None and rid not in ids:
            continue
        behind = np.abs(xy[:, 0]) - BASELINE_X_M
        c = contacts[shot]
        k = np.arange(min(frames, len(behind) - 1 - c))
        if len(k):
            rows.append(pd.DataFrame({"rally_id": rid, "k": k, "behind_m": behind[c + k],
                                      "speed_mps": (behind[c + k + 1] - behind[c + k])
                                      * data.fps}))
    if not rows:
        return pd.DataFrame(columns=["rally_id", "k", "behind_m", "speed_mps"])
    return pd.concat(rows, ignore_index=True)


def _chase_tracks(data: RallyData, rules: pd.DataFrame, shot: int, frames: int
                  ) -> pd.DataFrame:
    """Per rally whose ball of shot `shot` was answered: the answering player's speed along
    the line from where he stood at that contact to where he stood at his own, at each of the
    `frames` frames from the first (long form, with his run's length `need_m`)."""
    rows = []
    for rid, xy, contacts in _player_runs(data, rules, (shot + 1) % 2, shot + 2):
        c0, c1 = contacts[shot], contacts[shot + 1]
        d = xy[c1] - xy[c0]
        need = float(np.hypot(*d))
        k = np.arange(min(frames, len(xy) - 1 - c0))
        if need < CHASE_MIN_M or not len(k):
            continue
        step = (xy[c0 + k + 1] - xy[c0 + k]) @ (d / need) * data.fps
        rows.append(pd.DataFrame({"rally_id": rid, "k": k, "need_m": need, "speed_mps": step}))
    if not rows:
        return pd.DataFrame(columns=["rally_id", "k", "need_m", "speed_mps"])
    return pd.concat(rows, ignore_index=True)


@torch.no_grad()
def _teacher_forced_speed_change(model, vocab: Vocab, truth: RallyData, rules: pd.DataFrame,
                                 shot: int, frames: int, slot: int, direction, draws: int,
                                 seed: int, batch_size: int = 16) -> pd.DataFrame:
    """Per rally and frame k after the contact of shot `shot` (long form): player `slot`'s
    change of speed along a horizontal unit vector over the next frame, the record's
    (`dv_record`) and the model's expected one at the same state (`dv_model`, the mean of
    `draws` draws). `direction(rally_id, track_xy, contacts)` gives the vector from the
    player's recorded (T, 2) track and the rally's contact frames, or None to leave the rally
    out."""
    arr = rally_arrays(truth, vocab, unknown="generic")
    w = model.cfg.window_frames
    ds = WindowDataset(arr, w)
    items, contact, dirs = [], [], []
    for ri, rid in enumerate(arr.rally_id):
        contacts = list(rules.loc[rid, "contact_frames"]) if rid in rules.index else []
        if len(contacts) <= shot or contacts[shot] + frames + 1 >= arr.length[ri]:
            continue
        track = arr.pos_m[arr.start[ri]:arr.start[ri] + arr.length[ri], slot, :2]
        u = direction(int(rid), np.asarray(track, dtype=float), [int(c) for c in contacts])
        if u is None:
            continue
        s = max(0, int(contacts[shot]) + frames - w)
        items.append((ri, s))
        contact.append(int(contacts[shot]) - s)
        dirs.append(u)
    if not items:
        raise ValueError(f"no recorded rally played shot {shot} with {frames} frames after it")
    ds.items = items
    gen = torch.Generator().manual_seed(seed)
    fps = model.cfg.fps
    rows = []
    for b0 in range(0, len(items), batch_size):
        batch = default_collate([ds[i] for i in range(b0, min(b0 + batch_size, len(items)))])
        h = window_states(model, batch)
        pos, vel = batch["pos_m"], batch["vel_mps"]
        u = torch.as_tensor(np.stack(dirs[b0:b0 + len(pos)]), dtype=pos.dtype)[:, None, :]
        xy_next = torch.stack([model.sample_next(h, pos, vel, generator=gen)[..., slot, :2]
                               for _ in range(draws)]).mean(0)
        xy = pos[..., slot, :2]
        speed = (vel[..., slot, :2] * u).sum(-1)
        dv_model = ((xy_next - xy) * u).sum(-1) * fps - speed
        dv_record = ((batch["next_pos_m"][..., slot, :2] - xy) * u).sum(-1) * fps - speed
        for j in range(len(xy)):
            c = contact[b0 + j]
            k = np.arange(frames)
            rows.append(pd.DataFrame({"rally_id": int(arr.rally_id[items[b0 + j][0]]), "k": k,
                                      "speed_mps": speed[j, c + k].numpy(),
                                      "dv_record": dv_record[j, c + k].numpy(),
                                      "dv_model": dv_model[j, c + k].numpy()}))
    return pd.concat(rows, ignore_index=True)


def teacher_forced_recovery(model, vocab: Vocab, truth: RallyData, shot: int = 2,
                            frames: int = RECOVERY_FRAMES, draws: int = 32, seed: int = 0,
                            batch_size: int = 16, rules: pd.DataFrame | None = None
                            ) -> pd.DataFrame:
    """Per rally and frame k after the contact of shot `shot` (long form): the record's
    change of the hitter's speed away from the net over the next frame (`dv_record`, m/s)
    and the model's expected change at the same state (`dv_model`: the mean of `draws`
    draws of its next frame). Each rally's window ends `frames` frames after the contact."""
    rules = analyse_rally_data(truth) if rules is None else rules

    def away_from_net(rid, track, contacts):
        return np.array([np.sign(track[contacts[shot], 0]), 0.0])

    out = _teacher_forced_speed_change(model, vocab, truth, rules, shot, frames, shot % 2,
                                       away_from_net, draws, seed, batch_size)
    return out.drop(columns="speed_mps")


def chase_curves(sim, truth: RallyData, shot: int = 1, frames: int = CHASE_FRAMES,
                 bin_frames: int = BIN_FRAMES, draws: int = 32, seed: int = 0) -> pd.DataFrame:
    """The chase of the ball of shot `shot` by the player who answers it (1: the server's run
    to the return), in bins of `bin_frames` frames from its contact: his recorded speed
    towards where he strikes it (`speed_mps`, along the line from where he stood at the
    contact to where he stood at his own), the record's change of that speed over the next
    frame (`dv_record`) and the model's expected change at the same states (`dv_model`), over
    the `n` rallies whose ball was answered, by how far he had to go (`need_m`: up to 2 m,
    2-4 m, beyond); and the same speed in the model's branches rolled out from 3 frames after
    that contact (`branch_speed_mps` over `n_branch` branches whose player struck the ball,
    along the line to his own strike). A model that brakes too early teacher-forced has a
    fitting problem; one that matches on the record and in branches that reach the ball loses
    balls by the ones it does not reach (`eval.reach`)."""
    if shot < 0:
        raise ValueError(f"shot counts contacts from the serve (>= 0), got {shot}")
    if frames < bin_frames or bin_frames < 1:
        raise ValueError(f"need frames >= bin_frames >= 1, got {frames}, {bin_frames}")
    rules = analyse_rally_data(truth)
    need_m = {}

    def towards_the_strike(rid, track, contacts):
        if len(contacts) <= shot + 1:
            return None
        d = track[contacts[shot + 1]] - track[contacts[shot]]
        need_m[rid] = float(np.hypot(*d))
        return None if need_m[rid] < CHASE_MIN_M else d / need_m[rid]

    tf = _teacher_forced_speed_change(sim.model, sim.vocab, truth, rules, shot, frames,
                                      (shot + 1) % 2, towards_the_strike, draws, seed)
    tf["need_m"] = tf["rally_id"].map(need_m)
    if shot == 0:
        branches, _ = serve_branches(sim, truth, seed=seed, horizon_s=BRANCH_HORIZON_S)
    else:
        branches, _ = shot_branches(sim, truth, shot=shot, seed=seed,
                                    truth_out=shot_outcomes(truth, shot, rules),
                                    horizon_s=BRANCH_HORIZON_S)
    br = _chase_tracks(branches, analyse_rally_data(branches), shot, frames)
    keys = ["need", "frames_after"]
    for t in (tf, br):
        t["need"] = pd.cut(t["need_m"].astype(float), [0.0, 2.0, 4.0, np.inf],
                           labels=["<2 m", "2-4 m", ">4 m"])
        t["frames_after"] = t["k"] // bin_frames * bin_frames
    table = tf.groupby(keys, observed=True).agg(
        n=("rally_id", "nunique"), speed_mps=("speed_mps", "mean"),
        dv_record=("dv_record", "mean"), dv_model=("dv_model", "mean"))
    table = table.join(br.groupby(keys, observed=True).agg(
        n_branch=("rally_id", "nunique"), branch_speed_mps=("speed_mps", "mean")))
    return table.reset_index()


def recovery_curves(sim, truth: RallyData, shot: int = 2, frames: int = RECOVERY_FRAMES,
                    bin_frames: int = BIN_FRAMES, draws: int = 32, seed: int = 0
                    ) -> pd.DataFrame:
    """The hitter's run after shot `shot` (module doc), in bins of `bin_frames` frames from
    the contact: the record's `behind_m`, `speed_mps`, `dv_record`; the teacher-forced
    `dv_model`; the branches' `branch_behind_m` and `branch_speed_mps`; and `n` / `n_branch`,
    the rallies behind each."""
    if shot < 0:
        raise ValueError(f"shot counts contacts from the serve (>= 0), got {shot}")
    if frames < bin_frames or bin_frames < 1:
        raise ValueError(f"need frames >= bin_frames >= 1, got {frames}, {bin_frames}")
    rules = analyse_rally_data(truth)
    tf = teacher_forced_recovery(sim.model, sim.vocab, truth, shot, frames, draws, seed,
                                 rules=rules)
    rec = _hitter_tracks(truth, rules, shot, frames).merge(tf, on=["rally_id", "k"])
    # The server's run after his serve (shot 0) is read in the branches from 3 frames after
    # it, as the return's after it.
    if shot <= 1:
        branches, _ = serve_branches(sim, truth, seed=seed, horizon_s=BRANCH_HORIZON_S)
    else:
        branches, _ = shot_branches(sim, truth, shot=shot - 1, seed=seed,
                                    truth_out=shot_outcomes(truth, shot - 1, rules),
                                    horizon_s=BRANCH_HORIZON_S)
    br = _hitter_tracks(branches, analyse_rally_data(branches), shot, frames)
    rec["bin"] = rec["k"] // bin_frames * bin_frames
    br["bin"] = br["k"] // bin_frames * bin_frames
    table = rec.groupby("bin").agg(n=("rally_id", "nunique"), behind_m=("behind_m", "mean"),
                                   speed_mps=("speed_mps", "mean"),
                                   dv_record=("dv_record", "mean"),
                                   dv_model=("dv_model", "mean"))
    table = table.join(br.groupby("bin").agg(n_branch=("rally_id", "nunique"),
                                             branch_behind_m=("behind_m", "mean"),
                                             branch_speed_mps=("speed_mps", "mean")))
    return table.reset_index().rename(columns={"bin": "frames_after"})
