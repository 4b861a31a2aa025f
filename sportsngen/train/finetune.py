"""Fine-tuning player identities: add a player to a trained model and learn only their row.

A generic model (``model.generic_identity: true``, its Vocab has no players) maps every player to
one learned generic identity. `add_player` appends a new identity row, initialised from the
generic one, without touching the others; `freeze_except_identity` then leaves only chosen rows
trainable (a gradient hook zeroes the other rows' gradients, and the optimiser gives embeddings
no weight decay, so the other rows stay bit-identical).

A model trained on named players never uses its generic row (every training player has a row
of its own), so training from scratch sets that row to the mean of the players' rows
(`average_generic_identity`) before the model is saved: an unknown player then plays as the
average trained player rather than as a random embedding, and `add_player` starts a new player
from there.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import torch
from torch import nn

from sportsngen.data.tokens import Vocab
from sportsngen.data.tracking import RallyData
from sportsngen.errors import ModelFileError
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN
from sportsngen.model.export import is_model_file, load_model, read_extra, save_model, what_file
from sportsngen.model.inputs import GENERIC_ID, N_SPECIAL_IDS


def read_torch_file(path: str | Path, what: str = "model file or checkpoint"):
    """A torch file's object (a model file or a Lightning checkpoint), or `ModelFileError`
    saying why it is neither (empty, JSON, corrupt)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no {what} at {path}")
    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:  # EOFError, UnpicklingError, RuntimeError: all mean "not ours"
        raise ModelFileError(f"{path} is not a sportsngen {what}: {what_file(path)} "
                             f"({type(exc).__name__})") from exc


def load_pretrained(path: str | Path):
    """A model file (`save_model`) or a Lightning checkpoint of `DecoderModule` ->
    (model, event classifier or None, Vocab, ModelConfig)."""
    path = Path(path)
    blob = read_torch_file(path)
    if is_model_file(blob):
        return load_model(path)
    hp = blob.get("hyper_parameters", {}) if isinstance(blob, dict) else {}
    if "model_cfg" not in hp or "vocab" not in hp:
        raise ModelFileError(f"{path} is neither a sportsngen model file nor a DecoderModule "
                             "checkpoint (no model_cfg/vocab hyper-parameters)")
    cfg = ModelConfig.from_dict(hp["model_cfg"])
    model = SportsNGEN(cfg)
    state = {k[len("model."):]: v for k, v in blob["state_dict"].items()
             if k.startswith("model.")}
    model.load_state_dict(state)
    return model, None, Vocab.from_dict(hp["vocab"]), cfg


def check_data_matches(cfg: ModelConfig, vocab: Vocab, data: RallyData) -> None:
    """Raise ValueError when the data cannot be fed to a model of this config/vocab."""
    if abs(float(data.fps) - float(cfg.fps)) > 1e-9:
        raise ValueError(f"the model was trained at {cfg.fps:g} Hz but the data is "
                         f"{data.fps:g} Hz; resample the data or train a new model")
    if cfg.n_ids != vocab.n_ids and not cfg.generic_identity:
        raise ValueError(f"model config has {cfg.n_ids} identities but its vocabulary "
                         f"{vocab.n_ids}: config and vocabulary do not belong together")
    if cfg.n_tournaments != len(vocab.tournaments) + 1:
        raise ValueError(f"model config has {cfg.n_tournaments} tournaments but its "
                         f"vocabulary {len(vocab.tournaments) + 1}")
    unknown = sorted(set(data.rallies["surface"]) - set(vocab.surfaces))
    if unknown:
        raise ValueError(f"surfaces {unknown} are not in the model's {list(vocab.surfaces)}")


def add_player(model: SportsNGEN, vocab: Vocab, name: str):
    """-> (new model, new Vocab, identity index of `name`). Existing rows are copied unchanged;
    the new row starts from the generic identity. A player already known keeps their row."""
    if name in vocab.players:
        return model, vocab, vocab.player_index(name)
    new_vocab = vocab.with_player(name)
    # A generic model's other players stay generic (silently): they are unknown by design.
    unknown = "generic" if model.cfg.generic_identity or not vocab.players else model.cfg.unknown
    cfg = dataclasses.replace(model.cfg, n_ids=new_vocab.n_ids, generic_identity=False,
                              unknown=unknown)
    new = SportsNGEN(cfg)
    state = model.state_dict()
    old_w = state["embed.identity.weight"]
    state["embed.identity.weight"] = torch.cat([old_w, old_w[GENERIC_ID:GENERIC_ID + 1]])
    # A new player draws the heads' own serves and strikes, and his receivers start as the
    # model has them: a row at zero in every per-identity table.
    for key in SportsNGEN.PER_IDENTITY_TABLES:
        if state.get(key) is not None:
            state[key] = torch.cat([state[key], torch.zeros_like(state[key][:1])])
    new.load_state_dict(state)
    return new, new_vocab, new_vocab.player_index(name)


@torch.no_grad()
def average_generic_identity(model: SportsNGEN, vocab: Vocab) -> bool:
    """Set the generic identity row to the mean of the named players' rows, in place, for a
    model trained on named players (its generic row was never trained). A generic model
    (`generic_identity`, whose generic row is the trained one) or a vocabulary without players
    is left alone. -> whether the row was set."""
    if model.cfg.generic_identity or not vocab.players:
        return False
    w = model.embed.identity.weight
    w[GENERIC_ID] = w[N_SPECIAL_IDS:].mean(dim=0)
    return True


