"""The rally-end rules (`sportsngen.tennis.rally`) over recorded or simulated `RallyData`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.tennis.rally import MAX_RALLY_S, analyse_rallies


def analyse_rally_data(data, max_duration_s: float = MAX_RALLY_S) -> pd.DataFrame:
    """`analyse_rallies` over a `RallyData`, indexed by rally_id, with the rally's server_end,
    side and serve_number alongside."""
    arr = rally_arrays(data, Vocab.from_data(data, generic=True))
    n, t_max = len(arr), int(arr.length.max())
    pos = np.full((n, t_max, 3, 3), np.nan)
    cols = np.concatenate([np.arange(k) for k in arr.length])  # rows are packed in rally order
    pos[np.repeat(np.arange(n), arr.length), cols] = arr.pos_m
    r = data.rallies.set_index("rally_id").loc[arr.rally_id]
    out = analyse_rallies(pos, arr.length, r["server_end"].to_numpy(), r["side"].to_numpy(),
                          r["serve_number"].to_numpy(), data.fps, max_duration_s)
    out.insert(0, "rally_id", arr.rally_id)
    for col in ("serve_number", "side", "server_end"):
        out.insert(1, col, r[col].to_numpy())
    return out.set_index("rally_id")
