"""The library's error types and the argument checks that raise them. No torch.

Every error the library raises on purpose derives from `SportsNGENError` and from `ValueError`,
so `except ValueError` keeps working and a caller can tell the library's own refusals from a
bug's traceback. Messages name the argument (or the file, table, column and row) and the valid
values.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable

import numpy as np


class SportsNGENError(Exception):
    """Base of the library's own errors."""


class ArgumentError(SportsNGENError, ValueError, TypeError):
    """A bad argument to a public function. Also a TypeError, since a wrong type is one case."""


class TrackingDataError(SportsNGENError, ValueError):
    """Tracking data that breaks the schema; the message names the file or table, column, rally
    and row."""


class ModelFileError(SportsNGENError, ValueError):
    """A file that is not a readable sportsngen model file (or training checkpoint)."""


def check_int(name: str, value, lo: int | None = None, hi: int | None = None) -> int:
    """`value` as an int (numpy integers accepted, bools and floats refused) within [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentError(f"{name} must be an integer{_range(lo, hi)}, "
                            f"got {value!r} ({type(value).__name__})")
    value = int(value)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ArgumentError(f"{name} must be an integer{_range(lo, hi)}, got {value}")
    return value


def check_bool(name: str, value) -> bool:
    """`value` as a bool (numpy bools accepted; strings and numbers refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentError(f"{name} must be True or False, got {value!r} "
                            f"({type(value).__name__})")
    return bool(value)


def check_choice(name: str, value, choices: Iterable[str]) -> str:
    """`value` if it is one of `choices` (exactly); the error lists them and hints at a case
    slip ("Hard" for "hard")."""
    choices = tuple(choices)
    if isinstance(value, str) and value in choices:
        return value
    hint = ""
    if isinstance(value, str):
        near = [c for c in choices if c.lower() == value.strip().lower()]
        hint = f" (did you mean {near[0]!r}?)" if near else ""
    raise ArgumentError(f"{name} must be one of {list(choices)}, got {value!r}{hint}")


def check_name(name: str, value) -> str:
    """`value` if it is a non-empty string (a player's name, say)."""
    if not isinstance(value, str) or not value.strip():
        raise ArgumentError(f"{name} must be a non-empty string, got {value!r}")
    return value


def check_players(first, second, names: tuple[str, str] = ("server", "receiver")) -> None:
    """Two different players' names, or an `ArgumentError` naming the arguments."""
    check_name(names[0], first)
    check_name(names[1], second)
    if first == second:
        raise ArgumentError(f"{names[0]} and {names[1]} must be different players, got "
                            f"{first!r} twice")


def _range(lo: int | None, hi: int | None) -> str:
    if lo is not None and hi is not None:
        return f" in [{lo}, {hi}]"
    if lo is not None:
        return f" >= {lo}"
    return "" if hi is None else f" <= {hi}"
