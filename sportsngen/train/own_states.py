"""The serve head's states where the model's own rollouts put them, paired with the record's
serve: training targets for the states a simulation reaches.

A simulated point starts from a recorded toss's first frames (the model file's pool,
`sportsngen.data.serve_starts`) and the model plays the rest of the toss itself, so the decoder's
state at its serve is not the record's: on the bundled file's validation rallies its tosses
are struck up to 0.15 m higher than the recorded ones (whose contact the generator fixes per
player), and the serve head, which had only seen recorded tosses, faulted second serves 0.157
of the time there, 0.124 on the record's states, against the record's own 0.078; fitted on
both, 0.083 (docs/evaluation.md, twenty-first part). The generator draws a serve from the
server, the side and the serve number alone (`synth.behaviour.plan_serve`), so the recorded
serve of the same point is a draw of what the model should serve from its own toss: each
recorded rally is played once from the pool as a simulated point would be, and the state at
the model's own serve is paired with the record's serve bins (closed-loop training's idea,
with the record as the answer, for the one decision a serve head makes).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import RallyArrays, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.train.head_fit import HeadStates, collect_head_states

OWN_SERVE_S = 1.6       # a toss and its serve with frames to read the serve's label from


def _first(ids: np.ndarray) -> pd.Series:
    """Rally id -> position of its first entry in `ids`."""
    return pd.Series(np.arange(len(ids))).groupby(ids).first()


def own_serve_states(sim, data: RallyData, arrays: RallyArrays, seed: int = 0,
                     duration_s: float = OWN_SERVE_S, progress: bool = False,
                     record: HeadStates | None = None) -> tuple[HeadStates, HeadStates]:
    """The serve head's states at the recorded serves of `arrays` (rallies of `data`) and at
    the serves `sim` (a `Simulator`) plays from its own serve starts for the same points ->
    (record, own): `own` holds the decoder's states at the model's serves with the record's
    serve bins (rally ids the record's; rallies whose rollout struck no serve in `duration_s`
    are left out). `record`: those recorded states when already read (`collect_head_states`
    of `arrays`, turned windows after the rest), so they are not read twice."""
    from sportsngen.sim.assemble import PLAN_COLUMNS

    if record is None:
        record = collect_head_states(sim.model, arrays, "serve", progress=progress)
    first_rec = _first(record.rally_id)
    plan = data.rallies.set_index("rally_id").loc[first_rec.index].reset_index()
    played = sim.simulate_rallies(plan[PLAN_COLUMNS].copy(), seed=seed, progress=progress,
                                  max_duration_s=duration_s)
    states = collect_head_states(sim.model, rally_arrays(played, sim.vocab, unknown="generic"),
                                 "serve", progress=False)
    first_own = _first(states.rally_id)
    both = first_own.index.intersection(first_rec.index)
    o, r = first_own[both].to_numpy(), first_rec[both].to_numpy()
    own = HeadStates(states.h[o], record.bins[r], record.rally_id[r], record.serve[r],
                     states.contact_m[o], states.receiver[o], states.server_id[o])
    return record, own
