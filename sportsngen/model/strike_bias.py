"""A per-hitter shift of the strike head's odds of a rally ball long, wide or into the net.

The strike head reads the hitter only through the decoder's ball state. Teacher-forced on the
recorded rally strikes of the thirty-first part's bundled file (its training split and
`synthetic_named`, 125,865 strikes) it gives Williams' balls as server 0.113 odds of an error
(long, wide or into the net) against her record's 0.181, Isner's 0.112 against 0.188,
Sharapova's 0.110 against 0.133, while Djokovic's, Nadal's and Federer's are within 0.01 of
theirs (docs/evaluation.md, thirty-second part), and the rollouts draw what the head gives on
their own states. A match's rallies are as long as its players' errors let them be: that file's
rallies for Williams v Sharapova ran 4.6-5.3 shots against the truth's 3.7-4.0.
`ModelConfig.strike_bias` adds a table of logit shifts, per hitter identity and role (his own
service point or his opponent's), one added to the depth bins beyond the baseline, one to the
lateral bins outside the singles lines, one to the net-height bins wholly below the net;
`sportsngen.train.strike_bias` fits it, matching the head's mean odds of each on a hitter's
recorded strikes to his record's.

`ModelConfig.strike_width` adds a second table, per hitter and role, of a tilt of the lateral
bins inside the singles lines by the distance of each from the centre line: the head places
every player's balls in play about as wide as the average player's (teacher-forced on Djokovic v
Murray on clay a median 1.09-1.44 m from the centre line where their record's are 1.04-1.21,
while the generator's players differ from 1.15 m, Djokovic, to 1.41, Isner; docs/evaluation.md,
thirty-third part), and a rally is as long as the runs it asks for.

`ModelConfig.strike_pressure` adds one more table, per opponent and the hitter's role, of the
same three shifts on every rally strike but the return: how hard the ball the opponent sent is
to play. The generator's aim noise is the hitter's own times the opponent's rally pressure (and,
on the receiver's rally balls, the server's serve initiative), so the receivers' wide errors
after the return run 0.017-0.030 of their strikes for Djokovic v Murray and 0.039-0.063 for
Federer v Nadal, while the head with one row per hitter drew 0.04-0.07 for all four at the
record's states (docs/evaluation.md, thirty-eighth part).

`ModelConfig.strike_shape` adds two tables, per hitter and per opponent by the hitter's role,
of a tilt of the depth bins in play (by their depth) and of the net-height bins above the net
(by their height), on every strike but the return. The generator's reply to a ball is shorter,
higher and slower the harder that ball was (the opponent's rally pressure and, on the
receiver's balls, the server's serve initiative), and each player has his own depth margin;
teacher-forced on the training strikes the head's mean depth of the receivers' rally balls is
7.27-7.46 m whoever of the men sent the ball, while the record's runs from 6.78 m (against
Isner) to 7.52 (against Djokovic or Nadal). Measured on the bundled file, not bundled: the rallies
came nearer the truth's, the serve points won further (docs/evaluation.md, forty-third part).

`ModelConfig.strike_late` adds one more table, per hitter and role, of the same three shifts on
his strikes from the rally's `LATE_SHOT`th on (the return is the first). The head's input knows
the strike's number (`strike_shots`) and the hitter (`strike_players`), but not both at once:
in short rollouts from the record's states Federer's fourth and sixth balls were in play 0.795
and 0.866 of the time where his record's were 0.892 and 0.929, Nadal's fifth and seventh 0.805
and 0.771 against 0.761 and 0.694, and in whole rollouts Murray's balls from the fifth on erred
0.205 of the time where a 12,000-point truth's erred 0.161 (docs/evaluation.md, forty-seventh
part). Fitted on the record it moved the wrong way (the head at the record's own late states
errs less than the record; the rollouts' players arrive worse); `train.rollout_tables` moves it
by the model's own rollouts instead (docs/evaluation.md, forty-eighth part).

`ModelConfig.strike_return_surface` adds a table per surface and serve (first, second) of the
same three shifts on the returns. The generator's return faces the serve's heaviness, which a
surface passes on (clay less: `synth.behaviour.SURFACE_SERVE_WEIGHT`) and a second serve less;
the head draws a receiver's returns erring about alike on every surface and after either serve:
at the round robins' returns (the rollout's reading) it drew first serves' returns on clay
erring 0.184 where the record's erred 0.134, and second serves' on hard 0.097 against 0.136
(docs/evaluation.md, fifty-fifth part). `sportsngen.train.return_surface` fits it in turn with
the receivers' returns rows.

`ModelConfig.strike_depth` adds a table by where the ball is struck, not by whom: per band of
the contact's distance behind the hitter's baseline (`DEPTH_EDGES_M`) and his role, the same
three shifts on every strike but the return. In the generator a player far behind his baseline
defends (slower, safer, fewer errors) and one inside it attacks a short ball; at the record's
Djokovic v Murray clay strikes the record's late balls err 0.124 of the time from 2.3 m or more
behind the baseline and 0.173 from within 0.5 m of it, the head with every other table 0.153
and 0.159: flatter than the record. Its rollouts put more strikes far behind (27 % against
21 %), where they err 0.194 against the truth's 0.130 (docs/evaluation.md, forty-ninth part).
"""

