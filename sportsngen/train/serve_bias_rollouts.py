"""Refit the per-server serve shifts on the model's own rollouts.

The shifts of `train.serve_bias` are found on the record's states: the serve head's mean odds
of a long (a wide) serve at the recorded tosses equal the record's. A rollout serves from the
model's own toss, and there every named server faulted less than his record (the bundled file
of the thirtieth part: first serves in 3.4 points above the truth's over sixteen player-runs,
Djokovic's 7.8 and Federer's 6.6 on the check's seed 0; docs/evaluation.md, thirty-first part).
Here each server's serves are rolled out as a match plays them, cut once the serve's fate is
decided (`ROLLOUT_S`), their faults read by the rules, and his long and wide shifts moved
together by the gap between the record's fault share and the rollouts' in logits, a few rounds
with a gain of 1 / (round + 1) (a fault's odds rise monotonically with both shifts, and the
long and wide faults are most of them, so a full step is close to a Newton step; the falling
gain averages the rollouts' sampling noise). The record's share is read from the rallies
themselves (a rally with a fault label), not through the bins.

Measured on the bundled file: the named servers' first serves in came within 2 points of the
truth's on average (+1.99 against +3.44), but the checks fell from 85 to 79 of 96 statistics
(fewer first serves in, fewer aces), so the bundled recipe does not run it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from sportsngen.data.tokens import RallyArrays
from sportsngen.data.tracking import ERROR_KINDS, SURFACES
from sportsngen.model import serve_bias
from sportsngen.model.inputs import N_SPECIAL_IDS
from sportsngen.sim.simulator import points_plan
from sportsngen.train.serve_bias import MAX_SHIFT, share_logit

# A serve's fate is decided before 3 s of the rally (toss, flight, bounce): on 200 of the
# bundled file's serves, cut at 3 s and played out, the same 65 faults and 7 aces.
ROLLOUT_S = 3.0
_FAULT = ERROR_KINDS.index("fault")


def recorded_fault_shares(arrays: Sequence[RallyArrays]) -> pd.DataFrame:
    """Per (server_id, serve) over every rally of `arrays`: n serves, faults and their share
    (a rally is a fault where any of its frames carries the fault label)."""
    parts = []
    for a in arrays:
        fault_row = (a.labels[:, 3] == _FAULT).astype(np.int64)
        faults = np.add.reduceat(fault_row, a.start) if len(a) else np.zeros(0, np.int64)
        faults = np.where(a.length > 0, faults, 0) > 0
        parts.append(pd.DataFrame({"server_id": a.ident[:, 0], "serve": a.serve,
                                   "fault": faults}))
    df = pd.concat(parts, ignore_index=True)
    out = df.groupby(["server_id", "serve"])["fault"].agg(n="size", faults="sum").reset_index()
    out["share"] = out["faults"] / out["n"]
    return out


def top_receivers(arrays: Sequence[RallyArrays], server_id: int, k: int = 3) -> list[int]:
    """The `k` receivers `server_id` served to most in `arrays` (identity ids)."""
    ids = np.concatenate([a.ident[a.ident[:, 0] == server_id, 1] for a in arrays])
    if not len(ids):
        raise ValueError(f"server id {server_id} serves no rally in the record")
    vals, counts = np.unique(ids, return_counts=True)
    return [int(v) for v in vals[np.argsort(-counts, kind="stable")][:k]]


def rollout_fault_share(sim, server: str, receivers: Sequence[str], serve_number: int,
                        n_serves: int, seed: int) -> tuple[int, int]:
    """`n_serves` serves of `server` (serve `serve_number`: 1 or 2) rolled out by `sim`
    (`Simulator`), spread over `receivers` and every surface, cut at `ROLLOUT_S` -> (faults,
    serves decided: those the rules read a serve in)."""
    pairs = [(r, s) for r in receivers for s in SURFACES]
    per = max(1, int(np.ceil(n_serves / len(pairs))))
    plan = pd.concat([points_plan(server, rec, surface, per, seed * 1000 + i, serve_number)
                      for i, (rec, surface) in enumerate(pairs)], ignore_index=True)
    plan["rally_id"] = np.arange(len(plan))
    reason = sim.simulate_rallies(plan, seed=seed,
                                  max_duration_s=ROLLOUT_S).rallies["end_reason"].astype(str)
    faults = int(reason.isin(["fault", "double_fault"]).sum())
    decided = int((reason != "no_serve").sum())
    return faults, decided


def refine_serve_bias(sim, arrays: Sequence[RallyArrays], players: Sequence[str],
                      n_serves: int = 400, rounds: int = 3, seed: int = 0,
                      log=print) -> pd.DataFrame:
    """Move `sim.model.serve_bias`'s long and wide shifts (in place) of each of `players`, on
    both serves, until his rollouts' fault share meets his record's in `arrays`: `rounds`
    updates, each from `n_serves` fresh rollouts, then one more measurement. -> one row per
    (server, serve, round): record share, rollout share, the shift added."""
    model = sim.model
    if model.serve_bias is None:
        raise ValueError("the model has no per-server table (cfg.serve_bias): fit it first "
                         "(scripts/fit_serve_bias.py)")
    if n_serves < 20 or rounds < 0:
        raise ValueError(f"n_serves must be >= 20 and rounds >= 0, got {n_serves}, {rounds}")
    vocab = sim.vocab
    record = recorded_fault_shares(arrays).set_index(["server_id", "serve"])
    rows = []
    for name in players:
        sid = vocab.player_index(name, unknown="error")
        receivers = [vocab.players[i - N_SPECIAL_IDS] for i in top_receivers(arrays, sid)]
        for serve in range(serve_bias.N_SERVES):
            if (sid, serve) not in record.index:
                continue
            target = float(record.loc[(sid, serve), "share"])
            n_rec = int(record.loc[(sid, serve), "n"])
            for rnd in range(rounds + 1):
                faults, n = rollout_fault_share(sim, name, receivers, serve + 1, n_serves,
                                                seed + 7919 * rnd + 31 * serve)
                share = faults / max(n, 1)
                step = 0.0
                if rnd < rounds:
                    # A gain falling as 1 / (round + 1) averages the rounds' sampling noise
                    # away instead of chasing it (stochastic approximation).
                    step = float(share_logit(target, n_rec) - share_logit(share, n)) / (rnd + 1)
                    for kind in (serve_bias.LONG, serve_bias.WIDE):
                        v = float(model.serve_bias[sid, serve, kind]) + step
                        model.serve_bias[sid, serve, kind] = float(np.clip(v, -MAX_SHIFT,
                                                                           MAX_SHIFT))
                rows.append({"server": name, "serve": serve + 1, "round": rnd,
                             "record_n": n_rec, "record_share": target, "rollout_n": n,
                             "rollout_share": share, "step": step})
                log(f"{name} serve {serve + 1} round {rnd}: rollouts {share:.3f} of {n}, "
                    f"record {target:.3f} of {n_rec}" + (f", shift {step:+.3f}" if
                                                         rnd < rounds else ""))
    return pd.DataFrame(rows)