@torch.no_grad()
def graft_strike_head(model: SportsNGEN, donor: SportsNGEN) -> SportsNGEN:
    """`model` with `donor`'s strike head (`model.strike_head`, and its serve head where it
    has one): for two files fine-tuned from
    one base, each training other parts alone (`train_only`), so the strike head trained on
    one joins the other's parts (e.g. the ball's forecast and the players' head). Their shared
    trunk (the transformer blocks) must be identical, else the head was trained on another
    decoder and `ValueError` says so. -> a new model; neither argument changes."""
    if not donor.cfg.strike_head:
        raise ValueError("the donor model has no strike head (model.strike_head is off)")
    ours, theirs = model.state_dict(), donor.state_dict()
    trunk = [k for k in theirs if k.startswith("blocks.")]
    changed = [k for k in trunk if k not in ours or not torch.equal(ours[k], theirs[k])]
    if changed:
        raise ValueError(f"the two models' transformer blocks differ ({len(changed)} tensors, "
                         f"e.g. {changed[0]}): the strike head belongs to another decoder")
    # The donor's serve head, where it has one, comes with its strike head.
    new = SportsNGEN(dataclasses.replace(model.cfg, strike_head=True,
                                         serve_head=donor.cfg.serve_head or model.cfg.serve_head,
                                         strike_roles=donor.cfg.strike_roles,
                                         strike_shots=donor.cfg.strike_shots))
    shifts = ("strike_role.", "strike_shot.")
    ours = {k: v for k, v in ours.items() if not k.startswith(shifts)}
    state = {**ours, **{k: v for k, v in theirs.items()
                        if k.startswith(("strike_head.", "serve_head.") + shifts)}}
    new.load_state_dict(state)
    return new.eval()


def export_checkpoint(checkpoint: str | Path, out: str | Path, source: str | Path,
                      events_from: str | Path | None = None,
                      strike_head_from: str | Path | None = None,
                      average_identity: bool = False) -> Path:
    """A model file at `out` with the decoder of `checkpoint` (a training's decoder checkpoint,
    or a model file) and everything else (extras: serve starts, sampling defaults, split) from
    the model file `source`, the event classifier from `events_from` where given (a file whose
    g was retrained), the strike head from `strike_head_from` where given
    (`graft_strike_head`); `average_identity`: the generic identity row set to the players'
    mean (`average_generic_identity`). All must share the vocabulary. -> `out`."""
    model, _, vocab, _ = load_pretrained(checkpoint)
    events_from = events_from or source
    others = (source, events_from, *([strike_head_from] if strike_head_from else []))
    loaded = {other: load_model(other) for other in dict.fromkeys(others)}
    for other, (_, _, other_vocab, _) in loaded.items():
        if vocab.to_dict() != other_vocab.to_dict():
            raise SystemExit(f"{checkpoint} and {other} have different vocabularies")
    event_model = loaded[events_from][1]
    extra = read_extra(source)
    if strike_head_from:
        try:
            model = graft_strike_head(model, loaded[strike_head_from][0])
        except ValueError as exc:
            raise SystemExit(f"{strike_head_from}: {exc}") from exc
    if average_identity:
        average_generic_identity(model, vocab)
    save_model(out, model, vocab, event_model, extra=extra)
    print(f"wrote {out} (decoder of {checkpoint}; event classifier of {events_from}; "
          f"{sorted(extra)} of {source})")
    return Path(out)


@torch.no_grad()
def with_flag(model: SportsNGEN, flag: str, added: list[str]) -> SportsNGEN:
    """`model` with the boolean config `flag` turned on, whose new tensors (`added`, the
    state-dict keys) start as the model builds them and everything else is copied. -> a new
    model (the same one if the flag is on)."""
    if getattr(model.cfg, flag):
        return model
    new = SportsNGEN(dataclasses.replace(model.cfg, **{flag: True}))
    missing, unexpected = new.load_state_dict(model.state_dict(), strict=False)
    assert list(missing) == added and not unexpected, (missing, unexpected)
    return new.train(model.training)


def with_strike_roles(model: SportsNGEN) -> SportsNGEN:
    """`model` with the strike head's role shift added (`cfg.strike_roles`), at zero: it draws
    as before until the shift is fitted (`train.head_fit.fit_head`). -> a new model."""
    return with_flag(model, "strike_roles", ["strike_role.weight"])


def freeze_except_identity(model: SportsNGEN, rows: list[int]) -> None:
    """Freeze everything but the identity rows `rows` (gradients of other rows are zeroed)."""
    for p in model.parameters():
        p.requires_grad_(False)
    emb: nn.Embedding = model.embed.identity
    emb.weight.requires_grad_(True)
    keep = torch.zeros(emb.weight.shape[0], 1, dtype=emb.weight.dtype)
    keep[list(rows)] = 1.0
    emb.weight.register_hook(lambda g: g * keep.to(g.device))


def player_rallies(data: RallyData, player: str, n_sequences: int | None) -> RallyData:
    """The first `n_sequences` rallies (in table order) in which `player` serves or receives."""
    r = data.rallies
    ids = r.loc[(r["server"] == player) | (r["receiver"] == player), "rally_id"].tolist()
    if not ids:
        known = sorted(set(r["server"]) | set(r["receiver"]))
        raise ValueError(f"player {player!r} plays no rally in the data; players: {known[:20]}")
    return data.subset(ids[:n_sequences] if n_sequences else ids)


__all__ = ["add_player", "average_generic_identity", "check_data_matches", "freeze_except_identity",
           "load_pretrained", "player_rallies"]
