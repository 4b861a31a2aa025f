"""A head fitted alone on a frozen decoder's states, read once (`sportsngen.train.head_fit`)."""

import numpy as np
import pytest
import torch
from torch.utils.data import default_collate

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.inputs import BALL, flip_xy
from sportsngen.train.head_fit import cached_states, collect_head_states, fit_head, head_nll
from sportsngen.train.metrics import window_states
from sportsngen.train.windows import WindowDataset


def small_model(**kw) -> SportsNGEN:
    torch.manual_seed(0)
    cfg = dict(d_model=32, n_layers=2, n_heads=2, ff_mult=2, dropout=0.0, id_dim=8,
               embed_hidden=(32,), score_hidden=16, n_bins=9, head="factorised",
               head_hidden=16, window_s=4.0, fps=25.0, n_ids=40, n_tournaments=4,
               event_d_model=16, event_layers=1, event_heads=2, ball_centre="physics",
               serve_head=True, strike_head=True)
    cfg.update(kw)
    return SportsNGEN(ModelConfig(**cfg)).eval()


@pytest.fixture(scope="module")
def rallies():
    from sportsngen.eval.diagnostics import DiagnosticsSetup, truth_points

    data = truth_points(DiagnosticsSetup(n_points=30, seed=5))
    return rally_arrays(data, Vocab.from_data(data))


def test_serve_states_are_the_decoders_states_at_each_rallys_serve(rallies):
    model = small_model()
    st = collect_head_states(model, rallies, "serve", batch_size=7, progress=False)
    # One serve a rally (each lies in its rally's first 4 s window), every rally once.
    assert sorted(st.rally_id.tolist()) == sorted(rallies.rally_id.tolist())
    assert st.h.shape == (len(rallies), 32) and st.bins.shape == (len(rallies), 4)
    assert set(st.serve.tolist()) <= {0, 1}
    # The same state and bins as the training step computes on that rally's first window.
    ds = WindowDataset(rallies, model.cfg.window_frames, None)
    first = next(i for i, (ri, s) in enumerate(ds.items) if ri == 3 and s == 0)
    batch = default_collate([ds[first]])
    with torch.no_grad():
        h = window_states(model, batch)
    mask, bins = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                      batch["has_next"], serves=True)
    row = int(np.flatnonzero(st.rally_id == rallies.rally_id[3])[0])
    assert int(mask.sum()) == 1
    torch.testing.assert_close(st.h[row], h[..., BALL, :][mask][0])
    assert torch.equal(st.bins[row], bins[mask][0])
    np.testing.assert_allclose(st.contact_m[row], batch["pos_m"][..., BALL, :][mask][0].numpy())


def test_flipped_states_are_the_training_flips_in_the_world_frame_only(rallies):
    model = small_model()
    plain = collect_head_states(model, rallies, "serve", progress=False)
    both = collect_head_states(model, rallies, "serve", flip=True, progress=False)
    assert len(both) == 2 * len(plain)
    torch.testing.assert_close(both.h[:len(plain)], plain.h)
    # The turned half: the state of the same first window turned by the training flip.
    ds = WindowDataset(rallies, model.cfg.window_frames, None)
    first = next(i for i, (ri, s) in enumerate(ds.items) if ri == 2 and s == 0)
    item = dict(ds[first])
    for k in ("pos_m", "vel_mps", "next_pos_m", "prev_vel_mps"):
        item[k] = flip_xy(item[k])
    batch = default_collate([item])
    with torch.no_grad():
        h = window_states(model, batch)
    mask, bins = model.strike_targets(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"],
                                      batch["has_next"], serves=True)
    row = len(plain) + int(np.flatnonzero(plain.rally_id == rallies.rally_id[2])[0])
    torch.testing.assert_close(both.h[row], h[..., BALL, :][mask][0])
    assert torch.equal(both.bins[row], bins[mask][0])
    assert not torch.allclose(both.h[row], plain.h[row - len(plain)])
    # In the server's frame the turn is undone: nothing new to read.
    turned = small_model(frame="server")
    assert len(collect_head_states(turned, rallies, "serve", flip=True,
                                   progress=False)) == len(plain)


