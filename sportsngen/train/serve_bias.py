"""Fit a model's per-server shifts of the serve head's odds of a long and a wide serve, and of
its speed.

`ModelConfig.serve_bias` (`sportsngen.model.serve_bias`) adds to the serve head's logits, per
server and serve, one shift on the depth bins beyond the service line, one on the lateral
bins outside the box and a tilt of the speed bins. Each is found here by matching: on a
server's recorded serves (the decoder's states read once,
`train.head_fit.collect_head_states`), the shift that makes the head's mean odds of a long (a
wide) serve, or its mean speed, equal his record's, pulled toward the head's own by
`prior_serves` pseudo-serves so that a player with few serves moves little. The wide odds are
read at the record's own depth bin and the speed at its depth and lateral bins, as the head's
teacher-forced loss reads them. Each rises monotonically with its shift, so a bisection finds
it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
import torch

from sportsngen.model import serve_bias
from sportsngen.model.decoder import SportsNGEN
from sportsngen.train.finetune import with_flag
from sportsngen.train.head_fit import HeadStates

MAX_SHIFT = 4.0          # logits: odds moved at most e^4 (a fault share 0.05 -> 0.74)
SHORT_ROUNDS = 6         # `fit_serve_short`'s rounds of the short and long shifts in turn


def with_serve_bias(model: SportsNGEN) -> SportsNGEN:
    """`model` with the per-server table added (`cfg.serve_bias`), at zero: it draws as
    before until `fit_serve_bias` fills it. -> a new model (the same one if it has it)."""
    return with_flag(model, "serve_bias", ["serve_bias"])


def mean_odds(logits: torch.Tensor, mask: torch.Tensor, weight: torch.Tensor,
          shift: torch.Tensor) -> torch.Tensor:
    """Mean over rows of sum_j softmax(logits + shift * mask)_j * weight_j, for each of the
    candidate shifts (S,) -> (S,): the odds of the bins `mask` weights (or with the speed's
    tilt as `mask` and the bins' speeds as `weight`, the mean speed)."""
    lg = logits[None] + shift[:, None, None] * mask[None].to(logits.dtype)
    return (lg.softmax(-1) * weight[None]).sum(-1).mean(-1)


def bisect_shift(odds_of, target: float, max_shift: float, rising: bool = True,
                 iters: int = 40) -> float:
    """The shift in [-max_shift, max_shift] at which `odds_of(shift)` (monotone: rising with
    the shift, or falling with `rising=False`) equals `target`, by bisection; the bound where
    the target lies beyond it. Shared by the per-player tables fitted by matching."""
    lo, hi = -max_shift, max_shift
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if (odds_of(mid) < target) == rising:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def solve_shift(logits: torch.Tensor, mask: torch.Tensor, weight: torch.Tensor,
           target: float) -> float:
    """The shift whose mean odds (`mean_odds`) equal `target` (they rise with the shift, and the
    mean speed with the tilt)."""
    if bool(((mask == 0) | (mask == 1)).all()):
        return bisect_shift(binary_mask_odds(logits, mask, weight), target, MAX_SHIFT)
    return bisect_shift(lambda s: float(mean_odds(logits, mask, weight, torch.tensor([s]))[0]),
                        target, MAX_SHIFT)


def binary_mask_odds(logits: torch.Tensor, mask: torch.Tensor,
                     weight: torch.Tensor) -> Callable[[float], float]:
    """`mean_odds` as a function of one shift, for a `mask` of zeros and ones: a shift s
    multiplies the masked bins' probabilities by e^s before the softmax's normalisation, so
    each row needs only four sums (the probability and the weighted probability on and off
    the mask), read once; a bisection's forty steps then cost O(rows), not a softmax over
    rows x bins each (float64). -> shift -> mean odds."""
    p = logits.to(torch.float64).softmax(-1)
    on = mask.to(torch.float64)
    pw = p * weight.to(torch.float64)
    p_on, pw_on = (p * on).sum(-1), (pw * on).sum(-1)
    p_off, pw_off = p.sum(-1) - p_on, pw.sum(-1) - pw_on
    p_on, pw_on, p_off, pw_off = (x.detach().numpy() for x in (p_on, pw_on, p_off, pw_off))

    def odds_of(shift: float) -> float:
        g = np.exp(shift)
        return float(((pw_off + g * pw_on) / (p_off + g * p_on)).mean())
    return odds_of


def share_logit(share, n):
    """Log-odds of a share of `n` counts (scalars or arrays), kept off 0 and 1 by half a count:
    the gap a table moves by when a share is read from rollouts or a record."""
    p = np.clip(share, 0.5 / np.asarray(n, dtype=float), 1.0 - 0.5 / np.asarray(n, dtype=float))
    return np.log(p / (1.0 - p))


def pulled_toward(record: float, head: float, n: int, prior: float) -> float:
    """A fit's target: the record's share over `n` rows pulled toward the head's own by
    `prior` pseudo-rows at the head's odds."""
    return (n * record + prior * head) / (n + prior)


def matched_shift(logits: torch.Tensor, mask: torch.Tensor, weight: torch.Tensor,
                  record: float, prior: float) -> dict:
    """One cell's fit: the shift whose mean odds over the rows of `logits` equal the record's
    `record` pulled toward the head's own by `prior` pseudo-rows. -> record, head (the odds
    before), target, after and shift."""
    n = len(logits)
    before = float(mean_odds(logits, mask, weight, torch.zeros(1))[0])
    target = pulled_toward(record, before, n, prior)
    shift = solve_shift(logits, mask, weight, target)
    after = float(mean_odds(logits, mask, weight, torch.tensor([shift]))[0])
    return {"record": record, "head": before, "target": target, "after": after, "shift": shift}


def _check_fit(table: torch.Tensor | None, what: str, adder: str, prior_serves: float,
               min_serves: int) -> None:
    """A fit's arguments: the model has the table it fills, and sensible counts."""
    if table is None:
        raise ValueError(f"the model has no {what}: add it with {adder}")
    if prior_serves < 0 or min_serves < 1:
        raise ValueError("prior_serves must be >= 0 and min_serves >= 1")


@torch.no_grad()
def fit_serve_bias(model: SportsNGEN, states: HeadStates, prior_serves: float = 100.0,
                   min_serves: int = 20) -> pd.DataFrame:
    """Fill `model.serve_bias` (in place) from the recorded serves `states`, per server and
    serve with at least `min_serves` serves (others keep 0). -> per (server_id, serve): n,
    the record's long and wide shares and mean speed (m/s), the head's before and after, and
    the shifts."""
    _check_fit(model.serve_bias, "per-server table (cfg.serve_bias)", "with_serve_bias",
               prior_serves, min_serves)
    head = model.serve_head
    long_w = torch.as_tensor(serve_bias.long_fraction(), dtype=states.h.dtype)
    long_mask = long_w > 0.5
    speed_mps = torch.as_tensor(serve_bias.speed_centres_mps(), dtype=states.h.dtype)
    tilt = torch.as_tensor(serve_bias.speed_tilt(), dtype=states.h.dtype)
    contact = torch.as_tensor(states.contact_m, dtype=states.h.dtype)
    rows = []
    keys = pd.DataFrame({"server_id": states.server_id, "serve": states.serve})
    for (sid, srv), g in keys.groupby(["server_id", "serve"]):
        if len(g) < min_serves or not 0 <= srv < serve_bias.N_SERVES:
            continue
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        h, bins = states.h[i], states.bins[i]
        n = len(i)
        depth = head.dim_logits(h, bins, 0)
        wide = serve_bias.wide_bins(contact[i])
        lateral = head.dim_logits(h, bins, 1)
        speed = head.dim_logits(h, bins, 2)
        rec = {"long": float(long_w[bins[:, 0]].mean()),
               "wide": float(wide[torch.arange(n), bins[:, 1]].float().mean()),
               "speed": float(speed_mps[bins[:, 2]].mean())}
        row = {"server_id": int(sid), "serve": int(srv), "n": n}
        for kind, k, logits, mask, weight in (
                ("long", serve_bias.LONG, depth, long_mask.expand(n, -1), long_w.expand(n, -1)),
                ("wide", serve_bias.WIDE, lateral, wide, wide.to(h.dtype)),
                ("speed", serve_bias.SPEED, speed, tilt.expand(n, -1),
                 speed_mps.expand(n, -1))):
            fit = matched_shift(logits, mask, weight, rec[kind], prior_serves)
            model.serve_bias[int(sid), int(srv), k] = fit["shift"]
            row.update({f"{kind}_{name}": v for name, v in fit.items()})
        rows.append(row)
    return pd.DataFrame(rows)


def with_serve_aim(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the serve table) with the aim's table added (`cfg.serve_aim`), at zero: it
    draws as before until `fit_serve_aim` fills it. -> a new model."""
    if model.serve_bias is None:
        raise ValueError("the aim is read with the serve head's table (cfg.serve_bias): fit it "
                         "first (scripts/fit_serve_bias.py)")
    return with_flag(model, "serve_aim", ["serve_aim"])


def _mean_toward(logits: torch.Tensor, toward: torch.Tensor, inside: torch.Tensor,
                 tilt: torch.Tensor, shift: float) -> float:
    """Mean over rows of the head's mean distance toward the sideline of its lateral draws
    inside the box, with the aim's `shift`."""
    p = (logits + shift * tilt).softmax(-1) * inside
    return float(((p * toward).sum(-1) / p.sum(-1).clamp_min(1e-12)).mean())


@torch.no_grad()
def fit_serve_aim(model: SportsNGEN, states: HeadStates, prior_serves: float = 100.0,
                  min_serves: int = 20) -> pd.DataFrame:
    """Fill `model.serve_aim` (in place) from serve states paired with recorded serves
    (`train.own_states.own_serve_states`: the model's own tosses, the record's serve of the same
    point), per server and serve with at least `min_serves` recorded serves in the box: the
    tilt whose mean distance toward the sideline of the head's draws in the box (read at the
    record's depth bin, on the serves the record put in the box) equals the record's, pulled
    toward the head's own by `prior_serves` pseudo-serves (it rises with the tilt, so a
    bisection finds it); then the wide shift refitted so the head's odds of a wide serve over
    all his serves stay what they were (the tilt moves a little mass across the lines). ->
    per (server_id, serve): n, the record's, the head's before and after mean distances (m),
    the tilt, the wide odds and the wide shift after."""
    if model.serve_aim is None:
        raise ValueError("the model has no per-server aim (cfg.serve_aim): add it with "
                         "with_serve_aim")
    head = model.serve_head
    contact = torch.as_tensor(states.contact_m, dtype=states.h.dtype)
    keys = pd.DataFrame({"server_id": states.server_id, "serve": states.serve})
    rows = []
    for (sid, srv), g in keys.groupby(["server_id", "serve"]):
        if not 0 <= srv < serve_bias.N_SERVES:
            continue
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        h, bins, c = states.h[i], states.bins[i], contact[i]
        n_all = len(i)
        raw = head.dim_logits(h, bins, 1)
        wide = serve_bias.wide_bins(c)
        inside = ~wide
        toward = serve_bias.toward_sideline_m(c)
        tilt = serve_bias.aim_tilt(c)
        rows_i = torch.arange(n_all)
        in_box = inside[rows_i, bins[:, 1]] & \
            ~torch.as_tensor(serve_bias.long_fraction() > 0.5)[bins[:, 0]]
        n = int(in_box.sum())
        if n < min_serves:
            continue
        # The table's shifts touch only the wide bins of this dimension: the draws inside the
        # box read the head's own logits.
        box = raw[in_box]
        box_args = (toward[in_box], inside[in_box].to(h.dtype), tilt[in_box])
        record = float(toward[rows_i, bins[:, 1]][in_box].mean())
        before = _mean_toward(box, *box_args, 0.0)
        target = pulled_toward(record, before, n, prior_serves)
        aim = bisect_shift(lambda s, lg=box, a=box_args: _mean_toward(lg, *a, s), target,
                           MAX_SHIFT)
        model.serve_aim[int(sid), int(srv)] = aim
        w0 = float(model.serve_bias[int(sid), int(srv), serve_bias.WIDE])
        wide_before = float(mean_odds(raw + w0 * wide, wide, wide.to(h.dtype),
                                      torch.zeros(1))[0])
        fit = matched_shift(raw + aim * tilt, wide, wide.to(h.dtype), wide_before, 0.0)
        model.serve_bias[int(sid), int(srv), serve_bias.WIDE] = fit["shift"]
        rows.append({"server_id": int(sid), "serve": int(srv), "n": n,
                     "toward_record_m": record, "toward_head_m": before,
                     "toward_after_m": _mean_toward(box, *box_args, aim), "aim": aim,
                     "wide_odds": wide_before, "wide_after": fit["after"],
                     "wide_shift": fit["shift"]})
    return pd.DataFrame(rows)


def with_serve_short(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the serve table) with the short serves' table added (`cfg.serve_short`),
    at zero: it draws as before until `fit_serve_short` fills it. -> a new model."""
    if model.serve_bias is None:
        raise ValueError("the short serves' shift is read with the serve head's table "
                         "(cfg.serve_bias): fit it first (scripts/fit_serve_bias.py)")
    return with_flag(model, "serve_short", ["serve_short"])


@torch.no_grad()
def fit_serve_short(model: SportsNGEN, states: HeadStates, prior_serves: float = 100.0,
                    min_serves: int = 20) -> pd.DataFrame:
    """Fill `model.serve_short` (in place) from the recorded serves `states`, per server and
    serve with at least `min_serves` serves: the shift of the depth bins short of
    `serve_bias.SHORT_DEPTH_M` whose mean odds equal his record's share of serves that short,
    pulled toward the head's own by `prior_serves` pseudo-serves, found in turn with his long
    shift refitted to the target `fit_serve_bias` gives it (each moves the other's share a
    little; `SHORT_ROUNDS` rounds). -> per (server_id, serve): n, the record's short share,
    the head's before, the target, after, the shift, and the long share's target, odds after
    and shift."""
    _check_fit(model.serve_short, "short serves' table (cfg.serve_short)", "with_serve_short",
               prior_serves, min_serves)
    head = model.serve_head
    dtype = states.h.dtype
    short = torch.as_tensor(serve_bias.short_bins())
    long_w = torch.as_tensor(serve_bias.long_fraction(), dtype=dtype)
    long_mask = long_w > 0.5
    keys = pd.DataFrame({"server_id": states.server_id, "serve": states.serve})
    rows = []
    for (sid, srv), g in keys.groupby(["server_id", "serve"]):
        if len(g) < min_serves or not 0 <= srv < serve_bias.N_SERVES:
            continue
        sid, srv = int(sid), int(srv)
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        n = len(i)
        depth = head.dim_logits(states.h[i], states.bins[i], 0)
        record = float(short[states.bins[i, 0]].float().mean())
        short_head = float(mean_odds(depth, short, short.to(dtype), torch.zeros(1))[0])
        short_target = pulled_toward(record, short_head, n, prior_serves)
        long_record = float(long_w[states.bins[i, 0]].mean())
        long_head = float(mean_odds(depth, long_mask, long_w, torch.zeros(1))[0])
        long_target = pulled_toward(long_record, long_head, n, prior_serves)
        # Each shift moves the other's share a little (the softmax's sum): a few rounds in turn
        # bring both to their targets.
        long_shift = float(model.serve_bias[sid, srv, serve_bias.LONG])
        for _ in range(SHORT_ROUNDS):
            short_shift = solve_shift(depth + long_shift * long_mask, short.expand(n, -1),
                                      short.to(dtype).expand(n, -1), short_target)
            long_shift = solve_shift(depth + short_shift * short, long_mask.expand(n, -1),
                                     long_w.expand(n, -1), long_target)
        model.serve_short[sid, srv] = short_shift
        model.serve_bias[sid, srv, serve_bias.LONG] = long_shift
        both = depth + short_shift * short + long_shift * long_mask
        rows.append({"server_id": sid, "serve": srv, "n": n, "short_record": record,
                     "short_head": short_head, "short_target": short_target,
                     "short_after": float(mean_odds(both, short, short.to(dtype),
                                                    torch.zeros(1))[0]),
                     "short_shift": short_shift, "long_target": long_target,
                     "long_after": float(mean_odds(both, long_mask, long_w,
                                                   torch.zeros(1))[0]),
                     "long_shift": long_shift})
    return pd.DataFrame(rows)


LATERAL_ROUNDS = 200     # `fit_serve_lateral`'s rounds of matching the bands' shares
LATERAL_MIN_SHARE = 1e-4  # the least share a band is matched to


def with_serve_lateral(model: SportsNGEN) -> SportsNGEN:
    """`model` (with the serve table) with the lateral bands' table added
    (`cfg.serve_lateral`), at zero: it draws as before until `fit_serve_lateral` fills it.
    -> a new model."""
    if model.serve_bias is None:
        raise ValueError("the lateral bands' shift is read with the serve head's table "
                         "(cfg.serve_bias): fit it first (scripts/fit_serve_bias.py)")
    return with_flag(model, "serve_lateral", ["serve_lateral"])


def _band_shares(logits: torch.Tensor, band: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """Mean over rows of the odds of each band given a serve in the box: `logits` (N, bins)
    with each bin in band b (`band` (N, bins), -1 wide) shifted by `shift[b]` -> (bands,)."""
    inside = band >= 0
    lg = logits + torch.where(inside, shift[band.clamp(min=0)], torch.zeros_like(logits))
    p = lg.softmax(-1) * inside
    mass = torch.zeros(len(p), len(shift), dtype=p.dtype).scatter_add_(1, band.clamp(min=0), p)
    return (mass / mass.sum(1, keepdim=True).clamp(min=1e-12)).mean(0)


@torch.no_grad()
def fit_serve_lateral(model: SportsNGEN, states: HeadStates, prior_serves: float = 100.0,
                      min_serves: int = 50) -> pd.DataFrame:
    """Fill `model.serve_lateral` (in place) from the recorded serves `states`, per server and
    serve with at least `min_serves` serves the record put in the box: the band shifts whose
    head's odds of each band, given a serve in the box (read at the record's depth bin, on the
    serves the record put in the box), equal his record's shares, pulled toward the head's own
    by `prior_serves` pseudo-serves and none below `LATERAL_MIN_SHARE` (matched in
    `LATERAL_ROUNDS` rounds of log-ratio steps, the shifts centred); then his wide shift
    refitted so the head's odds of a wide serve over all his serves stay what they were. -> per
    (server_id, serve, band): n, the record's share, the head's before and after, and the
    band's shift."""
    _check_fit(model.serve_lateral, "lateral bands' table (cfg.serve_lateral)",
               "with_serve_lateral", prior_serves, min_serves)
    head = model.serve_head
    dtype = states.h.dtype
    contact = torch.as_tensor(states.contact_m, dtype=dtype)
    long_bins = torch.as_tensor(serve_bias.long_fraction() > 0.5)
    keys = pd.DataFrame({"server_id": states.server_id, "serve": states.serve})
    rows = []
    for (sid, srv), g in keys.groupby(["server_id", "serve"]):
        if not 0 <= srv < serve_bias.N_SERVES:
            continue
        sid, srv = int(sid), int(srv)
        i = torch.as_tensor(g.index.to_numpy(copy=True))
        h, bins, c = states.h[i], states.bins[i], contact[i]
        band = serve_bias.lateral_bands(c)
        rec_band = band[torch.arange(len(i)), bins[:, 1]]
        in_box = (rec_band >= 0) & ~long_bins[bins[:, 0]]
        n = int(in_box.sum())
        if n < min_serves:
            continue
        was = model.serve_lateral[sid, srv].clone()
        model.serve_lateral[sid, srv] = 0.0
        ids = torch.full((len(i),), sid)
        serve = torch.full((len(i),), srv)
        base = head.dim_logits(h, bins, 1) + serve_bias.serve_dim_bias(
            model.serve_bias, ids, serve, c, model.serve_aim, model.serve_short)[:, 1]
        wide = serve_bias.wide_bins(c)
        # The odds of a wide serve the file draws now, with the bands it has (none on a first
        # fit). Read without them, a refit matched the wide shift the last fit had already
        # moved, and moved it again: run twice on the bundled file, Murray's first serves' wide
        # shift went 0.79 -> 1.25 and his first serves in 7 points down (docs/evaluation.md,
        # seventy-second part).
        drawn = base + serve_bias.lateral_shift(was.expand(len(i), -1), c)
        wide_before = float(mean_odds(drawn, wide, wide.to(dtype), torch.zeros(1))[0])
        lg, bd = base[in_box], band[in_box]
        k = serve_bias.N_LATERAL_BANDS
        record = torch.bincount(rec_band[in_box], minlength=k).to(dtype) / n
        shift = torch.zeros(k, dtype=dtype)
        before = _band_shares(lg, bd, shift)
        target = (n * record + prior_serves * before) / (n + prior_serves)
        # A band the record never served to is held at `LATERAL_MIN_SHARE`, not driven to
        # minus infinity; the steps are not bounded on the way (a bound on some bands stops
        # the others' ratios from being matched), the shifts centred at the end.
        target = target.clamp(min=LATERAL_MIN_SHARE)
        target = target / target.sum()
        for _ in range(LATERAL_ROUNDS):
            shift = shift + torch.log(target / _band_shares(lg, bd, shift).clamp(min=1e-12))
        shift = shift - shift.mean()
        after = _band_shares(lg, bd, shift)
        model.serve_lateral[sid, srv] = shift
        w0 = float(model.serve_bias[sid, srv, serve_bias.WIDE])
        moved = base - w0 * wide + serve_bias.lateral_shift(shift.expand(len(i), -1), c)
        fit = matched_shift(moved, wide, wide.to(dtype), wide_before, 0.0)
        model.serve_bias[sid, srv, serve_bias.WIDE] = fit["shift"]
        for b in range(k):
            rows.append({"server_id": sid, "serve": srv, "band": b, "n": n,
                         "record": float(record[b]), "head": float(before[b]),
                         "after": float(after[b]), "shift": float(shift[b]),
                         "wide_odds": wide_before, "wide_after": fit["after"]})
    return pd.DataFrame(rows)
