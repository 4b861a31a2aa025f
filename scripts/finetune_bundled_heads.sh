#!/usr/bin/env bash
# Reproduce the bundled model from the one before it (commit dabb611, itself made by
# scripts/finetune_bundled_long.sh): its decoder frozen, three parts trained alone on generator
# version 6 and joined (docs/evaluation.md, fifteenth and sixteenth parts):
#   1. a strike head (model.strike_head: a rally strike drawn as where it lands, its height
#      over the net and its spin), 2,000 steps on 6 s windows;
#   2. the same head sharpened, 1,200 steps on 12 s windows;
#   3. the ball's flight forecast in the players' tokens (model.ball_forecast) with the
#      players' head, 700 steps on 12 s windows (2,100 lowered the players' held-out loss
#      further and made the checks worse: docs/evaluation.md, sixteenth part);
# then the export: stage 3's file with stage 2's strike head (the two share the frozen decoder),
# generic identity row averaged, sampling defaults, rally-outcome calibrator.
# As run: about 7, 9 and 16 minutes at the threads given (stage 3 beside other jobs), and
# about 40 for the calibrator.
#
#   scripts/finetune_bundled_heads.sh                       # every stage, then the export
#   STAGES="3 export" scripts/finetune_bundled_heads.sh     # from stage 2's folder on
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/bundled_heads}
STAGES=${STAGES:-"1 2 3 export"}
DEST=sportsngen/model/bundled/sportsngen-small.pt
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show dabb611:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

data=(data=synthetic_small model=small)
long=(windows.length_windows=2 windows.batch_size=8)
run() {   # stage folder, overrides...
    local dir=$1; shift
    echo "+ $dir"
    "$PY" train.py "${data[@]}" "$@" "hydra.run.dir=$RUN/$dir" 2>&1 | tail -n 5
}
for s in $STAGES; do
    case $s in
    1)  run s1 seed=5 "init=$BASE" init_strike_head=true train_only=strike_head optim.lr=1e-3 \
            optim.warmup_steps=50 trainer.val_check_interval=500 threads=2 trainer.max_steps=2000 ;;
    2)  run s2 seed=5 "init=$RUN/s1/model.pt" train_only=strike_head "${long[@]}" optim.lr=3e-4 \
            optim.warmup_steps=50 trainer.val_check_interval=400 threads=2 trainer.max_steps=1200 ;;
    3)  run s3 seed=1 "init=$BASE" init_ball_forecast=true train_only=forecast+player_head \
            optim.weight_decay=0.0 "${long[@]}" optim.contact_weight=10 optim.onset_weight=5 \
            optim.lr=5e-4 optim.warmup_steps=50 trainer.val_check_interval=350 threads=1 \
            trainer.max_steps=700 ;;
    export) ;;
    *)  echo "unknown stage $s" >&2; exit 2 ;;
    esac
done

if [[ " $STAGES " == *" export "* ]]; then
    "$PY" scripts/export_checkpoint.py "$RUN/s3/model.pt" "$DEST" --from "$RUN/s3/model.pt" \
        --strike-head-from "$RUN/s2/model.pt" --average-generic-identity
    "$PY" -c "from sportsngen.model.export import update_extra; update_extra('$DEST',
        sim_defaults={'top_p_player': 1.0, 'top_p_ball': 0.45, 'contact_odds': True,
                      'strike_in_reach': True, 'strike_in_reach_from': 2})"
    "$PY" scripts/rally_outcome_study.py --rallies 250 --n 16 --threads 1 --save-calibrator
    echo "exported $DEST ($(stat -c %s "$DEST") bytes)"
fi
