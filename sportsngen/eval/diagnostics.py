"""Rollout diagnostics: fast, low-noise signals of what a model gets wrong on its own rollouts.

All of them start from recorded serves of a ground truth (the generator's, by default Roger
Federer serving to Rafael Nadal on hard) and compare the model with that truth:

- **branch return share**: each recorded serve is rolled out from `BRANCH_AFTER_FRAMES` frames
  after its contact (the model has seen the toss and the strike, then plays on); of the
  branches whose serve lands in the box, the share the receiver returns (a second racket
  contact by the rally-end rules), against the same share of the recorded serves, and their
  difference with a paired bootstrap interval (serves resampled with their branches). A model
  whose receivers stand and watch shows it here first;
- **the server stopped**: the same serves branched again with the same seed, the server's
  track forced to brake and stand after the branch point (`sportsngen.eval.interventions`),
  and the return share minus the free branches' on the serves in the box in both (paired
  bootstrap interval). A model whose receivers read the server, as one trained on generator
  version 5 does (-0.52), returns fewer; the generator's receivers do not read him (0);
- **free-flight residual**: on those branches, how far each free-flight frame lies from one
  physics step of the ball (`sportsngen.eval.flight`, p50 and p90 per axis in mm; the
  recorded ball: well under 1 mm), and the share of those frames inside the centre bin of the
  model's ball bins in all three axes;
- **receivers still at the bounce**: the share of serves in the box whose receiver has moved
  less than `STILL_M` from where he stood at the contact when the serve bounces, branches
  against recorded serves;
- **contact probability within reach**: teacher-forced on the recorded serves that were
  returned, the model's largest probability of a racket contact (a next ball frame more than
  `contact_odds.REVERSAL_M` from its bin centre along x) over the frames the ball is within
  `REACH_M` of the receiver. Low means the model lets balls fly past players who could hit them;
- **contact probability at the serve's strike**: the same, on the tokens that predict the
  frames around each recorded serve's strike;
- **contact odds, calibrated?** (`contact_calibration`), teacher-forced on every ball token
  of the recorded rallies: the model's expected contacts (its summed P(contact)) over the
  recorded ones, on all tokens and where the ball is `EARLY_CONTACT_M` or more from both
  players (1 when calibrated; above it, rollouts strike balls before they reach the
  player); and, for the returns of serves and for the later shots, the chance of a contact
  over a recorded shot's approach (from the bounce to the recorded contact: 1 for a model
  that strikes what the record struck) and before it (up to the frame before the recorded
  contact: low for a model that knows when the ball gets there). Free of sampling noise:
  these move with the weights, not with a rollout's draws;
- **own serves**: the same serves played by the model from its own serve starts (the pool in
  the model file, as `simulate_points` plays them): the share struck at all (the rules stop a
  rally with no serve after 4 s), struck from the server's place, landing in the box (all,
  first and second serves), wide (of those in the box, bouncing in its outer third) and
  returned. The branches start after the recorded strike, so only these show a model that
  drops its own toss (a physics-centred fine-tune struck no serve in 12-17 % of its rallies
  while its branches returned 87 % of serves, docs/evaluation.md);
- **the server after the serve, one step** (`sportsngen.eval.one_step`): the server's speed
  9 frames after each recorded serve's strike, drawn one frame from the record's history,
  rank-correlated with the serve's speed within each serve number, and its slope on it (m/s
  per 10 m/s: ranks magnify a small dependence where the record's run barely varies), beside
  the record's own frame (about 0): a decoder that reads the serve's pace into the server's
  run shows it here, free of a rollout's drift; and the part of it the ball causes, the same
  draw with the serve's ball re-flown at 0.9 and 1.1 times its pace on its own path
  (`server_pace_response`; the record's server plans his run at the strike: 0);
- **branch third-shot share** (`sportsngen.eval.shot_branches`): each recorded return that
  stayed in play rolled out from `BRANCH_AFTER_FRAMES` frames after its contact; of the
  branches whose return stayed in play, the share the server struck back, against the
  record's (where serve points are lost after the return); and the **landing gap**, how far
  from the recorded first bounce the model flew those returns (median and p90, m): the free
  flight's error integrated over a rally ball's 20-30 frames;
- **shots after the window** (`sportsngen.eval.long_rallies`): the contact odds over the
  approach of recorded shots struck after the model's window, in the cached rollout's view and
  in a training window's;
- **leak check on rollouts** (`sportsngen.eval.leaks`, the serve pairs, with bootstrap
  intervals; cells on fewer than `MIN_LEAK_PAIRS` comparable pairs left blank): whether the
  model's players, after the branch point, move as if they knew the serve's outcome; the same
  on its own serves, played from the toss ("(own serves)": the serve's outcome is the model's
  too, a second sample of as many serves); beside each, the same cell on the recorded points
  (`truth_leak_aucs`).

`run_diagnostics` computes them all (110 s on two cores for the defaults, 143 s with seed 1);
``python -m sportsngen.eval diagnose`` prints them for any model file.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import RallyArrays, Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.eval.contact_odds import approach_frames, far_probability
from sportsngen.eval.flight import flight_residuals, rally_tracks
from sportsngen.eval.leaks import check_leaks, interval_holds_half, outside_band
from sportsngen.eval.long_rallies import late_shot_contact_odds
from sportsngen.eval.rules import analyse_rally_data
from sportsngen.eval.shot_branches import (
    RETURN_SHOT,
    answer_share,
    branch_rallies,
    landing_gaps_m,
    shot_branches,
    shot_outcomes,
)
from sportsngen.model.inputs import BALL, OBJECTS
from sportsngen.sim.assemble import PLAN_COLUMNS
from sportsngen.tennis.court import SINGLES_HALF_WIDTH_M, is_in_service_box
from sportsngen.train.metrics import window_states
from sportsngen.train.windows import WindowDataset

BRANCH_AFTER_FRAMES = 3   # frames after the serve contact kept from the record
HORIZON_S = 3.0           # a branch is rolled out this long: the serve, the return, its flight
OWN_SERVE_S = 4.5         # own serves: past the rules' 4 s "no serve struck" and the return
WIDE_SERVE_Y_M = 2.0 * SINGLES_HALF_WIDTH_M / 3.0   # a serve bouncing in the box's outer third
STILL_M = 0.05
REACH_M = 1.5
# Recorded racket contacts are struck within 1.43 m of the hitter (99th percentile, Federer v
# Nadal, 400 points); a contact drawn with the ball further from both players is early.
EARLY_CONTACT_M = 1.5
SERVE_PAIRS = ("fault_vs_in", "ace_vs_returned")
RECEIVER_SLOT = OBJECTS.index("receiver")
# A leak cell resting on fewer comparable pairs is left blank (NaN): with 3 pairs an AUC is 0,
# 0.33, 0.67 or 1 whatever the model does.
MIN_LEAK_PAIRS = 30
STRIKE_LEFT_M = 0.01  # a serve's ball this far nearer the net than its contact has been struck


@dataclass(frozen=True)
class DiagnosticsSetup:
    """Which truth the diagnostics branch from."""

    server: str = "Roger Federer"
    receiver: str = "Rafael Nadal"
    surface: str = "hard"
    n_points: int = 400
    seed: int = 0
    leak_boot: int = 200
    leak_exact: bool = False  # rank speeds and accelerations as exact floats (before s98)

    @property
    def leak_resolution(self) -> dict[str, float] | None:
        """`check_leaks`'s resolution: None for its default (`leaks.FEATURE_RESOLUTION`),
        {} for exact floats, the readings recorded before the resolution existed."""
        return {} if self.leak_exact else None


def truth_points(setup: DiagnosticsSetup) -> RallyData:
    """The generator's points of the setup's matchup, only those `server` serves."""
    from sportsngen.synth import generate_matches

    data = generate_matches([(setup.server, setup.receiver)], setup.surface,
                            n_points=setup.n_points, seed=setup.seed, workers=1)
    r = data.rallies
    return data.subset(r.loc[r["server"] == setup.server, "rally_id"])


def serve_outcomes(data: RallyData, rules: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per rally (rules on the tracks, or `rules` already read from them): serve in the box,
    returned, the receiver's movement from the serve contact to the first bounce (m), the
    frames (from the rally's first) of that bounce and of the return (-1 where there is
    none), and how far from the centre line the serve bounced (`bounce_abs_y_m`, NaN
    without a bounce)."""
    rules = analyse_rally_data(data) if rules is None else rules
    arr = rally_arrays(data, _generic_vocab(data))
    rows = []
    for ri, rid in enumerate(arr.rally_id):
        rule = rules.loc[rid]
        contacts, bounces = rule["contact_frames"], rule["bounce_frames"]
        in_box, moved, bounce, abs_y = False, np.nan, -1, np.nan
        if len(contacts) and len(bounces) and bounces[0] > contacts[0]:
            bounce = int(bounces[0])
            bx, by = rule["bounces_m"][0][:2]
            abs_y = abs(float(by))
            in_box = bool(is_in_service_box(bx, by, int(rule["server_end"]), str(rule["side"])))
            track = arr.pos_m[arr.start[ri]:arr.start[ri] + arr.length[ri], RECEIVER_SLOT, :2]
            # The rules round an event to the nearer frame of its step, which for a rally cut
            # short (a branch's horizon) can be the frame after its last one.
            last = len(track) - 1
            moved = float(np.hypot(*(track[min(bounce, last)] - track[min(contacts[0], last)])))
        returned = in_box and int(rule["n_shots"]) >= 2
        rows.append({"rally_id": int(rid), "in_box": in_box, "returned": returned,
                     "moved_m": moved, "bounce_frame": bounce, "bounce_abs_y_m": abs_y,
                     "return_frame": int(contacts[1]) if returned else -1})
    return pd.DataFrame(rows).set_index("rally_id")


