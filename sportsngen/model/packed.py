"""What the compiled kernels share: which inputs they take (`kernel_inputs`) and their weights
packed as numpy copies (`packed`), kept on the module and packed again only after they
change."""

from __future__ import annotations

from collections.abc import Callable

import torch


def kernel_inputs(*tensors: torch.Tensor | None) -> bool:
    """Whether tensors go to a numba kernel: each given one a float32 CPU tensor outside
    autograd, and no `torch.compile` tracing (dynamo cannot trace numba). Elsewhere (other
    devices, dtypes, training) the torch operations the kernels are tested against run."""
    # A loop and `is_cpu`, not all() over `device.type`: asked some 30 times a simulated
    # frame, the generator form was 2.4 % of a match (1.7 us a call against 0.5).
    for t in tensors:
        if t is not None and (t.dtype is not torch.float32 or not t.is_cpu or t.requires_grad):
            return False
    return not torch.compiler.is_compiling()


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
