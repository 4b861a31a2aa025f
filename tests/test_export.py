"""Reading model files (`sportsngen.model.export`): a file read again comes from memory as a
copy of its own; a file changed on disk is read afresh."""

from __future__ import annotations

import shutil

import torch

from sportsngen.model import export
from sportsngen.model.export import read_blob, read_extra, update_extra


def test_a_file_read_again_is_a_copy_and_a_changed_file_is_read_afresh(tiny_model_file, tmp_path,
                                                                        monkeypatch):
    loads = []
    real_load = torch.load
    monkeypatch.setattr(export.torch, "load", lambda *a, **k: loads.append(a[0]) or
                        real_load(*a, **k))
    path = shutil.copy(tiny_model_file, tmp_path / "m.pt")
    first = read_blob(path)
    name, weight = next(iter(first["decoder"].items()))
    kept = weight.clone()
    # The caller's copy is its own: changing it changes nothing the next reader sees.
    first["extra"]["note"] = "changed"
    weight.zero_()
    again = read_blob(path)
    assert len(loads) == 1
    assert "note" not in again["extra"] and torch.equal(again["decoder"][name], kept)
    # Written in place (a new file renamed over it): the next read is the new file.
    update_extra(path, note="written")
    assert read_extra(path)["note"] == "written"
    assert len(loads) == 2                     # update_extra read it from memory
    # Another file under the same name: its own contents.
    shutil.copy(tiny_model_file, path)
    assert "note" not in read_extra(path)