def with_rules_serve_outcomes(data: RallyData, out: pd.DataFrame) -> RallyData:
    """`data` with each serve's outcome from the rules (`serve_outcomes`: in the box ->
    "in_play", else "error"). A simulated rally's shot outcomes are its event classifier's,
    and the one retrained on version 6 labelled 5 of the 6 aces of 35 serve branches errors,
    which left the leak check on rollouts no ace to compare."""
    shots = data.shots.copy()
    serve = shots["shot_index"].to_numpy() == 0
    in_box = shots.loc[serve, "rally_id"].map(out["in_box"]).fillna(False).to_numpy(bool)
    outcome = np.array(shots["outcome"], dtype=object)
    outcome[np.flatnonzero(serve)] = np.where(in_box, "in_play", "error")
    shots["outcome"] = outcome
    return replace(data, shots=shots)


def _generic_vocab(data: RallyData) -> Vocab:
    return Vocab.from_data(data, generic=True)


def wide_share(in_box: pd.DataFrame) -> float:
    """Of serves in the box (`serve_outcomes` rows), the share bouncing in the box's outer third
    (`WIDE_SERVE_Y_M`); NaN without any."""
    return float((in_box["bounce_abs_y_m"] > WIDE_SERVE_Y_M).mean()) if len(in_box) else np.nan


