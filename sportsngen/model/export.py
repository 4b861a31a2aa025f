"""A self-contained model file: weights + config + vocabularies, loadable without Hydra.

`save_model(path, model, vocab, event_classifier=None)` writes one `torch.save` file of plain
types (dicts, lists, tensors), so `load_model` reads it with `weights_only=True`.
"""

from __future__ import annotations

import copy
import os
from collections import OrderedDict
from pathlib import Path

import torch

from sportsngen.data.tokens import Vocab
from sportsngen.errors import ModelFileError
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.event_classifier import EventClassifier

FORMAT = "sportsngen-model"
VERSION = 1
# Files read lately, by (path, inode, size, modification time, map_location): the bundled
# file's 42,000 small objects of initial conditions take 0.27 s to unpickle with weights_only
# and 0.02 s to copy, and a study or a test run reads the same file dozens of times.
_READ_CACHE: OrderedDict[tuple, dict] = OrderedDict()
_READ_CACHE_FILES = 4


def save_model(path: str | Path, model: SportsNGEN, vocab: Vocab,
               event_classifier: EventClassifier | None = None, extra: dict | None = None) -> Path:
    """Write the decoder (and optionally the event classifier) with config and vocab."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if model.cfg.n_ids != vocab.n_ids and not model.cfg.generic_identity:
        raise ValueError(f"model has {model.cfg.n_ids} identities but the vocab {vocab.n_ids}")
    blob = {
        "format": FORMAT, "version": VERSION, "config": model.cfg.to_dict(),
        "vocab": vocab.to_dict(),
        "decoder": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "event_classifier": None if event_classifier is None else
        {k: v.detach().cpu() for k, v in event_classifier.state_dict().items()},
        "extra": _plain(dict(extra or {})),
    }
    torch.save(blob, path)
    return path


def _plain(value):
    """numpy arrays -> tensors (recursively), so the file stays loadable with weights_only."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if hasattr(value, "__array__") and not isinstance(value, torch.Tensor):
        return torch.as_tensor(value)
    return value


def what_file(path: Path) -> str:
    """What a file that torch cannot read as a model looks like, for the error message."""
    with open(path, "rb") as fh:
        head = fh.read(64)
    if not head:
        return "the file is empty"
    if head.lstrip()[:1] in (b"{", b"["):
        return "it holds JSON"
    if head[:2] == b"PK":
        return "a torch file of other objects (a Lightning checkpoint? export it with " \
               "sportsngen.model.export.save_model)"
    return "corrupt or not a torch file"


def read_blob(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """The dict of a model file, or `ModelFileError` saying why `path` is not one."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no model file at {path}")
    st = path.stat()
    key = (str(path.resolve()), st.st_ino, st.st_size, st.st_mtime_ns, str(map_location))
    if key in _READ_CACHE:
        _READ_CACHE.move_to_end(key)
        return copy.deepcopy(_READ_CACHE[key])      # a copy: callers may change theirs
    try:
        blob = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # EOFError, UnpicklingError, RuntimeError: all mean "not ours"
        raise ModelFileError(f"{path} is not a sportsngen model file: {what_file(path)} "
                             f"({type(exc).__name__})") from exc
    if not is_model_file(blob):
        raise ModelFileError(f"{path} is not a sportsngen model file (a Lightning checkpoint? "
                             "export it with sportsngen.model.export.save_model)")
    missing = [k for k in ("version", "config", "vocab", "decoder") if k not in blob]
    if missing:
        raise ModelFileError(f"{path} is a damaged sportsngen model file: it lacks {missing}")
    _READ_CACHE[key] = blob
    while len(_READ_CACHE) > _READ_CACHE_FILES:
        _READ_CACHE.popitem(last=False)
    return copy.deepcopy(blob)


def update_extra(path: str | Path, **items) -> Path:
    """Add or replace entries of a model file's `extra` data in place (e.g. the simulator's
    initial conditions, `sportsngen.data.serve_starts`)."""
    path = Path(path)
    blob = read_blob(path)
    blob["extra"] = {**dict(blob.get("extra") or {}), **_plain(items)}
    # Written beside it and renamed: a reader (a study on the other core) never sees half a file.
    tmp = path.with_name(path.name + ".tmp")
    torch.save(blob, tmp)
    os.replace(tmp, path)
    return path


def is_model_file(blob: dict) -> bool:
    return isinstance(blob, dict) and blob.get("format") == FORMAT


def read_extra(path: str | Path) -> dict:
    """The `extra` dict saved with a model file (e.g. the training summary and data split)."""
    return dict(read_blob(path).get("extra") or {})


def load_model(path: str | Path, map_location: str | torch.device = "cpu"):
    """-> (model in eval mode, event classifier or None, Vocab, ModelConfig)."""
    path = Path(path)
    blob = read_blob(path, map_location)
    if blob["version"] > VERSION:
        raise ModelFileError(f"{path} has format version {blob['version']}, newer than "
                             f"{VERSION}: update sportsngen")
    cfg = ModelConfig.from_dict(blob["config"])
    model = SportsNGEN(cfg)
    ec = None if blob.get("event_classifier") is None else EventClassifier(cfg)
    try:
        model.load_state_dict(blob["decoder"])
        if ec is not None:
            ec.load_state_dict(blob["event_classifier"])
    except RuntimeError as exc:   # weights of another shape than the stored config says
        raise ModelFileError(f"{path} is a damaged sportsngen model file: its weights do not "
                             f"match its config ({exc})") from exc
    model.eval()
    if ec is not None:
        ec.eval()
    return model, ec, Vocab.from_dict(blob["vocab"]), cfg
