"""Training: Lightning modules and data module, fine-tuning, the `train.py` driver."""

from sportsngen.train.datamodule import TrackingDataModule, load_rally_data
from sportsngen.train.module import DecoderModule, EventModule

__all__ = ["DecoderModule", "EventModule", "TrackingDataModule", "load_rally_data"]
