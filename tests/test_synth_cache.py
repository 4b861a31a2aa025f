"""The synthetic-data cache heals itself: a damaged finished cache is regenerated with a warning,
two processes finishing the same cache both succeed, and dead generations' temporary folders are
removed. The generator is replaced by a fast toy writer: what is tested is the cache logic."""

from __future__ import annotations

import os
import socket
import subprocess
import threading

import pandas as pd
import pytest

from sportsngen.data.toy import make_toy_rallies
from sportsngen.synth import dataset
from sportsngen.synth.dataset import load_synthetic, publish, remove_stale_tmp

CFG = {"source": "synthetic", "name": "t", "players": {"named": ["Roger Federer"],
       "population": {"men": 1}}, "surfaces": ["hard"], "n_points": 4, "seed": 1}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """$SPORTSNGEN_CACHE in tmp_path and a toy generator; -> the list of generated folders."""
    monkeypatch.setenv("SPORTSNGEN_CACHE", str(tmp_path))
    made = []

    def fake_generate(c, folder, progress=True):
        made.append(folder)
        make_toy_rallies(3, int(c["seed"])).save(folder)
        return folder

    monkeypatch.setattr(dataset, "generate_to_folder", fake_generate)
    return made


def _folders(tmp_path):
    return sorted(p.name for p in (tmp_path / "synthetic").iterdir())


def _overwrite_middle(path):
    raw = bytearray(path.read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 64] = b"\x00" * 64
    path.write_bytes(bytes(raw))


@pytest.mark.parametrize("damage", [
    "bytes overwritten in frames.parquet",
    "frames.parquet truncated, no checksums (a cache from before them)",
    "meta.json deleted",
])
def test_a_damaged_cache_is_regenerated_with_a_warning(tmp_path, cache, damage):
    first = load_synthetic(CFG, progress=False)
    (folder,) = (tmp_path / "synthetic").iterdir()
    assert (folder / "checksums.json").is_file()
    if damage.startswith("bytes"):
        _overwrite_middle(folder / "frames.parquet")
    elif damage.startswith("frames.parquet truncated"):
        (folder / "checksums.json").unlink()
        raw = (folder / "frames.parquet").read_bytes()
        (folder / "frames.parquet").write_bytes(raw[: len(raw) // 3])
    else:
        (folder / "meta.json").unlink()
    with pytest.warns(UserWarning, match=f"synthetic cache {folder} is damaged"):
        again = load_synthetic(CFG, progress=False)
    pd.testing.assert_frame_equal(first.frames, again.frames)
    assert len(cache) == 2 and _folders(tmp_path) == [folder.name]
    load_synthetic(CFG, progress=False)     # healed: loads without generating again
    assert len(cache) == 2


def test_two_finishers_of_one_cache_both_succeed(tmp_path, cache, monkeypatch):
    """Forced interleaving: A generates, then B generates and publishes the whole cache, then A
    publishes. A must find B's copy, keep it, and leave no temporary folder."""
    a_generated, b_done = threading.Event(), threading.Event()
    generate = dataset.generate_to_folder

    def interleaved(c, folder, progress=True):
        generate(c, folder, progress)
        if threading.current_thread().name == "A":
            a_generated.set()
            assert b_done.wait(60), "B never finished"
        return folder

    monkeypatch.setattr(dataset, "generate_to_folder", interleaved)
    results = {}

    def run(name):
        try:
            if name == "B":
                assert a_generated.wait(60), "A never generated"
            results[name] = load_synthetic(CFG, progress=False)
        except BaseException as exc:  # reported below, in the test's thread
            results[name] = exc
        finally:
            if name == "B":
                b_done.set()

    threads = [threading.Thread(target=run, args=(n,), name=n) for n in "AB"]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert len(cache) == 2                       # both generated
    for name in "AB":
        assert not isinstance(results[name], BaseException), (name, results[name])
    pd.testing.assert_frame_equal(results["A"].frames, results["B"].frames)
    (only,) = _folders(tmp_path)
    assert ".tmp" not in only


def test_publish_replaces_a_damaged_copy_in_the_way(tmp_path, cache):
    load_synthetic(CFG, progress=False)
    (folder,) = (tmp_path / "synthetic").iterdir()
    _overwrite_middle(folder / "shots.parquet")
    fresh = tmp_path / "synthetic" / "fresh"
    make_toy_rallies(3, 1).save(fresh)
    dataset.write_checksums(fresh)
    publish(fresh, folder)
    assert not fresh.exists() and dataset.cache_damage(folder) is None


def test_dead_generations_temporary_folders_are_removed(tmp_path, cache):
    dead = subprocess.Popen(["true"])
    dead.wait()
    root = tmp_path / "synthetic"
    host = socket.gethostname()
    names = {"old style, dead": f"t-0123.tmp{dead.pid}",
             "dead": f"t-0123.tmp{dead.pid}-ab12@{host}",
             "alive (this process)": f"t-0123.tmp{os.getpid()}-cd34@{host}",
             "dead, but on another host": f"t-0123.tmp{dead.pid}-ef56@elsewhere"}
    for name in names.values():
        (root / name).mkdir(parents=True)
        (root / name / "frames.parquet").write_bytes(b"half written")
    load_synthetic(CFG, progress=False)
    left = set(_folders(tmp_path))
    assert names["alive (this process)"] in left and names["dead, but on another host"] in left
    assert names["dead"] not in left and names["old style, dead"] not in left
    assert remove_stale_tmp(root) == []