def test_fitting_lowers_the_nll_and_keeps_the_best_head(rallies):
    model = small_model()
    st = collect_head_states(model, rallies, "serve", progress=False)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    history = fit_head(model, "serve", st, st, steps=300, lr=3e-3, batch_size=32,
                       eval_every=50, progress=False)
    assert [r["step"] for r in history] == [0, 50, 100, 150, 200, 250, 300]
    # A head of ~16 k weights on 23 serves: it learns them (from ~18 nats, 4 x log 96).
    assert history[0]["val_nll"] > 17.0 and min(r["val_nll"] for r in history) < 12.0
    assert head_nll(model, "serve", st) == pytest.approx(min(r["val_nll"] for r in history))
    # Only the serve head moved.
    after = model.state_dict()
    moved = {k for k in after if not torch.equal(after[k], before[k])}
    assert moved and all(k.startswith("serve_head.") for k in moved)


def test_strike_states_and_clear_errors(rallies):
    model = small_model()
    st = collect_head_states(model, rallies, "strike", progress=False)
    assert len(st) > len(rallies)          # several rally strikes a point
    with pytest.raises(ValueError, match="no serve head"):
        collect_head_states(small_model(serve_head=False), rallies, "serve", progress=False)
    with pytest.raises(ValueError, match="head must be one of"):
        collect_head_states(model, rallies, "volley", progress=False)
    with pytest.raises(ValueError, match="positive"):
        fit_head(model, "strike", st, st, steps=0)


def test_strike_states_know_whose_strike_it_is(rallies):
    model = small_model()
    st = collect_head_states(model, rallies, "strike", progress=False)
    # The record's rally strikes alternate: the receiver hits the return, the server the next.
    assert 0.4 < st.receiver.mean() < 0.7
    server_x = {int(r): np.sign(rallies.pos_m[rallies.start[i], 0, 0])
                for i, r in enumerate(rallies.rally_id)}
    on_server_end = np.sign(st.contact_m[:, 0]) == np.array([server_x[int(r)]
                                                             for r in st.rally_id])
    assert (st.receiver == ~on_server_end).all()


def test_the_strike_role_shift_is_fitted_with_the_head_and_nothing_else(rallies):
    from sportsngen.train.finetune import with_strike_roles

    base = small_model()
    model = with_strike_roles(base)
    st = collect_head_states(model, rallies, "strike", progress=False)
    # At zero the shift changes nothing.
    assert head_nll(model, "strike", st) == pytest.approx(head_nll(base, "strike", st))
    before = {k: v.clone() for k, v in model.state_dict().items()}
    fit_head(model, "strike", st, st, steps=200, lr=3e-3, batch_size=64, eval_every=50,
             progress=False)
    after = model.state_dict()
    moved = {k for k in after if not torch.equal(after[k], before[k])}
    assert "strike_role.weight" in moved
    assert all(k.startswith(("strike_head.", "strike_role.")) for k in moved)
    assert head_nll(model, "strike", st) < head_nll(base, "strike", st)


def test_own_serve_states_pair_the_models_own_serve_with_the_records_serve(
        federer_points_and_head_model):
    """A stand-in simulator plays each point as recorded, but tosses rally A's ball 0.1 m
    higher before the serve and sends it 0.5 m wider after, and stops rally B before its
    serve: A's own state differs from its recorded one and takes the record's bins, not its
    own serve's; B is left out; the rest equal the record."""
    import pandas as pd

    from sportsngen.data.tracking import RallyData
    from sportsngen.train.own_states import own_serve_states

    data, model, stand_in = federer_points_and_head_model
    arrays = rally_arrays(data, stand_in.vocab)
    a, b = (int(x) for x in arrays.rally_id[:2])
    serve_frame = data.shots[data.shots["shot_index"] == 0].set_index("rally_id")["frame"]
    seen = {}

    def simulate_rallies(plan, seed=0, progress=False, max_duration_s=None):
        seen["plan"] = plan
        f = data.frames[data.frames["rally_id"].isin(plan["rally_id"])].copy()
        toss = (f["rally_id"] == a) & (f["object"] == "ball") & (f["frame"] < serve_frame[a])
        f.loc[toss, "z"] += 0.1
        after = (f["rally_id"] == a) & (f["object"] == "ball") & (f["frame"] > serve_frame[a])
        f.loc[after, "y"] += 0.5
        f = f[(f["rally_id"] != b) | (f["frame"] < serve_frame[b] - 5)]
        keep = data.rallies["rally_id"].isin(plan["rally_id"])
        return RallyData(f, data.rallies[keep], data.shots[data.shots["rally_id"].isin(
            plan["rally_id"])], fps=data.fps)

    stand_in.simulate_rallies = simulate_rallies
    try:
        record, own = own_serve_states(stand_in, data, arrays, seed=3)
        # Recorded states read before are used as given, not read again.
        given = own_serve_states(stand_in, data, arrays, seed=3, record=record)
    finally:
        del stand_in.simulate_rallies
    assert given[0] is record and torch.equal(given[1].h, own.h)
    assert torch.equal(given[1].bins, own.bins)
    played = collect_head_states(model, rally_arrays(simulate_rallies(seen["plan"]),
                                                     stand_in.vocab), "serve", progress=False)
    assert not torch.equal(played.bins[played.rally_id == a][0],
                           record.bins[record.rally_id == a][0])
    assert sorted(seen["plan"]["rally_id"]) == sorted(pd.unique(record.rally_id))
    assert b not in own.rally_id and len(own) == len(pd.unique(record.rally_id)) - 1
    rec_row = {int(r): i for i, r in reversed(list(enumerate(record.rally_id)))}
    for i, rid in enumerate(own.rally_id.tolist()):
        j = rec_row[rid]
        assert torch.equal(own.bins[i], record.bins[j]) and own.serve[i] == record.serve[j]
        same = torch.allclose(own.h[i], record.h[j], atol=1e-5)
        assert same == (rid != a), rid