from __future__ import annotations

import numpy as np
import torch

from sportsngen.model import strike
from sportsngen.tennis.court import BASELINE_X_M, SINGLES_HALF_WIDTH_M, net_height_m

LONG, WIDE, NET = 0, 1, 2      # the table's last axis: the kind of error
N_KINDS = 3
# The rows of the hitters' surfaces table (`ModelConfig.strike_surface`): his rally balls, his
# returns.
STROKE_RALLY, STROKE_RETURN = 0, 1
N_STROKES = 2
N_ROLES = 2                    # 0: the hitter serves this point; 1: he receives
DEPTH, HEIGHT = 0, 1           # the shape tables' last axis: which dimension is tilted
N_SHAPES = 2
LATE_SHOT = 5                  # the late table's first strike (1 the return)
# The depth table's band edges: the contact's |x| less the baseline's (m; negative inside the
# court). Seven bands: inside the court by more than a metre, then up to three metres behind
# the baseline in steps of 0.75 m, then beyond.
DEPTH_EDGES_M = (-1.0, 0.0, 0.75, 1.5, 2.25, 3.0)
N_DEPTH_BANDS = len(DEPTH_EDGES_M) + 1


def error_bins() -> np.ndarray:
    """(N_KINDS, STRIKE_BINS) bool: per kind the bins of its dimension (depth, lateral, net
    height; `strike.STRIKE_DIMS`) that make the ball an error: beyond the baseline, outside a
    singles line, wholly below the net's lowest height (its centre). The depth and lateral
    edges fall on the lines, so those bins are wholly in or out; a net-height bin above the
    centre's height may clear the net or not by where the ball crosses, and is left alone."""
    e = strike.strike_edges()
    depth, lateral, over_net = e[0], e[1], e[2]
    long = depth[:-1] >= BASELINE_X_M - 1e-9
    wide = (lateral[1:] <= -SINGLES_HALF_WIDTH_M + 1e-9) | \
        (lateral[:-1] >= SINGLES_HALF_WIDTH_M - 1e-9)
    net = over_net[1:] <= float(net_height_m(0.0)) + 1e-9
    return np.stack([long, wide, net])


_ERROR_BINS = error_bins()
# The width's tilt: one unit of shift adds this many logits per metre from the centre line.
WIDTH_UNIT_M = 1.0


def lateral_offsets_m() -> np.ndarray:
    """(STRIKE_BINS,) each lateral bin's centre's distance from the centre line (m)."""
    e = strike.strike_edges()[1]
    return np.abs(0.5 * (e[1:] + e[:-1]))


def width_tilt() -> np.ndarray:
    """(STRIKE_BINS,) the lateral bins' logit per unit of the width's shift: the bin centre's
    distance from the centre line less its mean over the bins in play (m / `WIDTH_UNIT_M`),
    zero on the bins outside the singles lines (the wide error's, `error_bins`), so the tilt
    moves the balls in play apart or together and barely their share."""
    off = lateral_offsets_m()
    inside = ~_ERROR_BINS[WIDE]
    return np.where(inside, off - off[inside].mean(), 0.0) / WIDTH_UNIT_M