def serve_strike_frames(data: RallyData) -> pd.Series:
    """Rally id -> the frame of its serve's strike, the first past the racket, counted from the
    rally's first frame (rallies without a serve left out). The shots table's frame is the
    contact's, rounded (`shot_index` 0): where the ball there has not yet left the contact
    toward the net by `STRIKE_LEFT_M` (a contact late in the frame interval: every one of
    Williams' generated serves), the strike is the next frame. The ball's own position at that
    frame is read, not the flight after it carried back (`leaks.frames_flown`): over two
    frames a serve's drag puts that 0.04 of a frame out, enough to move 35 of 1,628 strikes."""
    serves = data.shots.loc[data.shots["shot_index"] == 0, ["rally_id", "frame", "contact_x"]]
    ball = data.frames.loc[data.frames["object"] == "ball", ["rally_id", "frame", "x"]]
    at = serves.merge(ball, on=["rally_id", "frame"], how="left")
    left = (at["contact_x"].abs() - at["x"].abs()) > STRIKE_LEFT_M  # NaN (no ball row): False
    strike = pd.Series((at["frame"] + (~left).astype(int)).to_numpy(),
                       index=at["rally_id"].to_numpy())
    first = data.frames.groupby("rally_id")["frame"].min()
    return (strike - first.reindex(strike.index)).astype(int)


def serve_branches(sim, truth: RallyData, seed: int = 0, horizon_s: float = HORIZON_S,
                   after_frames: int = BRANCH_AFTER_FRAMES) -> tuple[RallyData, pd.Series]:
    """Each recorded serve rolled out once from `after_frames` frames after its contact (the
    serve's strike frame, the first past the racket, kept at 0; -1: the model strikes) ->
    (the branches, a Series: branch rally id -> the recorded rally id it branched from)."""
    return branch_rallies(sim, truth, serve_strike_frames(truth) + after_frames + 1, seed,
                          horizon_s)


