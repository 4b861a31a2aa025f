"""The package's dependency order (docs/architecture.md, "Layers"), read from the source: every
import of one sportsngen package by another points down the order, except into the few
foundation modules named here, and no two modules import each other at load time."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sportsngen"

# Lowest first. A package may import its own and any package of a lower rank.
ORDER = ("errors", "workers", "tennis", "data", "synth", "baselines", "model", "sim", "train",
         "eval", "viz", "report", "studies", "cli")
RANK = {name: i for i, name in enumerate(ORDER)}
RANK.update(errors=0, workers=0, tennis=0)   # the three foundations are one rank

# Modules of higher packages that lower ones may read: each imports nothing above `synth`
# (checked below). The model's input schema is what tokenised data is cut to; the points
# table's statistics, the win-probability calibrators, a track's reach and physical checks and
# the Hawk-Eye figures are what the simulator, the table fits and the generator's calibration
# measure themselves by.
FOUNDATION_MODULES = {
    "sportsngen.model.inputs",
    "sportsngen.eval.stats",
    "sportsngen.eval.calibration",
    "sportsngen.eval.physical",
    "sportsngen.eval.reach",
    "sportsngen.eval.markdown",
    "sportsngen.eval.hawkeye_strikes",
    "sportsngen.eval.hawkeye",
    "sportsngen.eval.hawkeye_report",
}

# Imports that point up the order on purpose, each with its reason. Two closed-loop table fits
# measure the model's own rollouts with eval's readers before they fit.
UPWARD = {
    ("sportsngen.train.table_fits", "sportsngen.eval.shot_profile"):
        "the late strikes' table refitted on rollouts' strike endings",
    ("sportsngen.train.expert_files", "sportsngen.eval.expert_answers"):
        "the generator's answers to simulated states, read by eval's expert answers",
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports() -> list[tuple[str, str, bool]]:
    """(importer, imported module, at load time) for every `from sportsngen... import`."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text())
        top = {id(node) for node in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sportsngen."):
                for target in _targets(node):
                    out.append((_module_name(path), target, id(node) in top))
    return out


def _targets(node: ast.ImportFrom) -> set[str]:
    """The modules an import reads: `from pkg import submodule` reads the submodule."""
    folder = PACKAGE.parent.joinpath(*node.module.split("."))
    subs = {f"{node.module}.{a.name}" for a in node.names
            if (folder / f"{a.name}.py").is_file() or (folder / a.name).is_dir()}
    plain = [a for a in node.names if f"{node.module}.{a.name}" not in subs]
    return subs | ({node.module} if plain else set())


def _package(module: str) -> str:
    return module.split(".")[1]


IMPORTS = _imports()


def test_the_scan_reads_the_package():
    assert len(IMPORTS) > 500
    assert {_package(m) for m, _, _ in IMPORTS} <= set(RANK)
    assert ("sportsngen.sim.simulator", "sportsngen.eval.calibration", True) in IMPORTS


@pytest.mark.parametrize("package", ORDER)
def test_imports_point_down_the_order(package):
    upward = sorted({(a, b) for a, b, _ in IMPORTS if _package(a) == package
                     and RANK[_package(b)] > RANK[package] and b not in FOUNDATION_MODULES
                     and (a, b) not in UPWARD})
    assert upward == [], f"{package} imports above itself: {upward}"


def test_each_upward_import_is_still_there():
    """A listed exception that the code no longer has is taken off the list."""
    assert set(UPWARD) <= {(a, b) for a, b, _ in IMPORTS}


def test_foundation_modules_import_nothing_above_synth():
    for a, b, _ in IMPORTS:
        if a in FOUNDATION_MODULES and b not in FOUNDATION_MODULES:
            assert RANK[_package(b)] <= RANK["synth"], f"{a} imports {b}"


def test_no_import_cycle_at_load_time():
    graph: dict[str, set[str]] = {}
    for a, b, at_load in IMPORTS:
        if not at_load:
            continue
        # Loading b first runs each package above it (its __init__); a's own packages are
        # loaded before a is.
        parts = b.split(".")
        for k in range(2, len(parts) + 1):
            target = ".".join(parts[:k])
            if target != a and not a.startswith(target + "."):
                graph.setdefault(a, set()).add(target)
    done: set[str] = set()

    def visit(node: str, stack: list[str]) -> None:
        if node in stack:
            raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(node):]
                                                                + [node]))
        if node in done:
            return
        for nxt in sorted(graph.get(node, ())):
            visit(nxt, stack + [node])
        done.add(node)

    for node in sorted(graph):
        visit(node, [])
