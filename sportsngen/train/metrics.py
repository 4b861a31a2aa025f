"""Next-frame metrics of the decoder f, as sums over tokens (exact per-frame means over a whole
validation set, and across DDP ranks once the sums are all-reduced).

Per object kind: the model's NLL (nats per object token, summed over the dimensions of its bin)
and top-1 bin accuracy; for the ball also split into frames in flight and frames at racket
contact (`near_contact`: within one frame of a shot in the shots table), where a
constant-velocity guess is worst. Two references on the same tokens:

- the constant-velocity predictor: independent Gaussians per dimension centred on
  ``pos + vel / fps``, discretised onto the model's bins, with each dimension's standard
  deviation picked from `CV_SIGMAS_M` to minimise its NLL over the whole set (fitted in sample,
  so the comparison favours the reference);
- its top-1: the bin that holds the constant-velocity extrapolation.
"""

from __future__ import annotations

import math

import torch

from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL, object_features
from sportsngen.train.windows import check_finite

CV_SIGMAS_M = torch.logspace(-3.5, 0.5, 25, dtype=torch.float64)
PARTS = ("player", "flight", "contact")  # player tokens; ball tokens in flight / at contact
_SCALARS = ("n", "nll", "hit", "cv_hit")
_DIMS = {"player": 2, "flight": 3, "contact": 3}


def window_states(model: SportsNGEN, batch: dict) -> torch.Tensor:
    """The decoder's output states (B, T, 3, d) for a collated batch of `WindowDataset` items
    (raises naming the rally on NaN)."""
    check_finite(batch)
    feats = object_features(batch["pos_m"], batch["vel_mps"], batch["t_s"])
    ctx = model.context_tokens(batch["surface"], batch["tournament"], batch["serve"],
                               batch["score"])
    return model(feats, batch["ident"], ctx)