def strike_branches(sim, truth: RallyData, after_frames: tuple[int, ...] = (-1, 0, 1, 3),
                    seed: int = 0) -> pd.DataFrame:
    """Where a serve's fate is decided: the recorded serves branched at each of `after_frames`
    (`serve_branches`) -> per branch point and serve number, the share landing in the box, the
    shares of those wide (`wide_share`) and returned, beside the recorded serves' (`after` =
    "recorded"). From -1 the model strikes from the recorded toss; from 0 it has the strike's
    first frame and decides the next; from 3 the flight is set."""
    number = truth.rallies.set_index("rally_id")["serve_number"]
    parts = []
    for after in [*after_frames, None]:
        if after is None:
            out, label = serve_outcomes(truth), "recorded"
            out["serve_number"] = number.reindex(out.index).to_numpy()
        else:
            branches, order = serve_branches(sim, truth, seed=seed, after_frames=after)
            out, label = serve_outcomes(branches), str(after)
            out["serve_number"] = number.reindex(order.reindex(out.index)).to_numpy()
        for serve, g in out.groupby("serve_number"):
            box = g[g["in_box"]]
            parts.append({"after": label, "serve_number": int(serve), "n": len(g),
                          "in_box": float(g["in_box"].mean()),
                          "wide": wide_share(box),
                          "returned": float(box["returned"].mean()) if len(box) else np.nan})
    return pd.DataFrame(parts)


def paired_return_gap(branch_out: pd.DataFrame, truth_out: pd.DataFrame, order: pd.Series,
                      n_boot: int, seed: int, level: float = 0.95) -> tuple[float, float, float]:
    """Branch return share minus the recorded share of the same serves, with a bootstrap
    interval that resamples serves together with their branches -> (gap, lo, hi). Paired, so
    the truth's own sampling noise (the recorded share moved 11 points between two 400-point
    seeds) does not widen it."""
    b = branch_out.loc[order.index]
    r = truth_out.loc[order.to_numpy()]
    b_in, b_ret = b["in_box"].to_numpy(bool), b["returned"].to_numpy(bool)
    r_in, r_ret = r["in_box"].to_numpy(bool), r["returned"].to_numpy(bool)

    def gap(idx: np.ndarray) -> float:
        nb, nr = b_in[idx].sum(), r_in[idx].sum()
        if nb == 0 or nr == 0:
            return float("nan")
        return float(b_ret[idx].sum() / nb - r_ret[idx].sum() / nr)

    rng = np.random.default_rng(seed)
    boots = np.array([gap(rng.integers(0, len(b), len(b))) for _ in range(max(n_boot, 1))])
    lo, hi = np.nanquantile(boots, [(1 - level) / 2, (1 + level) / 2])
    return gap(np.arange(len(b))), float(lo), float(hi)


@dataclass
class FirstWindows:
    """The model's first window of every recorded rally and its teacher-forced P(contact) on
    each ball token (`far_probability`; token t predicts frame t+1): one pass of the model
    that every contact signal reads."""

    arrays: RallyArrays
    windows: dict        # rally position -> WindowDataset item
    odds: dict           # rally position -> (T,) P(contact)


def first_windows(sim, truth: RallyData, batch_size: int = 32) -> FirstWindows:
    """Score the first window of every rally of `truth` once (`FirstWindows`)."""
    arr = rally_arrays(truth, sim.vocab, unknown="generic")
    items = WindowDataset(arr, sim.model.cfg.window_frames)
    first = {items.items[i][0]: items[i] for i in items.first_windows()}
    rows = sorted(first)
    p = window_contact_probabilities(sim.model, [first[ri] for ri in rows], batch_size)
    return FirstWindows(arr, first, dict(zip(rows, p)))


@torch.no_grad()
def window_contact_probabilities(model, windows: list, batch_size: int = 32) -> np.ndarray:
    """Teacher-forced P(contact) (`far_probability`, with the model's contact table where it
    has one) of every ball token of `windows` (`WindowDataset` items of one length T) ->
    (len(windows), T); token t predicts frame t+1."""
    out = []
    for b0 in range(0, len(windows), batch_size):
        batch = default_collate(windows[b0:b0 + batch_size])
        h = window_states(model, batch)[:, :, BALL]
        frames = [None if batch.get(k) is None else batch[k].reshape(-1, 3, 3)
                  for k in ("pos_m", "vel_mps", "prev_vel_mps")]
        out.append(far_probability(model, h.reshape(-1, h.shape[-1]), *frames)
                   .reshape(h.shape[:2]))
    t = model.cfg.window_frames
    return torch.cat(out).numpy() if out else np.zeros((0, t), dtype=np.float32)


def _max_contact_probability(fw: FirstWindows, picked: list) -> list[float]:
    """For (rally position, frames) pairs: the largest P(contact) over those frames."""
    return [float(fw.odds[ri][frames].max()) for ri, frames in picked]


