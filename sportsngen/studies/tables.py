"""Markdown of the studies: tables, and files whose hand-written part survives a rewrite."""

from __future__ import annotations

from pathlib import Path


def md_table(header: list[str], rows: list[list[str]], left: int = 1) -> list[str]:
    """Markdown lines of a table: the first `left` columns aligned left, the rest right."""
    lines = ["| " + " | ".join(header) + " |",
             "|" + "---|" * left + "---:|" * (len(header) - left)]
    return lines + ["| " + " | ".join(cells) + " |" for cells in rows]


def kept_tail(path: Path, marker: str) -> str | None:
    """The text of `path` from `marker` on (hand-written notes), or None."""
    old = path.read_text() if path.is_file() else ""
    return old[old.index(marker):] if marker in old else None


def write_markdown(path: Path, lines: list[str], tail: str = "") -> None:
    """`lines` and a newline, then `tail` (a kept hand-written part), into `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n" + tail)
