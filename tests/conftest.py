"""Fixtures shared by several test files."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

REPO = Path(__file__).resolve().parents[1]


def tiny_sim(path, **kw):
    """The tiny model's Simulator for tests whose subject is not the physical limits: unretried
    rallies and no limits. The model is trained three steps, so most frames it draws fail a
    limit and are drawn again up to 40 times: most of a rollout's time (docs/architecture.md)."""
    from sportsngen.sim import Simulator

    return Simulator.from_pretrained(path, **{"max_retries": 0, "physical_limits": False, **kw})


def init_runs(tmp_path: Path, model_file: Path, option: str, steps=(0, 3)) -> dict:
    """The tiny model file fine-tuned on toy rallies with one `init_...` option (e.g.
    "init_clock_s=2.0") for each number of `steps` -> steps: `load_model`'s tuple."""
    from sportsngen.model import load_model
    from sportsngen.train.run import train_from_config

    over = ["experiment=tiny", "data=toy", "data.n_rallies=16", "trainer.val_check_interval=3",
            "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
            "events.enabled=false", f"init={model_file}", option]
    runs = {}
    for n in steps:
        with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
            cfg = compose(config_name="train", overrides=[*over, f"trainer.max_steps={n}"])
        runs[n] = load_model(train_from_config(cfg, tmp_path / f"s{n}")["model_file"])
    return runs


def run_folder(tmp_path_factory, worker_id: str, name: str) -> Path:
    """A folder all of a run's workers share (xdist's base temporary folder's parent), or a
    fresh one without xdist."""
    if worker_id == "master":
        return tmp_path_factory.mktemp(name)
    return tmp_path_factory.getbasetemp().parent / name


@pytest.fixture(scope="session")
def tiny_model_file(tmp_path_factory, worker_id) -> Path:
    """A tiny decoder + event classifier trained a few steps on toy rallies, exported (with
    serve starts), for simulator tests. Trained once a run: under xdist the first worker to
    need it trains it in the run's shared temporary folder and the others wait for the file."""
    from filelock import FileLock

    from sportsngen.train.run import train_from_config

    out = run_folder(tmp_path_factory, worker_id, "tiny_run")
    with FileLock(str(out) + ".lock"):
        if not (out / "model.pt").exists():
            overrides = ["experiment=tiny", "data=toy", "data.n_rallies=16",
                         "trainer.max_steps=3", "trainer.val_check_interval=3",
                         "trainer.limit_val_batches=1", "trainer.enable_progress_bar=false",
                         "events.max_steps=2"]
            with initialize_config_dir(config_dir=str(REPO / "conf"), version_base=None):
                cfg = compose(config_name="train", overrides=overrides)
            train_from_config(cfg, out)
    return out / "model.pt"


@pytest.fixture(scope="session")
def federer_points_and_head_model(truth_data):
    """80 generated points of Federer serving to Nadal, a small untrained model with serve and
    strike heads, and a stand-in for a Simulator (its `vocab`, `model` and serve nucleus): what
    the teacher-forced head tables read."""
    from types import SimpleNamespace

    from sportsngen.data.tokens import Vocab
    from tests.test_head_fit import small_model

    data = truth_data(80, 6)
    model = small_model()
    return data, model, SimpleNamespace(vocab=Vocab.from_data(data), model=model,
                                        top_p_serve=1.0)


@pytest.fixture(scope="session")
def truth_data(tmp_path_factory, worker_id):
    """`truth_data(n_points, seed)`: `truth_points(DiagnosticsSetup(n_points, seed))`, the
    generator's Federer-serving points, generated once a run. Several test files read the same
    points; the first worker to ask writes them to the run's shared temporary folder (as
    `tiny_model_file` does) and every call reads a fresh copy, exact to the bit, which a test
    may change freely."""
    from filelock import FileLock

    from sportsngen.data.tracking import RallyData
    from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points

    root = run_folder(tmp_path_factory, worker_id, "truth")

    def read(n_points: int, seed: int) -> RallyData:
        folder = root / f"n{n_points}-s{seed}"
        with FileLock(str(folder) + ".lock"):
            if not (folder / "meta.json").exists():
                truth_points(DiagnosticsSetup(n_points=n_points, seed=seed)).save(folder)
        return RallyData.load(folder, validate=False)

    root.mkdir(parents=True, exist_ok=True)
    return read