def contact_calibration(sim, truth: RallyData, fw: FirstWindows | None = None,
                        rules: pd.DataFrame | None = None) -> dict:
    """How well the model's teacher-forced P(contact) matches the recorded contacts (module
    doc), on the first window of every recorded rally -> {"ratio" (the model's expected
    contacts, the sum of its P(contact), over the recorded ones), "early_ratio" (the same
    where the ball is `EARLY_CONTACT_M` or more from both players), "return_approach",
    "return_before", "rally_approach", "rally_before" (means over the returns of serves and
    over the later shots, `approach_frames`), "contacts", "early_contacts", "returns",
    "rally_shots"}."""
    fw = fw or first_windows(sim, truth)
    arr, rows = fw.arrays, sorted(fw.windows)
    if not rows:
        raise ValueError("contact_calibration: no recorded rally to score")
    p = np.stack([fw.odds[ri] for ri in rows])
    batch = default_collate([fw.windows[ri] for ri in rows])
    _, ball_bin = sim.model.target_bins(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                        batch.get("prev_vel_mps"))
    happened = sim.model.contact_bins()[ball_bin[..., 0]].numpy()
    scored = batch["has_next"].numpy().astype(bool)
    pos = batch["pos_m"].numpy()
    gap = np.min([np.hypot(*(pos[..., BALL, :2] - pos[..., k, :2]).transpose(2, 0, 1))
                  for k in range(BALL)], axis=0)
    far = scored & (gap >= EARLY_CONTACT_M)
    rules = analyse_rally_data(truth) if rules is None else rules
    odds: dict[str, tuple[list, list]] = {"return": ([], []), "rally": ([], [])}
    for i, ri in enumerate(rows):
        rule = rules.loc[arr.rally_id[ri]]
        for shot, lo, hi in approach_frames(list(rule["contact_frames"]),
                                            list(rule["bounce_frames"])):
            if hi >= sim.model.cfg.window_frames - 1:
                break
            miss = np.cumprod(1.0 - p[i, lo:hi + 1].astype(float))
            kind = odds["return" if shot == 1 else "rally"]
            kind[0].append(1.0 - miss[-1])
            kind[1].append(1.0 - (miss[-2] if len(miss) > 1 else 1.0))
    n_far = int(happened[far].sum())
    out = {"ratio": float(p[scored].sum() / max(int(happened[scored].sum()), 1)),
           "early_ratio": float(p[far].sum() / n_far) if n_far else float("nan"),
           "contacts": int(happened[scored].sum()), "early_contacts": n_far,
           "returns": len(odds["return"][0]), "rally_shots": len(odds["rally"][0])}
    for kind, (approach, before) in odds.items():
        out[f"{kind}_approach"] = float(np.mean(approach)) if approach else float("nan")
        out[f"{kind}_before"] = float(np.mean(before)) if before else float("nan")
    return out


def contact_probability(sim, truth: RallyData, outcomes: pd.DataFrame,
                        fw: FirstWindows | None = None) -> tuple[float, int]:
    """Mean over returned recorded serves (`serve_outcomes`) of the model's largest
    teacher-forced P(contact) while the ball is within `REACH_M` of the receiver, from the
    bounce to the return (first window of each rally) -> (mean, serves averaged)."""
    fw = fw or first_windows(sim, truth)
    picked = []   # (rally position, frames within reach)
    for ri, rid in enumerate(fw.arrays.rally_id):
        lo, hi = outcomes.at[rid, "bounce_frame"], outcomes.at[rid, "return_frame"]
        if not outcomes.at[rid, "returned"] or hi >= sim.model.cfg.window_frames - 1:
            continue
        pos = fw.windows[ri]["pos_m"][lo:hi + 1]
        gap = np.hypot(*(pos[:, BALL, :2] - pos[:, RECEIVER_SLOT, :2]).T)
        if (gap <= REACH_M).any():
            picked.append((ri, lo + np.flatnonzero(gap <= REACH_M)))
    best = _max_contact_probability(fw, picked)
    return (float(np.mean(best)) if best else float("nan")), len(best)


def serve_contact_probability(sim, truth: RallyData,
                              fw: FirstWindows | None = None) -> tuple[float, int]:
    """Mean over recorded serves of the model's largest teacher-forced P(contact) on the
    tokens that predict the frames around the serve's strike (the shots table's frame, one
    frame either side) -> (mean, serves averaged). The serve is the one contact no rollout
    can branch past: a model unsure of it drops the toss ("no_serve")."""
    fw = fw or first_windows(sim, truth)
    strike = serve_strike_frames(truth)
    picked = []
    for ri, rid in enumerate(fw.arrays.rally_id):
        if rid not in strike.index:
            continue
        f = int(strike[rid])
        if 2 <= f < sim.model.cfg.window_frames - 1:
            picked.append((ri, np.arange(f - 2, f + 1)))
    best = _max_contact_probability(fw, picked)
    return (float(np.mean(best)) if best else float("nan")), len(best)


