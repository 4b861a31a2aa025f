"""Training: Lightning modules and data module, fine-tuning, the `train.py` driver.

The Lightning classes are imported on first use (PEP 562), so a submodule of plain torch
(`train.metrics`, the table fits) does not pull Lightning in: `import sportsngen.eval.diagnostics`
took 6.1 s with it, Lightning alone about 5 s of that."""

from __future__ import annotations

import importlib

_WHERE = {"DecoderModule": "module", "EventModule": "module",
          "TrackingDataModule": "datamodule", "load_rally_data": "datamodule"}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f"sportsngen.train.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
