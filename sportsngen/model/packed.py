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
    return not torch.compiler.is_compiling() and all(
        t.device.type == "cpu" and t.dtype == torch.float32 and not t.requires_grad
        for t in tensors if t is not None)


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