def own_serves(sim, truth: RallyData, seed: int = 0) -> RallyData:
    """The recorded rallies' serves played by the model from its own serve starts (the pool
    in the model file, as `simulate_points` does), `OWN_SERVE_S` long: long enough for the
    rules to flag a serve never struck and to see the return."""
    plan = truth.rallies.reset_index(drop=True)[PLAN_COLUMNS].copy()
    plan["match_id"] = "own_serve"
    return sim.simulate_rallies(plan, seed=seed, max_duration_s=OWN_SERVE_S)


def own_serve_rows(own: RallyData, truth_out: pd.DataFrame,
                   out: pd.DataFrame | None = None) -> list[tuple]:
    """Rows of the diagnostics table for `own_serves`: struck, struck from the right place, in
    the box (all, first and second serves), wide (of those in the box, bouncing in the box's
    outer third) and returned (of those in the box), beside the recorded serves (the same
    rally ids, so the same serve numbers). `out`: the own serves' `serve_outcomes`, when
    already read."""
    failed = own.rallies.set_index("rally_id")["failed_checks"].astype(str)
    out = serve_outcomes(own) if out is None else out
    n = len(failed)
    rows = [("own serves struck", float((~failed.str.contains("no_serve")).mean()), 1.0, n),
            ("own serves struck from the server's place",
             float((~failed.str.contains("serve_position|no_serve")).mean()), 1.0, n),
            ("own serves in the box", float(out["in_box"].mean()),
             float(truth_out["in_box"].mean()), n)]
    number = own.rallies.set_index("rally_id")["serve_number"]
    for k, name in ((1, "first"), (2, "second")):
        mine = out.loc[number.reindex(out.index).to_numpy() == k, "in_box"]
        theirs = truth_out.loc[number.reindex(truth_out.index).to_numpy() == k, "in_box"]
        rows.append((f"own serves in the box, {name} serves", float(mine.mean()) if len(mine) else
                     float("nan"), float(theirs.mean()) if len(theirs) else float("nan"),
                     int(len(mine))))
    in_box, truth_in = out[out["in_box"]], truth_out[truth_out["in_box"]]
    rows.append(("own serves wide (serves in the box)", wide_share(in_box),
                 wide_share(truth_in), int(len(in_box))))
    ret = out.loc[out["in_box"], "returned"]
    rows.append(("own serves returned (serves in the box)",
                 float(ret.mean()) if len(ret) else float("nan"),
                 float(truth_out.loc[truth_out["in_box"], "returned"].mean()), int(len(ret))))
    return rows


def truth_leak_aucs(record: pd.DataFrame, cells: pd.DataFrame) -> np.ndarray:
    """The leak check's AUC on the recorded points (`record`, `check_leaks` of them) for each
    (pair, role, feature, k) row of `cells` (NaN where the record has fewer than
    `MIN_LEAK_PAIRS` comparable pairs): what a rollout cell is to be read against (the
    generator's players tie within a stratum, 0.5)."""
    rec = record.assign(auc=record["auc"].where(record["n_pairs"] >= MIN_LEAK_PAIRS))
    key = ["pair", "role", "feature", "k"]
    return cells[key].merge(rec[key + ["auc"]], on=key, how="left")["auc"].to_numpy(float)


def leak_table_rows(rollouts: RallyData, record: pd.DataFrame, setup: DiagnosticsSetup,
                    label: str = "") -> pd.DataFrame:
    """The serve pairs' leak cells of `rollouts` (serve outcomes from the rules) as rows of the
    diagnostics table, each beside the record's cell (`truth_leak_aucs`); cells on fewer than
    `MIN_LEAK_PAIRS` pairs blank."""
    leaks = check_leaks(rollouts, n_boot=setup.leak_boot, seed=setup.seed,
                        resolution=setup.leak_resolution)
    leaks = leaks[leaks["pair"].isin(SERVE_PAIRS)]
    few = leaks["n_pairs"] < MIN_LEAK_PAIRS
    return pd.DataFrame({
        "signal": [f"leak AUC{label} {r.pair} {r.role} {r.feature} k={int(r.k)}"
                   for r in leaks.itertuples()],
        "model": leaks["auc"].where(~few).to_numpy(float),
        "data": truth_leak_aucs(record, leaks),
        "n": leaks["n_pairs"].to_numpy(int),
        "lo": leaks["lo"].where(~few).to_numpy(float),
        "hi": leaks["hi"].where(~few).to_numpy(float)})