def test_states_are_read_once_and_kept_under_the_key_they_were_read_with(tmp_path):
    calls = []

    def read():
        calls.append(1)
        return {"train": torch.arange(3), "val": torch.arange(2)}

    path = tmp_path / "sub" / "states.pt"
    got, cached = cached_states(path, {"model": "a"}, read)
    assert not cached and len(calls) == 1 and path.exists()
    again, cached = cached_states(path, {"model": "a"}, read)
    assert cached and len(calls) == 1
    assert again["train"].tolist() == [0, 1, 2] and again["val"].tolist() == [0, 1]
    with pytest.raises(ValueError, match="remove it"):
        cached_states(path, {"model": "b"}, read)
    # States read under another reading of the strike labels are refused too.
    old = torch.load(path, weights_only=False)
    torch.save({**old, "labels": old["labels"] - 1}, path)
    with pytest.raises(ValueError, match="strike labels version"):
        cached_states(path, {"model": "a"}, read)
    none, cached = cached_states(None, "k", read)          # no path: read every time
    assert not cached and len(calls) == 2 and set(none) == {"train", "val"}


def test_strike_states_read_as_a_rollout_reads_them(rallies):
    """With lead_frames each rally strike is read from its own window ending that many frames
    after it: the same strikes and bins as the tiling windows give, in the same order, and
    the decoder's state exactly that window's at the strike; a strike in a rally's first
    window (the window starts at the rally's first frame either way) reads the same state."""
    model = small_model()
    tiled = collect_head_states(model, rallies, "strike", progress=False)
    view = collect_head_states(model, rallies, "strike", progress=False, lead_frames=8)
    assert len(view) == len(tiled)
    assert np.array_equal(view.rally_id, tiled.rally_id)
    assert torch.equal(view.bins, tiled.bins)
    np.testing.assert_allclose(view.contact_m, tiled.contact_m)
    window = model.cfg.window_frames
    same = torch.isclose(view.h, tiled.h, atol=1e-5).all(-1).numpy()
    assert same.any() and not same.all()     # first-window strikes alike, later ones not
    ds = WindowDataset(rallies, window, None)
    row = int(np.flatnonzero(~same)[0])
    ri = int(np.flatnonzero(rallies.rally_id == view.rally_id[row])[0])
    # Find the strike's frame in its rally from the tiling windows, then read it as a rollout.
    at = None
    for k, (i, s) in enumerate(ds.items):
        if i != ri:
            continue
        b = default_collate([ds[k]])
        mask, bins = model.strike_targets(b["pos_m"], b["vel_mps"], b["next_pos_m"],
                                          b["has_next"])
        for t in mask[0].nonzero()[:, 0].tolist():
            if np.allclose(b["pos_m"][0, t, BALL].numpy(), view.contact_m[row]):
                at = s + t
    assert at is not None and at >= window - 8
    own = WindowDataset(rallies, window, None, items=[(ri, at - (window - 8))])
    with torch.no_grad():
        h = window_states(model, default_collate([own[0]]))
    torch.testing.assert_close(view.h[row], h[0, window - 8, BALL])
    with pytest.raises(ValueError, match="lead_frames"):
        collect_head_states(model, rallies, "strike", progress=False, lead_frames=2)
    with pytest.raises(ValueError, match="lead_frames"):
        collect_head_states(model, rallies, "serve", progress=False, lead_frames=8)