_WIDTH_TILT = width_tilt()
_DIMS = (0, 1, 2)              # the strike dimension each kind shifts
# The shapes' tilts: one unit of shift adds this many logits per metre from the tilt's centre.
SHAPE_UNIT_M = 1.0
# Each tilt is centred on the training strikes' mean (in-play depth beyond the net, height over
# the net of the balls above it), where a strike's draws lie: centred on the bins' own mean
# (4.1 m over the net) a tilt of -2 per metre lifted the balls in play 5 logits against the
# net's bins, and the net's shift refitted with it ran into `MAX_SHIFT`.
DEPTH_CENTRE_M = 7.6
HEIGHT_CENTRE_M = 1.7


def _centred_tilt(dim: int, error: np.ndarray, centre_m: float) -> np.ndarray:
    e = strike.strike_edges()[dim]
    value = 0.5 * (e[1:] + e[:-1])
    return np.where(~error, value - centre_m, 0.0) / SHAPE_UNIT_M


def depth_tilt() -> np.ndarray:
    """(STRIKE_BINS,) the depth bins' logit per unit of the depth's shift: the bin centre's
    depth beyond the net less `DEPTH_CENTRE_M` (m / `SHAPE_UNIT_M`), zero on the bins beyond
    the baseline (the long error's), so the tilt moves the balls in play deeper or shorter."""
    return _centred_tilt(0, _ERROR_BINS[LONG], DEPTH_CENTRE_M)


def height_tilt() -> np.ndarray:
    """(STRIKE_BINS,) the net-height bins' logit per unit of the height's shift: the bin
    centre's height less `HEIGHT_CENTRE_M`, zero on the bins wholly below the net (the net
    error's), so the tilt moves the balls over the net higher or lower."""
    return _centred_tilt(2, _ERROR_BINS[NET], HEIGHT_CENTRE_M)


_SHAPE_TILTS = np.stack([depth_tilt(), height_tilt()])
_SHAPE_DIMS = (0, 2)           # the strike dimension each shape tilts


def depth_band(ball_x_m: torch.Tensor) -> torch.Tensor:
    """(N,) the ball's x where it is struck (m) -> (N,) int64 band of its distance behind the
    baseline (`DEPTH_EDGES_M`; 0 the deepest inside the court)."""
    edges = torch.as_tensor(DEPTH_EDGES_M, dtype=ball_x_m.dtype, device=ball_x_m.device)
    return torch.bucketize(ball_x_m.abs() - BASELINE_X_M, edges, right=True)


