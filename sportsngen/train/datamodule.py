"""Where rallies come from (`load_rally_data`) and the LightningDataModule of windows."""

from __future__ import annotations

import hashlib
import importlib
from collections.abc import Mapping
from pathlib import Path

import lightning as L
import numpy as np
from torch.utils.data import DataLoader

from sportsngen.data.tokens import RallyArrays, Vocab, rally_arrays
from sportsngen.data.tracking import RallyData
from sportsngen.errors import ArgumentError
from sportsngen.train.windows import Augment, WindowDataset

DATA_SOURCES = ("toy", "synthetic", "folder")
_TOY_KEYS = {"source", "n_rallies", "seed", "fps"}


def load_rally_data(cfg: Mapping) -> RallyData:
    """Load tracking data from a data config with ``source: toy | synthetic | folder``.

    toy: `sportsngen.data.toy.make_toy_rallies(n_rallies, seed, fps)`; synthetic: the generator's
    `sportsngen.synth.dataset.load_synthetic(cfg)`; folder: `RallyData.load(path)`.
    """
    cfg = dict(cfg)
    source = cfg.get("source", "synthetic")
    if source == "toy":
        extra = sorted(set(cfg) - _TOY_KEYS)
        if extra:  # e.g. a conf/data/synthetic_* file merged over the toy default
            raise ValueError(f"data.source is 'toy' but the data config has keys {extra}; "
                             "set data.source=synthetic (or folder) for that config")
        from sportsngen.data.toy import make_toy_rallies

        return make_toy_rallies(int(cfg.get("n_rallies", 200)), int(cfg.get("seed", 0)),
                                float(cfg.get("fps", 25.0)))
    if source == "synthetic":
        try:
            dataset = importlib.import_module("sportsngen.synth.dataset")
        except ImportError as exc:
            raise ValueError("data.source=synthetic needs sportsngen.synth.dataset "
                             f"(the generator), which cannot be imported: {exc}") from exc
        return dataset.load_synthetic(cfg)
    if source == "folder":
        if not cfg.get("path") or str(cfg["path"]) == "???":   # "???": Hydra's unset value
            raise ArgumentError("data.source=folder needs data.path, the RallyData folder: "
                                "python train.py data=folder data.path=/path/to/folder")
        return RallyData.load(Path(cfg["path"]).expanduser())
    raise ValueError(f"data.source must be one of {DATA_SOURCES}, got {source!r}")


def data_fingerprint(data: RallyData) -> str:
    """A short hash of the rallies' ids and every coordinate: tells whether data loaded again
    (e.g. regenerated after the generator's profiles changed) are the data a model saw."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(data.rallies["rally_id"].to_numpy(np.int64)).tobytes())
    h.update(np.ascontiguousarray(data.frames[["x", "y", "z"]].to_numpy(np.float32)).tobytes())
    return h.hexdigest()[:16]


def split_positions(n: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random train/validation split of `n` rallies by position (seeded) -> (train, val),
    each sorted; at least one rally in each when there are two or more."""
    if not 0.0 <= val_fraction < 1.0:
        raise ValueError(f"val_fraction must be in [0, 1), got {val_fraction}")
    order = np.random.default_rng(seed).permutation(n)
    n_val = int(round(n * val_fraction))
    if val_fraction > 0 and n >= 2:
        n_val = min(max(n_val, 1), n - 1)
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def split_rallies(arrays: RallyArrays, val_fraction: float, seed: int):
    """`arrays` split as `split_positions` says -> (train, val)."""
    train, val = split_positions(len(arrays), val_fraction, seed)
    return arrays.select(train), arrays.select(val)


class TrackingDataModule(L.LightningDataModule):
    """Windows of a `RallyData` for the decoder and the event classifier."""

    def __init__(self, data: RallyData, vocab: Vocab, window_frames: int, batch_size: int = 16,
                 val_fraction: float = 0.1, seed: int = 0, augment: Augment | None = None,
                 num_workers: int = 0, unknown: str = "warn",
                 extra_train: RallyArrays | None = None):
        super().__init__()
        self.data, self.vocab = data, vocab
        self.window_frames, self.batch_size = window_frames, batch_size
        self.val_fraction, self.seed = val_fraction, seed
        self.augment = augment if augment is not None else Augment()
        self.num_workers, self.unknown = num_workers, unknown
        self.train_arrays: RallyArrays | None = None
        self.val_arrays: RallyArrays | None = None
        # Rallies trained on beside the data's training split, never validated on (an expert's
        # answers to the model's own rollouts, `sportsngen.train.expert`).
        self.extra_train = extra_train

    def setup(self, stage: str | None = None) -> None:
        if self.train_arrays is not None:
            return
        arrays = rally_arrays(self.data, self.vocab, self.unknown)
        self.train_arrays, self.val_arrays = split_rallies(arrays, self.val_fraction, self.seed)
        if self.extra_train is not None:
            if abs(self.extra_train.fps - arrays.fps) > 1e-9:
                raise ValueError(f"extra training rallies at {self.extra_train.fps:g} Hz, the "
                                 f"data at {arrays.fps:g} Hz")
            self.train_arrays = RallyArrays.concat([self.train_arrays, self.extra_train])

    def train_dataloader(self) -> DataLoader:
        rank = self.trainer.global_rank if self.trainer is not None else 0
        ds = WindowDataset(self.train_arrays, self.window_frames, self.augment,
                           seed=self.seed + 1000 * rank)
        return DataLoader(ds, batch_size=self.batch_size, shuffle=True, drop_last=False,
                          num_workers=self.num_workers,
                          persistent_workers=self.num_workers > 0)

    def val_dataloader(self) -> DataLoader:
        ds = WindowDataset(self.val_arrays, self.window_frames, None)
        return DataLoader(ds, batch_size=self.batch_size, shuffle=False,
                          num_workers=self.num_workers)