_SERVES = {1: "first", 2: "second"}


def leak_rows_summary(table: pd.DataFrame, band=(0.4, 0.6)) -> str:
    """One line on `run_diagnostics`' leak rows: how many of the model's AUCs lie outside
    `band`, and how many of those have a bootstrap interval holding 0.5 (unsure: at 400
    points a cell rests on a few hundred pairs and falls outside by chance)."""
    rows = table[table["signal"].str.startswith("leak AUC")]
    cells = rows.rename(columns={"model": "auc"})[["auc", "lo", "hi"]]
    out = outside_band(cells, band)
    unsure = out & interval_holds_half(cells)
    return (f"leak rows outside [{band[0]:g}, {band[1]:g}]: {int(out.sum())} of "
            f"{int(cells['auc'].notna().sum())} read ({int(unsure.sum())} unsure: their 95 % "
            f"interval holds 0.5)")


# Points at which the leak rows are read: at 400 each rests on 70-900 pairs and the rows
# outside with an interval leaving out 0.5 changed from seed to seed; at 1,600 (3 1/2 min here)
# an interval is about +-0.1 and the rows outside on five seeds were all one family, the
# receiver 12 frames into an ace (docs/evaluation.md, seventy-fifth part).
LEAK_READ_POINTS = 1600


def leak_rows_advice(n_points: int) -> str | None:
    """A line under the leak rows when `n_points` is too few to read them, else None."""
    if n_points >= LEAK_READ_POINTS:
        return None
    return (f"(at {n_points} points the leak rows rest on few pairs and move from seed to seed: "
            f"read them with --points {LEAK_READ_POINTS})")


