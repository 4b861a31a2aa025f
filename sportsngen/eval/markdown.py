"""Markdown tables, the one way the checks and reports write them (kept in eval, the lowest
layer that writes them, so `eval`, `viz` and `report` all import it downward)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]],
                   float_format: str = "{:.3f}") -> list[str]:
    """The lines of a markdown table: `header`, a rule, one line a row; floats through
    `float_format`, anything else through `str`."""
    def cell(v: object) -> str:
        return float_format.format(v) if isinstance(v, float) else str(v)

    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(cell(v) for v in r) + " |" for r in rows])
