"""A per-server shift of the serve head's odds of a long and of a wide serve, and of its speed.

The serve head reads the server only through the decoder's ball state at the toss. Fitted on
every player's serves, it draws every named player's faults near the average player's: on the
serves it was fitted on, its mass beyond the service line on second serves is 0.043-0.089 for
every named server against records of 0.011-0.099, and four times each named player's serves
did not move it (docs/evaluation.md, twenty-fourth part). `ModelConfig.serve_bias` adds a
table of logit shifts, per player identity and serve (first, second), one added to the depth
bins beyond the service line, one to the lateral bins outside the box the serve is aimed at,
and a tilt of the speed bins; `sportsngen.train.serve_bias` fits it after the head, matching
the head's mean odds (and mean speed) on a server's recorded serves to his record's.

`ModelConfig.serve_aim` adds a second table, per player identity and serve, of a tilt of the
lateral bins inside the box the serve is aimed at by their distance toward its outer sideline
(`aim_tilt`), which `sportsngen.train.serve_bias.fit_serve_aim` fits on the states of the
model's own serves. Measured on the bundled file (11,997 serves from its own tosses), the head
already aims as the record there (2.06-2.11 m toward the sideline against 1.99-2.08; every
fitted tilt within 0.06 a metre; docs/evaluation.md, thirty-seventh part): an option, off.

`ModelConfig.serve_lateral` adds a third, per player identity and serve, of shifts of the
lateral bins inside the box by band (`lateral_bands`: seven bands of four bins from the centre
line to the sideline), which `sportsngen.train.serve_bias.fit_serve_lateral` fits on recorded
serves. A mean does not say where the serves go: the head, fitted on everyone's serves, drew
the big servers' first serves to the body (Federer's bands 2-4, 1.2-2.9 m from the centre line,
0.12 of his serves in the box against his record's 0.05) and too few out wide, where the aces
are (docs/evaluation.md, fifty-third part).
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.model import strike
from sportsngen.tennis.court import SERVICE_LINE_X_M, SINGLES_HALF_WIDTH_M

LONG, WIDE, SPEED = 0, 1, 2    # the table's last axis
N_KINDS = 3
N_SERVES = 2                   # first, second
# The speed's shift tilts its bins' logits by (centre - SPEED_REF_MPS) / SPEED_UNIT_MPS: an
# exponential tilt that moves the head's mean speed, one unit a logit per 10 m/s.
SPEED_REF_MPS = 40.0
SPEED_UNIT_MPS = 10.0


def long_fraction() -> np.ndarray:
    """(STRIKE_BINS,) the share of each serve depth bin beyond the service line (one bin
    straddles it: the edges fall on the baseline, not on the service line)."""
    e = strike.serve_edges()[0]
    return np.clip((e[1:] - SERVICE_LINE_X_M) / (e[1:] - e[:-1]), 0.0, 1.0)


def _centres(dim: int) -> np.ndarray:
    e = strike.serve_edges()[dim]
    return 0.5 * (e[1:] + e[:-1])


_LONG_BINS = long_fraction() > 0.5
# A serve landing this close to the net is in it at a second serve's pace: Williams' second
# serves drawn at her recorded tosses went into the net 0.077 of the time against her record's
# 0.023, all of the excess from serves drawn short of 4 m (16 % of the draws against 6 % of her
# serves; docs/evaluation.md, forty-second part). An edge of the depth bins.
SHORT_DEPTH_M = 3.9


def short_bins() -> np.ndarray:
    """(STRIKE_BINS,) bool: the serve depth bins wholly short of `SHORT_DEPTH_M`."""
    return strike.serve_edges()[0][1:] <= SHORT_DEPTH_M


_SHORT_BINS = short_bins()
_LATERAL_CENTRES_M = _centres(1)


def speed_centres_mps() -> np.ndarray:
    """(STRIKE_BINS,) the serve speed bins' centres (m/s)."""
    return _centres(2)


def speed_tilt() -> np.ndarray:
    """(STRIKE_BINS,) the speed bins' logit per unit of the speed's shift."""
    return (speed_centres_mps() - SPEED_REF_MPS) / SPEED_UNIT_MPS


_SPEED_TILT = speed_tilt()


def toward_sideline(contact_m, lateral_m):
    """Serves struck at `contact_m` (..., 3) with lateral `lateral_m` (...) (`SERVE_DIMS`, in
    the hitter's view) -> (...) their distance from the centre line toward the outer sideline
    of the box diagonally opposite (0-4.115 m inside it, negative in the other box). numpy or
    torch alike."""
    lib = torch if isinstance(contact_m, torch.Tensor) else np
    return lib.sign(contact_m[..., 1]) * lib.sign(contact_m[..., 0]) * lateral_m


def serve_wide(contact_m, lateral_m):
    """Serves struck at `contact_m` (..., 3) with lateral `lateral_m` (...) -> (...) bool:
    outside the box diagonally opposite, the other box included (`toward_sideline`). numpy or
    torch alike (`eval.serve_draws.serve_faults` reads faults with it)."""
    toward = toward_sideline(contact_m, lateral_m)
    return (toward < 0) | (toward > SINGLES_HALF_WIDTH_M)


