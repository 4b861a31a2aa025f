#!/usr/bin/env bash
# The bundled file refitted on generator version 6.2's tracks (docs/evaluation.md, thirtieth
# part): the file before (commit 4fc8842's) read on the new tracks of its own data config, its
# heads first, then the decoder, then the heads and tables that read the decoder's states again.
# Stages, in order (STAGES to run some; each writes $RUN/<stage>.pt from the one before):
#   strike   the strike head alone on its frozen decoder's states (fit_head.py, 8,000 steps)
#   serve1   the serve head alone, recorded serves and the model's own tosses (--own-serves)
#   bias1    the per-server serve shifts (fit_serve_bias.py)
#   decoder  700 steps of train.py on 12 s windows, every part but the serve head
#            (train_only), the split's seed 7; the sampling defaults and calibrator copied
#            back from the file before (export_checkpoint.py --from would also bring back its
#            split and its version 6.1 serve starts, where train.py wrote the new data's)
#   serve2   the serve head again on the new decoder's states (it served 5-9 points more
#            first serves in without it)
#   bias2    the shifts again
#   contact  the contact table again (fit_contact_reach.py)
#   calibrator  the rally-outcome calibrator (200 rallies, 32 rollouts; about 40 minutes)
# As run: 9 + 1, 6, 3, 9, 5, 3, 8 minutes at two threads before the calibrator.
#
#   scripts/refit_bundled_v62.sh                 # all stages, then copies the file to DEST
#   STAGES="contact calibrator" scripts/refit_bundled_v62.sh   # DEST gets the last stage run's file
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/refit_v62}
DEST=${DEST:-sportsngen/model/bundled/sportsngen-small.pt}
STAGES=${STAGES:-"strike serve1 bias1 decoder serve2 bias2 contact calibrator"}
mkdir -p "$RUN"
[ -f "$RUN/base.pt" ] || git show 4fc8842:sportsngen/model/bundled/sportsngen-small.pt \
    > "$RUN/base.pt"
quiet() { tr '\r' '\n' | grep -v "it/s\|^$" || true; }
# each stage reads the file the stage before it writes (the calibrator refits contact.pt)
prev="$RUN/base.pt"
last=""
for s in strike serve1 bias1 decoder serve2 bias2 contact calibrator; do
    out="$RUN/$s.pt"
    [ "$s" = calibrator ] && out="$prev"
    case " $STAGES " in *" $s "*) ;; *) prev="$out"; continue ;; esac
    case $s in
    strike)
        "$PY" scripts/fit_head.py --model "$prev" --head strike --steps 8000 --lr 3e-4 \
            --eval-every 1000 --threads 2 --states "$RUN/strike_states.pt" --out "$out" 2>&1 | quiet ;;
    serve1|serve2)
        "$PY" scripts/fit_head.py --model "$prev" --head serve --own-serves --steps 3000 \
            --lr 3e-4 --eval-every 250 --threads 2 --states "$RUN/${s}_states.pt" \
            --out "$out" 2>&1 | quiet ;;
    bias1|bias2|contact)      # the same stages of add_own_serves.sh, on a copy
        cp "$prev" "$out"
        DEST="$out" RUN_DIR="$RUN/own" STAGES="${s%[12]}" PYTHON="$PY" \
            scripts/add_own_serves.sh 2>&1 | quiet ;;
    decoder)
        "$PY" train.py data=synthetic_small model=small init="$prev" windows.length_windows=2 \
            windows.batch_size=8 optim.contact_weight=10 optim.onset_weight=5 optim.lr=2e-4 \
            optim.warmup_steps=50 trainer.val_check_interval=350 threads=2 \
            trainer.max_steps=700 seed=7 \
            "train_only=blocks+ball_head+embed+player_head+context+ln_f+strike_head+strike_role" \
            hydra.run.dir="$RUN/decoder" 2>&1 | quiet
        cp "$RUN/decoder/model.pt" "$out"
        "$PY" -c "import sys
from sportsngen.model.export import read_extra, update_extra
e = read_extra(sys.argv[1])
update_extra(sys.argv[2], sim_defaults=e['sim_defaults'],
             outcome_calibrator=e['outcome_calibrator'])" "$prev" "$out" ;;
    calibrator)
        DEST="$out" RUN_DIR="$RUN/own" STAGES=calibrator PYTHON="$PY" scripts/add_own_serves.sh ;;
    esac
    prev="$out"
    last="$out"
done
[ -n "$last" ] || { echo "no stage of $STAGES is known" >&2; exit 2; }
cp "$last" "$DEST"     # the last stage run
echo "$DEST: $(stat -c %s "$DEST") bytes"