def strike_dim_bias(table: torch.Tensor, hitter_id: torch.Tensor, receiver: torch.Tensor,
                    width: torch.Tensor | None = None, returns: torch.Tensor | None = None,
                    returning: torch.Tensor | None = None,
                    pressure: torch.Tensor | None = None,
                    opponent_id: torch.Tensor | None = None,
                    shape: torch.Tensor | None = None,
                    shape_opponent: torch.Tensor | None = None,
                    late: torch.Tensor | None = None,
                    shot: torch.Tensor | None = None,
                    depth: torch.Tensor | None = None,
                    ball_x_m: torch.Tensor | None = None,
                    return_surface: torch.Tensor | None = None,
                    serve: torch.Tensor | None = None,
                    surface: torch.Tensor | None = None,
                    player_surface: torch.Tensor | None = None,
                    second: torch.Tensor | None = None) -> torch.Tensor:
    """The strike head's logit shifts for strikes of `hitter_id` (N,), who is the point's
    receiver where `receiver` (N,) bool, from `table` (n_ids, N_ROLES, N_KINDS) and the
    width's `width` (n_ids, N_ROLES) or None -> (N, 4, STRIKE_BINS): each kind's error bins
    shifted, the lateral bins in play tilted by the width, the spin's dimension left alone.
    With the returns' table `returns` (n_ids, N_KINDS) and `returning` (N,) bool (the strike
    is the return), its row is added to the returns' shifts. With the opponents' table
    `pressure` (n_ids, N_ROLES, N_KINDS) and `opponent_id` (N,) (who struck the ball now
    being answered), his row by the hitter's role is added on every strike but a return. With
    the shape tables `shape` and `shape_opponent` (n_ids, N_ROLES, N_SHAPES), the hitter's row
    and (with `opponent_id`) the opponent's tilt the depth and net-height bins
    (`depth_tilt`, `height_tilt`) on every strike but a return. With the late table `late`
    (n_ids, N_ROLES, N_KINDS) and `shot` (N,) (the strike's number, 1 the return), the hitter's
    row by role is added on the strikes numbered `LATE_SHOT` or more. With the depth table
    `depth` (N_DEPTH_BANDS, N_ROLES, N_KINDS) and `ball_x_m` (N,) (the ball's x where it is
    struck), its row by `depth_band` and the hitter's role is added on every strike but a
    return. With the surfaces' returns table `return_surface` (n_surfaces,
    `serve_bias.N_SERVES`, N_KINDS), `serve` (N,) (0 first, 1 second) and `surface` (N,)
    (the surfaces' indices), the row of the surface and serve is added on the returns. With
    the hitters' surfaces table `player_surface` (n_ids, n_surfaces, N_STROKES, N_KINDS) and
    `surface`, the hitter's row for the surface and stroke (`STROKE_RALLY`, or
    `STROKE_RETURN` where `returning`) is added on every strike. With the second serves'
    table `second` (n_ids, N_ROLES, N_KINDS) and `serve`, the hitter's row by role is added on
    every strike but the return of points whose serve is the second (`serve` 1)."""
    shift = table[hitter_id.long(), receiver.long()]                      # (N, N_KINDS)
    if late is not None and shot is not None:
        shift = shift + late[hitter_id.long(), receiver.long()] * \
            (shot >= LATE_SHOT).to(shift.dtype)[:, None]
    if returns is not None and returning is not None:
        shift = shift + returns[hitter_id.long()] * returning.to(shift.dtype)[:, None]
    if return_surface is not None and returning is not None and serve is not None \
            and surface is not None:
        shift = shift + return_surface[surface.long(), serve.long()] * \
            returning.to(shift.dtype)[:, None]
    if player_surface is not None and surface is not None:
        stroke = torch.zeros_like(hitter_id, dtype=torch.long) if returning is None \
            else returning.long() * STROKE_RETURN
        shift = shift + player_surface[hitter_id.long(), surface.long(), stroke]
    # The opponents' and depth tables add on every strike but a return.
    rally = torch.ones_like(shift[:, 0]) if returning is None else \
        (~returning.bool()).to(shift.dtype)
    if pressure is not None and opponent_id is not None:
        shift = shift + pressure[opponent_id.long(), receiver.long()] * rally[:, None]
    if second is not None and serve is not None:
        shift = shift + second[hitter_id.long(), receiver.long()] * \
            (rally * (serve == 1).to(shift.dtype))[:, None]
    if depth is not None and ball_x_m is not None:
        shift = shift + depth[depth_band(ball_x_m), receiver.long()] * rally[:, None]
    out = torch.zeros(len(hitter_id), 4, strike.STRIKE_BINS, dtype=table.dtype,
                      device=table.device)
    for kind, dim in enumerate(_DIMS):
        mask = torch.as_tensor(_ERROR_BINS[kind], dtype=table.dtype, device=table.device)
        out[:, dim] = shift[:, kind, None] * mask
    if width is not None:
        tilt = torch.as_tensor(_WIDTH_TILT, dtype=table.dtype, device=table.device)
        out[:, 1] += width[hitter_id.long(), receiver.long(), None] * tilt
    if shape is not None:
        out += shape_bias(shape, shape_opponent, hitter_id, receiver, returning, opponent_id)
    return out


def shape_bias(shape: torch.Tensor, shape_opponent: torch.Tensor | None,
               hitter_id: torch.Tensor, receiver: torch.Tensor,
               returning: torch.Tensor | None = None,
               opponent_id: torch.Tensor | None = None) -> torch.Tensor:
    """The shape tables' logit shifts (N, 4, STRIKE_BINS): per strike the hitter's row of
    `shape` by his role plus (with `opponent_id`) the opponent's row of `shape_opponent`,
    each unit a `depth_tilt` on the depth bins and a `height_tilt` on the net-height bins;
    zero on the returns (`returning`)."""
    r = receiver.long()
    units = shape[hitter_id.long(), r]                                    # (N, N_SHAPES)
    if shape_opponent is not None and opponent_id is not None:
        units = units + shape_opponent[opponent_id.long(), r]
    if returning is not None:
        units = units * (~returning.bool()).to(units.dtype)[:, None]
    tilts = torch.as_tensor(_SHAPE_TILTS, dtype=shape.dtype, device=shape.device)
    out = torch.zeros(len(hitter_id), 4, strike.STRIKE_BINS, dtype=shape.dtype,
                      device=shape.device)
    for k, dim in enumerate(_SHAPE_DIMS):
        out[:, dim] = units[:, k, None] * tilts[k]
    return out
