"""Export a decoder checkpoint as a model file, with another model file's event classifier and
extras (serve starts, simulation defaults, split).

    .venv/bin/python scripts/export_checkpoint.py CHECKPOINT OUT [--from MODEL_FILE]
        [--events-from MODEL_FILE] [--strike-head-from MODEL_FILE] [--average-generic-identity]

For a training stopped at a chosen checkpoint (`outputs/.../checkpoints_decoder/*.ckpt`, which
hold the decoder only): the decoder's weights from CHECKPOINT, everything else from --from
(default: the bundled model), the event classifier from --events-from when given (a model file
whose g was retrained: `train.py init=... trainer.max_steps=0 events.retrain=true`). All must
share the vocabulary. CHECKPOINT may also be a model file. `--average-generic-identity` sets the
generic identity row to the mean of the players' rows
(`sportsngen.train.finetune.average_generic_identity`, what training from scratch does), for a
model trained on named players whose generic row was never trained; not for a player fine-tuned
onto a generic model, whose generic row is the trained one. `--strike-head-from` adds the
strike head of another file fine-tuned from the same base with the rest frozen
(`sportsngen.train.finetune.graft_strike_head`; the two must share their transformer blocks).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sportsngen.model.export import load_model, read_extra, save_model
from sportsngen.sim.simulator import model_path
from sportsngen.train.finetune import average_generic_identity, graft_strike_head, load_pretrained


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--from", dest="source", type=Path, default=model_path())
    ap.add_argument("--events-from", type=Path, default=None)
    ap.add_argument("--strike-head-from", type=Path, default=None)
    ap.add_argument("--average-generic-identity", action="store_true")
    args = ap.parse_args()
    model, _, vocab, _ = load_pretrained(args.checkpoint)
    events_from = args.events_from or args.source
    others = (args.source, events_from, *([args.strike_head_from] if args.strike_head_from
                                          else []))
    loaded = {other: load_model(other) for other in dict.fromkeys(others)}
    for other, (_, _, other_vocab, _) in loaded.items():
        if vocab.to_dict() != other_vocab.to_dict():
            raise SystemExit(f"{args.checkpoint} and {other} have different vocabularies")
    event_model = loaded[events_from][1]
    extra = read_extra(args.source)
    if args.strike_head_from:
        try:
            model = graft_strike_head(model, loaded[args.strike_head_from][0])
        except ValueError as exc:
            raise SystemExit(f"{args.strike_head_from}: {exc}") from exc
    if args.average_generic_identity:
        average_generic_identity(model, vocab)
    save_model(args.out, model, vocab, event_model, extra=extra)
    print(f"wrote {args.out} (decoder of {args.checkpoint}; event classifier of {events_from}; "
          f"{sorted(extra)} of {args.source})")


if __name__ == "__main__":
    main()