def run_diagnostics(sim, setup: DiagnosticsSetup = DiagnosticsSetup()) -> pd.DataFrame:
    """Every diagnostic of the module doc -> a table: signal, model, data (NaN where the
    signal has no data side), n (serves, frames or, for a leak AUC, comparable pairs) and, for
    the leak AUCs, the bootstrap interval lo-hi (blank under `MIN_LEAK_PAIRS` pairs)."""
    truth = truth_points(setup)
    truth_rules = analyse_rally_data(truth)      # read once: three signals use it
    truth_out = serve_outcomes(truth, truth_rules)
    branches, order = serve_branches(sim, truth, seed=setup.seed)
    branch_out = serve_outcomes(branches)
    rows = []

    def share(out, col, sel):
        s = out.loc[sel, col]
        return float(s.mean()) if len(s) else float("nan"), int(len(s))

    m, n = share(branch_out, "returned", branch_out["in_box"])
    d, _ = share(truth_out, "returned", truth_out["in_box"])
    rows.append(("branch return share (serves in the box)", m, d, n))
    gap, lo, hi = paired_return_gap(branch_out, truth_out, order, setup.leak_boot, setup.seed)
    # Imported here: the interventions build on this module's serve branches.
    from sportsngen.eval.interventions import stopped_server_gap
    stopped = stopped_server_gap(sim, truth, branches, order, branch_out, setup.seed,
                                 setup.leak_boot)
    still_m = branch_out.loc[branch_out["in_box"], "moved_m"] < STILL_M
    still_d = truth_out.loc[truth_out["in_box"], "moved_m"] < STILL_M
    rows.append(("receivers still at the bounce", float(still_m.mean()),
                 float(still_d.mean()), int(len(still_m))))
    arr = rally_arrays(branches, _generic_vocab(branches))
    res = flight_residuals(rally_tracks(arr.pos_m, arr.start, arr.length), sim.fps)
    s = res.summary(sim.model.cfg)
    truth_arr = rally_arrays(truth, _generic_vocab(truth))
    ts = flight_residuals(rally_tracks(truth_arr.pos_m, truth_arr.start, truth_arr.length),
                          truth.fps).summary(sim.model.cfg)
    for q in ("median", "p90"):
        for ax in "xyz":
            key = f"{q}_{ax}_mm"
            rows.append((f"free-flight residual {q} {ax} (mm)", s[key], ts[key],
                         int(s["frames"])))
    rows.append(("free-flight frames in the physics step's centre bin",
                 s.get("centre_bin_share", float("nan")), ts.get("centre_bin_share", float("nan")),
                 int(s["frames"])))
    fw = first_windows(sim, truth)
    p_contact, n_contact = contact_probability(sim, truth, truth_out, fw)
    rows.append(("contact probability within reach (returned serves)", p_contact,
                 float("nan"), n_contact))
    p_serve, n_serve = serve_contact_probability(sim, truth, fw)
    rows.append(("contact probability at the serve's strike", p_serve, float("nan"), n_serve))
    cal = contact_calibration(sim, truth, fw, truth_rules)
    for kind, label, n in (("return", "returns of serves", "returns"),
                           ("rally", "later shots", "rally_shots")):
        rows += [(f"contact probability over the approach ({label})", cal[f"{kind}_approach"],
                  1.0, cal[n]),
                 (f"contact probability before the recorded contact ({label})",
                  cal[f"{kind}_before"], float("nan"), cal[n])]
    rows += [("expected / recorded contacts (ball tokens)", cal["ratio"], 1.0, cal["contacts"]),
             (f"expected / recorded contacts, ball {EARLY_CONTACT_M:g} m or more from both "
              "players", cal["early_ratio"], 1.0, cal["early_contacts"])]
    late = late_shot_contact_odds(sim, truth, truth_rules)
    rows += [("contact probability over the approach, shots after the window (rollout's band)",
              late["band"], 1.0, late["shots"]),
             ("contact probability over the approach, shots after the window (training's "
              "window)", late["window"], 1.0, late["shots"])]
    own = own_serves(sim, truth, seed=setup.seed)
    own_out = serve_outcomes(own)
    rows += own_serve_rows(own, truth_out, own_out)
    from sportsngen.eval.one_step import (
        COUPLING_AFTER_FRAMES,
        server_pace_response,
        server_serve_coupling,
    )
    coupling = server_serve_coupling(sim, truth, seed=setup.seed)
    for c in coupling.itertuples():
        rows.append((f"server speed at strike + {COUPLING_AFTER_FRAMES}, one step: corr with "
                     f"serve speed ({_SERVES[c.serve_number]} serves)", c.model_corr,
                     c.record_corr, c.n))
    for c in coupling.itertuples():
        rows.append((f"server speed at strike + {COUPLING_AFTER_FRAMES}, one step: m/s per 10 "
                     f"m/s of serve ({_SERVES[c.serve_number]} serves)", c.model_slope,
                     c.record_slope, c.n))
    # The same, caused: his serve's ball re-flown faster and slower on its own path.
    for c in server_pace_response(sim, truth, seed=setup.seed).itertuples():
        rows.append((f"server speed at strike + {COUPLING_AFTER_FRAMES}, one step: m/s per 10 "
                     f"m/s of the ball's pace, path held ({_SERVES[c.serve_number]} serves)",
                     c.slope, 0.0, c.n))
    returns = shot_outcomes(truth, RETURN_SHOT, truth_rules)
    ret_branches, ret_order = shot_branches(sim, truth, RETURN_SHOT, BRANCH_AFTER_FRAMES,
                                            setup.seed, truth_out=returns)
    ret_out = shot_outcomes(ret_branches, RETURN_SHOT)
    ans = answer_share(ret_out, returns, ret_order)
    gaps = landing_gaps_m(ret_out, returns, ret_order)
    rows += [("branch returns still in play (returns in play)", ans["in_play"], 1.0,
              len(ret_order)),
             ("branch third-shot share (returns in play)", ans["model"], ans["data"], ans["n"])]
    for q, label in ((0.5, "median"), (0.9, "p90")):
        rows.append((f"branch return's landing gap {label} (m)",
                     float(np.quantile(gaps, q)) if len(gaps) else float("nan"), 0.0,
                     len(gaps)))
    table = pd.DataFrame(rows, columns=["signal", "model", "data", "n"])
    gap_row = pd.DataFrame([{"signal": "branch return share minus recorded (paired)",
                             "model": gap, "data": np.nan, "n": len(order), "lo": lo, "hi": hi},
                            {"signal": "branch return share, server stopped, minus free "
                                       "(paired)", "model": stopped["diff"], "data": 0.0,
                             "n": int(stopped["n_pairs"]), "lo": stopped["lo"],
                             "hi": stopped["hi"]}])
    table = pd.concat([table.iloc[:1], gap_row, table.iloc[1:]], ignore_index=True)
    record = check_leaks(truth, n_boot=0, resolution=setup.leak_resolution)
    leak_rows = [leak_table_rows(with_rules_serve_outcomes(branches, branch_out), record, setup),
                 leak_table_rows(with_rules_serve_outcomes(own, own_out), record, setup,
                                 " (own serves)")]
    return pd.concat([table, *leak_rows], ignore_index=True)

