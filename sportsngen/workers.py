"""The start method of the library's process pools."""

from __future__ import annotations

import multiprocessing as mp
from multiprocessing.context import BaseContext


def pool_context(module: str) -> BaseContext:
    """The context for a pool whose worker functions live in `module`: `forkserver` where the
    platform has it, its server importing `module` once, so each worker is forked from it
    instead of importing the library afresh (a pool of two for rally win probabilities:
    4.9 / 5.7 -> 2.4 / 2.7 s, 9.6 / 10.6 -> 5.4 / 6.1 s of CPU). The server has run no OpenMP
    region, so its forks may start torch threads; a fork of a process that has run one hangs
    there (docs/evaluation.md, sixty-third part). `spawn` where there is no forkserver (Windows).
    A server already started by an earlier pool keeps its imports; its workers import the rest
    as spawned ones would."""
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload([module])
    return ctx
