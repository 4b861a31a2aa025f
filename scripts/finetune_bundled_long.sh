#!/usr/bin/env bash
# Reproduce the bundled model from the one before it (commit f9317af, itself made by
# scripts/finetune_bundled.sh): two 700-step stages on generator version 6 with the ball's bins
# centred on one physics step and training windows of two model windows (12 s under the 6 s
# band mask, so the tokens past the window are trained as the cached rollout reads them), then
# the export: generic identity row averaged, sampling defaults, rally-outcome calibrator.
# About 28 minutes a stage at one thread, about 50 more for the calibrator (docs/model-card.md).
#
#   scripts/finetune_bundled_long.sh               # both stages, then export into the package
#   STAGES="2 export" scripts/finetune_bundled_long.sh   # from stage 1's folder on
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/bundled_long}
STAGES=${STAGES:-"1 2 export"}
DEST=sportsngen/model/bundled/sportsngen-small.pt
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show f9317af:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

common=(data=synthetic_small model=small init_ball_centre=physics
        windows.length_windows=2 windows.batch_size=8
        optim.contact_weight=10 optim.onset_weight=5 optim.lr=2e-4 optim.warmup_steps=50
        trainer.val_check_interval=350 threads=1 trainer.max_steps=700)
# stage: training seed (its data order) and the model file it starts from
declare -A SEED=([1]=1 [2]=3)
declare -A INIT=([1]="$BASE" [2]="$RUN/s1/model.pt")
for s in $STAGES; do
    [ "$s" = export ] && continue
    echo "+ stage $s"
    "$PY" train.py "${common[@]}" "seed=${SEED[$s]}" "init=${INIT[$s]}" \
        "hydra.run.dir=$RUN/s$s" 2>&1 | tail -n 5
done

if [[ " $STAGES " == *" export "* ]]; then
    # The stages never train the generic identity row (unknown players): the mean again.
    "$PY" scripts/export_checkpoint.py "$RUN/s2/model.pt" "$DEST" --from "$RUN/s2/model.pt" \
        --average-generic-identity
    "$PY" -c "from sportsngen.model.export import update_extra; update_extra('$DEST',
        sim_defaults={'top_p_player': 1.0, 'top_p_ball': 0.45, 'contact_odds': True})"
    "$PY" scripts/rally_outcome_study.py --rallies 250 --n 16 --threads 1 --save-calibrator
    echo "exported $DEST ($(stat -c %s "$DEST") bytes)"
fi
