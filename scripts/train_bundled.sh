#!/usr/bin/env bash
# Train the bundled model and export it into the package (do not run casually: a long run).
#
#   scripts/train_bundled.sh                                   # CPU, conf defaults
#   scripts/train_bundled.sh trainer=gpu trainer.max_steps=20000   # any extra Hydra overrides
#
# Trains the `small` decoder f and its event classifier g on `synthetic_small` (generated once
# and cached under $SPORTSNGEN_CACHE or ~/.cache/sportsngen), checks the exported file stays
# under 40 MB, copies it to sportsngen/model/bundled/sportsngen-small.pt, then scores it on the
# held-out rallies. Everything the model card needs (command, time, hardware, figures) lands in
# the run folder: train.log, provenance.txt, heldout.md, heldout.json, summary.json.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/bundled/$(date -u +%Y%m%d-%H%M%S)}
DEST=sportsngen/model/bundled/sportsngen-small.pt
MAX_BYTES=$((40 * 1024 * 1024))
mkdir -p "$RUN"

cmd=("$PY" train.py data=synthetic_small model=small seed=0 events.enabled=true
     "hydra.run.dir=$RUN" "$@")
start=$(date +%s)
"${cmd[@]}" 2>&1 | tee "$RUN/train.log"
elapsed=$(( $(date +%s) - start ))

bytes=$(stat -c %s "$RUN/model.pt")
if [ "$bytes" -ge "$MAX_BYTES" ]; then
    echo "model file is $bytes bytes, over the 40 MB limit for the package" >&2
    exit 1
fi
mkdir -p "$(dirname "$DEST")"
cp "$RUN/model.pt" "$DEST"

{
    echo "command: scripts/train_bundled.sh $*"
    echo "train.py call: ${cmd[*]}"
    echo "commit: $(git rev-parse HEAD 2>/dev/null || echo unknown)"
    echo "wall time (train + events + export): ${elapsed} s"
    echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | xargs), $(nproc) cores"
    echo "gpu: $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1 || true)"
    echo "torch: $("$PY" -c 'import torch; print(torch.__version__)')"
    echo "file: $DEST, $bytes bytes"
} | tee "$RUN/provenance.txt"

"$PY" scripts/evaluate_model.py --model "$DEST" --json "$RUN/heldout.json" | tee "$RUN/heldout.md"
echo "done: copy the figures of $RUN into docs/model-card.md"
