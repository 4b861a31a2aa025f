#!/usr/bin/env bash
# Reproduce the bundled model from the one before it (commit fc1703a, itself made by
# scripts/finetune_bundled_heads.sh): its decoder and every head frozen, a serve head
# (model.serve_head: a serve drawn as where it lands, its speed and its spin, the launch
# solved on the physics centre's flight) trained alone on generator version 6
# (docs/evaluation.md, eighteenth part):
#   1. 1,500 steps at lr 1e-3 on 6 s windows;
#   2. 2,500 more from stage 1's file, the same settings and another seed;
# then the export: stage 2's file, sampling defaults (the rule for balls in reach from the
# return on), rally-outcome calibrator. As run: about 5 and 9 minutes at two threads, and about
# 40 for the calibrator.
#
#   scripts/add_serve_head.sh                     # both stages, then the export
#   STAGES="export" scripts/add_serve_head.sh     # from stage 2's folder on
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/serve_head}
STAGES=${STAGES:-"1 2 export"}
DEST=sportsngen/model/bundled/sportsngen-small.pt
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show fc1703a:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

run() {   # stage folder, overrides...
    local dir=$1; shift
    echo "+ $dir"
    "$PY" train.py data=synthetic_small model=small "$@" train_only=serve_head optim.lr=1e-3 \
        optim.warmup_steps=50 trainer.val_check_interval=500 threads=2 \
        "hydra.run.dir=$RUN/$dir" 2>&1 | tail -n 5
}
for s in $STAGES; do
    case $s in
    1)  run s1 seed=5 "init=$BASE" init_serve_head=true trainer.max_steps=1500 ;;
    2)  run s2 seed=6 "init=$RUN/s1/model.pt" trainer.max_steps=2500 ;;
    export) ;;
    *)  echo "unknown stage $s" >&2; exit 2 ;;
    esac
done

if [[ " $STAGES " == *" export "* ]]; then
    cp "$RUN/s2/model.pt" "$DEST"
    "$PY" -c "from sportsngen.model.export import update_extra; update_extra('$DEST',
        sim_defaults={'top_p_player': 1.0, 'top_p_ball': 0.45, 'contact_odds': True,
                      'strike_in_reach': True, 'strike_in_reach_from': 1})"
    "$PY" scripts/rally_outcome_study.py --rallies 150 --n 16 --threads 2 --save-calibrator
    echo "exported $DEST ($(stat -c %s "$DEST") bytes)"
fi
