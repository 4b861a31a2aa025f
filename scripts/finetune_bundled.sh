#!/usr/bin/env bash
# Reproduce the bundled model from its base: the stages of teacher-forced fine-tuning on
# generator version 6 (causal) data that made sportsngen-small.pt, then its event classifier
# retrained on the same data, its sampling defaults, rally-outcome calibrator and generic
# identity row. 14-20 minutes a stage at one thread (about 0.85 steps/s; 700 steps, stage 3
# 1,050), about 40 more for the calibrator; each stage resumes the last one's optimiser, so a
# stage can be stopped and run again alone (STAGES="4 5").
#
#   scripts/finetune_bundled.sh                 # every stage, then export into the package
#   STAGES="5" scripts/finetune_bundled.sh      # one stage (needs the earlier ones' folders)
#
# The base is the bundled model of commit 135bb07 (trained on generator versions 4 and 5, see
# docs/model-card.md); the stage boundaries are the ones the shipped model went through, stage
# 3 resuming stage 2 at step 1,050 as it did (a last.ckpt written before the fix that makes it
# the state a run ended in).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/bundled_v6}
STAGES=${STAGES:-"1 2 3 4 5"}
DEST=sportsngen/model/bundled/sportsngen-small.pt
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show 135bb07:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

common=(data=synthetic_small model=small seed=0 "init=$BASE" init_ball_centre=velocity
        optim.contact_weight=5 optim.onset_weight=5 optim.lr=2e-4 optim.warmup_steps=50
        trainer.val_check_interval=350 threads=1)
# stage: max steps, checkpoint resumed (empty: none)
declare -A STEPS=([1]=700 [2]=1400 [3]=2100 [4]=2800 [5]=3500)
declare -A FROM=([1]="" [2]="$RUN/s1/checkpoints_decoder/last.ckpt"
                 [3]="$RUN/s2/checkpoints_decoder/epoch=0-step=1050.ckpt"
                 [4]="$RUN/s3/checkpoints_decoder/last.ckpt"
                 [5]="$RUN/s4/checkpoints_decoder/last.ckpt")
LAST=5
for s in $STAGES; do
    extra=()
    [ -n "${FROM[$s]}" ] && extra+=("resume=${FROM[$s]}")
    echo "+ stage $s: to step ${STEPS[$s]}"
    "$PY" train.py "${common[@]}" "trainer.max_steps=${STEPS[$s]}" "${extra[@]}" \
        "hydra.run.dir=$RUN/s$s" 2>&1 | tail -n 5
done

if [[ " $STAGES " == *" $LAST "* ]]; then
    # The event classifier g on the same data (the base's was trained on versions 4 and 5).
    "$PY" train.py data=synthetic_small model=small seed=0 "init=$RUN/s$LAST/model.pt" \
        trainer.max_steps=0 events.retrain=true events.max_steps=800 threads=1 \
        "hydra.run.dir=$RUN/events" 2>&1 | tail -n 5
    cp "$RUN/events/model.pt" "$DEST"
    "$PY" -c "from sportsngen.model.export import update_extra; update_extra('$DEST',
        sim_defaults={'top_p_player': 1.0, 'top_p_ball': 0.45, 'contact_odds': True})"
    "$PY" scripts/rally_outcome_study.py --rallies 400 --n 16 --save-calibrator
    # The stages never train the generic identity row (unknown players): the mean again.
    cp "$DEST" "$RUN/before_generic.pt"
    "$PY" scripts/export_checkpoint.py "$RUN/before_generic.pt" "$DEST" \
        --from "$RUN/before_generic.pt" --average-generic-identity
    echo "exported $DEST ($(stat -c %s "$DEST") bytes)"
fi