class NextFrameMetrics:
    """Accumulates token sums over batches; `compute()` turns them into per-token means.

    `vector()` / `from_vector()` flatten the sums into one float64 tensor, for an all-reduce.
    """

    def __init__(self) -> None:
        self.sums: dict[str, torch.Tensor] = {}
        for p in PARTS:
            for s in _SCALARS:
                self.sums[f"{s}_{p}"] = torch.zeros((), dtype=torch.float64)
            self.sums[f"cv_{p}"] = torch.zeros(len(CV_SIGMAS_M), _DIMS[p], dtype=torch.float64)
        for p in PARTS[1:]:     # the ball's sub-bin head, where the model has one
            self.sums[f"sub_{p}"] = torch.zeros((), dtype=torch.float64)
        for k in ("n_strike", "nll_strike", "n_serve", "nll_serve"):   # strike and serve heads
            self.sums[k] = torch.zeros((), dtype=torch.float64)

    def _add(self, part: str, nll: torch.Tensor, hit: torch.Tensor, cv_hit: torch.Tensor,
             bins, off: torch.Tensor, cv_mean: torch.Tensor) -> None:
        """One part's selected tokens: nll (N,), hit (N,), cv_hit (N,), off/cv_mean (N, dims)."""
        s = self.sums
        s[f"n_{part}"] += nll.numel()
        s[f"nll_{part}"] += nll.double().sum().cpu()
        s[f"hit_{part}"] += hit.double().sum().cpu()
        s[f"cv_hit_{part}"] += cv_hit.double().sum().cpu()
        if nll.numel():
            sig = CV_SIGMAS_M.to(off.device, off.dtype)[:, None, None].expand(-1, 1, off.shape[-1])
            s[f"cv_{part}"] += bins.gaussian_nll(off, cv_mean, sig).double().sum(dim=1).cpu()

    @torch.no_grad()
    def update(self, model: SportsNGEN, batch: dict, h: torch.Tensor | None = None) -> None:
        """Add one batch (a `WindowDataset` collate; `h` the decoder's output if computed)."""
        cfg = model.cfg
        if h is None:
            h = window_states(model, batch)
        pos, vel, nxt = batch["pos_m"], batch["vel_mps"], batch["next_pos_m"]
        prev = batch.get("prev_vel_mps")
        centre = model.centres(pos, vel, prev)
        off = model.to_model_frame(nxt - centre, pos)          # the frame the bins are in
        p_idx, b_idx = model.offset_bins(off)
        p_nll, b_nll = model.nll(h, p_idx, b_idx)
        p_top = model.player_head.top1(h[..., :BALL, :])
        b_top = model.ball_head.top1(h[..., BALL, :])
        cv_mean = model.to_model_frame(pos + vel / cfg.fps - centre, pos)
        m = batch["has_next"].bool()
        near = batch["near_contact"].bool()
        pb, bb = model.player_bins, model.ball_bins
        p_off, p_cv = off[..., :BALL, :2][m], cv_mean[..., :BALL, :2][m]
        self._add("player", p_nll[m].flatten(), (p_top == p_idx).all(-1)[m].flatten(),
                  (pb.index(p_cv) == p_idx[m]).all(-1).flatten(), pb,
                  p_off.reshape(-1, 2), p_cv.reshape(-1, 2))
        sub = model.ball_sub_nll(h, off, b_idx)
        if model.strike_head is not None:
            s_mask, s_bins = model.strike_targets(pos, vel, nxt, batch["has_next"])
            self.sums["n_strike"] += float(s_mask.sum())
            nll = model.strike_nll(h, s_mask, s_bins, pos, batch["serve"])
            self.sums["nll_strike"] += nll.double().sum().cpu()
        if model.serve_head is not None:
            s_mask, s_bins = model.strike_targets(pos, vel, nxt, batch["has_next"], serves=True)
            self.sums["n_serve"] += float(s_mask.sum())
            self.sums["nll_serve"] += model.serve_nll(h, s_mask, s_bins).double().sum().cpu()
        for part, sel in (("flight", m & ~near), ("contact", m & near)):
            self.sums[f"sub_{part}"] += sub[sel].double().sum().cpu()
            b_cv = cv_mean[..., BALL, :][sel]
            self._add(part, b_nll[sel], (b_top == b_idx).all(-1)[sel],
                      (bb.index(b_cv) == b_idx[sel]).all(-1), bb, off[..., BALL, :][sel], b_cv)

    def vector(self) -> torch.Tensor:
        return torch.cat([v.reshape(-1) for v in self.sums.values()])

    def from_vector(self, vec: torch.Tensor) -> NextFrameMetrics:
        """A copy whose sums are read back from `vector()`'s layout (e.g. after all-reduce)."""
        out = NextFrameMetrics()
        i = 0
        for k, v in self.sums.items():
            out.sums[k] = vec[i:i + v.numel()].reshape(v.shape).double().cpu()
            i += v.numel()
        return out

    def compute(self) -> dict[str, float]:
        """Per-token means (NaN where a part has no token); `loss` is the training loss's
        per-object-token mean (2 players and 1 ball a frame)."""
        s = self.sums

        def ratio(num: torch.Tensor, den: torch.Tensor) -> float:
            return float(num / den) if float(den) > 0 else math.nan

        n_ball = s["n_flight"] + s["n_contact"]
        out = {"n_player_tokens": float(s["n_player"]), "n_ball_flight": float(s["n_flight"]),
               "n_ball_contact": float(s["n_contact"])}
        out["nll_player"] = ratio(s["nll_player"], s["n_player"])
        out["nll_ball"] = ratio(s["nll_flight"] + s["nll_contact"], n_ball)
        out["acc_player"] = ratio(s["hit_player"], s["n_player"])
        out["acc_ball"] = ratio(s["hit_flight"] + s["hit_contact"], n_ball)
        out["cv_acc_player"] = ratio(s["cv_hit_player"], s["n_player"])
        out["cv_acc_ball"] = ratio(s["cv_hit_flight"] + s["cv_hit_contact"], n_ball)
        # One CV predictor per kind: each dimension's sigma fitted on all of that kind's tokens.
        best_p = s["cv_player"].argmin(dim=0)
        out["cv_nll_player"] = ratio(s["cv_player"].gather(0, best_p[None]).sum(), s["n_player"])
        cv_ball = s["cv_flight"] + s["cv_contact"]
        best_b = cv_ball.argmin(dim=0)[None]
        out["cv_nll_ball"] = ratio(cv_ball.gather(0, best_b).sum(), n_ball)
        for part in ("flight", "contact"):
            n = s[f"n_{part}"]
            out[f"nll_ball_{part}"] = ratio(s[f"nll_{part}"], n)
            out[f"acc_ball_{part}"] = ratio(s[f"hit_{part}"], n)
            out[f"cv_acc_ball_{part}"] = ratio(s[f"cv_hit_{part}"], n)
            out[f"cv_nll_ball_{part}"] = ratio(s[f"cv_{part}"].gather(0, best_b).sum(), n)
            # NLL of where inside its bins the ball lies (0 without a sub-bin head; uniform
            # parts would score 3 ln(ball_sub_bins)): not part of `loss`, which stays at the
            # bins' resolution so models with and without the head compare.
            out[f"sub_nll_ball_{part}"] = ratio(s[f"sub_{part}"], n)
        # The strike head's NLL per strike (its four dimensions' bins; NaN without one), apart
        # from `loss` like the sub-bin head's.
        out["strike_nll"] = ratio(s["nll_strike"], s["n_strike"])
        out["n_strikes"] = float(s["n_strike"])
        out["serve_nll"] = ratio(s["nll_serve"], s["n_serve"])    # the serve head's, likewise
        out["n_serves"] = float(s["n_serve"])
        out["cv_sigma_player_m"] = [float(CV_SIGMAS_M[i]) for i in best_p]
        out["cv_sigma_ball_m"] = [float(CV_SIGMAS_M[i]) for i in best_b[0]]
        out["loss"] = (2 * out["nll_player"] + out["nll_ball"]) / 3.0
        return out


@torch.no_grad()
def evaluate_windows(model: SportsNGEN, loader) -> dict[str, float]:
    """`NextFrameMetrics` of `model` (eval mode) over every batch of `loader`."""
    was_training = model.training
    model.eval()
    metrics = NextFrameMetrics()
    device = next(model.parameters()).device
    for batch in loader:
        batch = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in batch.items()}
        check_finite(batch)
        metrics.update(model, batch)
    model.train(was_training)
    return metrics.compute()
