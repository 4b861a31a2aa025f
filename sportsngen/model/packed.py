"""Weights packed for the compiled kernels (`head_kernel`, `step_kernel`), kept on the module
and packed again only after they change."""

from __future__ import annotations

from collections.abc import Callable

import torch


def packed(module: torch.nn.Module, pack: Callable[[], tuple],
           *also: torch.nn.Module) -> tuple:
    """`pack()` (numpy copies of the weights of `module` and of the modules `also`), cached
    on `module` until one of them changes: fine-tuning updates them in place (their version
    counters move) and moving the model gives them new storage (their data pointers move).
    The parameters are listed once, at the first call."""
    weights = module.__dict__.get("_packed_weights")
    if weights is None:
        weights = module.__dict__["_packed_weights"] = \
            [w for m in (module, *also) for w in m.parameters()]
    key = tuple((w.data_ptr(), w._version) for w in weights)
    cached = module.__dict__.get("_packed_cache")
    if cached is None or cached[0] != key:
        cached = module.__dict__["_packed_cache"] = (key, pack())
    return cached[1]
