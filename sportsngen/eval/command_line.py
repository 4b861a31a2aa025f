"""What the check and diagnosis commands' command lines share: the model file and its sampling
flags (`eval.sampling_options`), threads, and a run's points and seed; and the simulator they
ask for, built once here rather than in every script."""

from __future__ import annotations

import argparse

import torch

from sportsngen.errors import ArgumentError
from sportsngen.eval.sampling_options import add_sampling_options, sampling_kwargs
from sportsngen.sim import Simulator

# Settings a command line may give beside the sampling flags, None for the model file's.
_EXTRA_SETTINGS = ("top_p_player", "refresh_frames")


def add_points_seed(parser: argparse.ArgumentParser, points: int, seed: int,
                    points_help: str | None = None, seed_help: str | None = None) -> None:
    """Add `--points` and `--seed` with a command's own defaults."""
    parser.add_argument("--points", type=int, default=points, help=points_help)
    parser.add_argument("--seed", type=int, default=seed, help=seed_help)


def add_simulator_options(parser: argparse.ArgumentParser, threads: int | None = None) -> None:
    """Add `--model` (default: the bundled model), `--threads` (torch's threads; None leaves
    torch's), `--top-p-player` and the sampling flags, every one defaulting to the file's."""
    parser.add_argument("--model", default=None)
    parser.add_argument("--threads", type=int, default=threads)
    parser.add_argument("--top-p-player", type=float, default=None)
    add_sampling_options(parser)


def simulator_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace,
                        **kwargs) -> Simulator:
    """The `Simulator` of `add_simulator_options`' flags (and `--refresh-frames` where the
    command has it), `kwargs` passed on; a flag out of its range is the parser's error."""
    if getattr(args, "threads", None):
        torch.set_num_threads(args.threads)
    try:
        kwargs.update(sampling_kwargs(args))
    except ArgumentError as exc:
        parser.error(str(exc))
    for name in _EXTRA_SETTINGS:
        if getattr(args, name, None) is not None:
            kwargs[name] = getattr(args, name)
    return Simulator.from_pretrained(args.model, **kwargs)