def wide_bins(contact_m: torch.Tensor) -> torch.Tensor:
    """Serves struck at `contact_m` (N, 3) -> (N, STRIKE_BINS) bool: the lateral bins that put
    the serve wide (`serve_wide` at each bin's centre); the lateral edges fall on the centre
    and singles lines, so a bin is wholly in or out."""
    centre = torch.as_tensor(_LATERAL_CENTRES_M, dtype=contact_m.dtype, device=contact_m.device)
    return serve_wide(contact_m[:, None, :], centre)


def toward_sideline_m(contact_m: torch.Tensor) -> torch.Tensor:
    """Serves struck at `contact_m` (N, 3) -> (N, STRIKE_BINS): `toward_sideline` at each
    lateral bin's centre."""
    centre = torch.as_tensor(_LATERAL_CENTRES_M, dtype=contact_m.dtype, device=contact_m.device)
    return toward_sideline(contact_m[:, None, :], centre)


# The aim's tilt: one unit of shift adds a logit per metre toward the sideline, about the box's
# middle, so it moves serves in the box toward the sideline or the T and barely in or out.
AIM_MID_M = SINGLES_HALF_WIDTH_M / 2


def aim_tilt(contact_m: torch.Tensor) -> torch.Tensor:
    """Serves struck at `contact_m` (N, 3) -> (N, STRIKE_BINS): the lateral bins' logit per
    unit of the aim's shift, `toward_sideline_m` less `AIM_MID_M` inside the box aimed at, zero
    outside it (the wide bins, which `serve_bias`'s wide shift holds)."""
    toward = toward_sideline_m(contact_m)
    return torch.where(wide_bins(contact_m), torch.zeros_like(toward), toward - AIM_MID_M)


# The lateral bands' table (`lateral_bands`): the box's width toward its sideline in equal
# bands of four lateral bins (28 bins span a box), so no bin's centre falls on a band's edge.
N_LATERAL_BANDS = 7


def lateral_bands(contact_m: torch.Tensor) -> torch.Tensor:
    """Serves struck at `contact_m` (N, 3) -> (N, STRIKE_BINS) int64: each lateral bin's band
    inside the box aimed at (0 at the centre line to N_LATERAL_BANDS - 1 at the sideline, by
    its centre's `toward_sideline`), -1 outside it (the wide bins)."""
    toward = toward_sideline_m(contact_m)
    band = (toward / (SINGLES_HALF_WIDTH_M / N_LATERAL_BANDS)).floor().long()
    band = band.clamp(0, N_LATERAL_BANDS - 1)
    return torch.where(wide_bins(contact_m), torch.full_like(band, -1), band)


def lateral_shift(shifts: torch.Tensor, contact_m: torch.Tensor) -> torch.Tensor:
    """Per-serve band shifts `shifts` (N, N_LATERAL_BANDS) of serves struck at `contact_m`
    (N, 3) -> (N, STRIKE_BINS): each lateral bin's shift, zero on the wide bins."""
    band = lateral_bands(contact_m.to(shifts.dtype))
    got = shifts.gather(1, band.clamp(min=0))
    return torch.where(band >= 0, got, torch.zeros_like(got))


def serve_dim_bias(table: torch.Tensor, server_id: torch.Tensor, serve: torch.Tensor,
                   contact_m: torch.Tensor, aim: torch.Tensor | None = None,
                   short: torch.Tensor | None = None,
                   lateral: torch.Tensor | None = None) -> torch.Tensor:
    """The serve head's logit shifts for serves of `server_id` (N,) on serve `serve` (N,; 0
    first, 1 second) struck at `contact_m` (N, 3), from `table` (n_ids, N_SERVES, N_KINDS) ->
    (N, 4, STRIKE_BINS): the long depth bins and the wide lateral bins shifted, the speed bins
    tilted (`speed_tilt`), the spin's left alone; with the aim's table `aim` (n_ids,
    N_SERVES), the lateral bins in the box tilted too (`aim_tilt`); with the short serves'
    table `short` (n_ids, N_SERVES), the depth bins short of `SHORT_DEPTH_M` shifted too; with
    the lateral bands' table `lateral` (n_ids, N_SERVES, N_LATERAL_BANDS), each lateral bin
    in the box by its band's shift (`lateral_shift`)."""
    n = len(server_id)
    shift = table[server_id.long(), serve.long().clamp(0, N_SERVES - 1)]      # (N, N_KINDS)
    out = torch.zeros(n, 4, strike.STRIKE_BINS, dtype=table.dtype, device=table.device)
    long = torch.as_tensor(_LONG_BINS, device=table.device)
    out[:, 0] = shift[:, LONG, None] * long
    out[:, 1] = shift[:, WIDE, None] * wide_bins(contact_m.to(table.dtype))
    out[:, 2] = shift[:, SPEED, None] * torch.as_tensor(_SPEED_TILT, dtype=table.dtype,
                                                         device=table.device)
    if aim is not None:
        a = aim[server_id.long(), serve.long().clamp(0, N_SERVES - 1)]
        out[:, 1] += a[:, None] * aim_tilt(contact_m.to(table.dtype))
    if short is not None:
        s = short[server_id.long(), serve.long().clamp(0, N_SERVES - 1)]
        out[:, 0] += s[:, None] * torch.as_tensor(_SHORT_BINS, device=table.device)
    if lateral is not None:
        rows = lateral[server_id.long(), serve.long().clamp(0, N_SERVES - 1)]
        out[:, 1] += lateral_shift(rows, contact_m)
    return out
