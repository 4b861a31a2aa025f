#!/usr/bin/env bash
# Reproduce the bundled model from the one before it (commit 43eca70, itself made by
# scripts/add_serve_head.sh): its decoder and every other head frozen, the strike head refitted
# alone on the decoder's states at the rally strikes of its own training split (read once,
# with the training's turned windows), its input shifted by whose strike it is and the
# point's serve (model.strike_roles: the server's or the receiver's, first or second serve),
# the shift fitted with it (docs/evaluation.md, twentieth part). 6,000 steps at lr 3e-4, kept
# at the best validation NLL. Then the rally-outcome calibrator refitted on the new file.
# As run: about 10 minutes to read the states at two threads (kept in $RUN/strike_states.pt),
# under a minute to fit, about 25 for the calibrator.
#
#   scripts/add_strike_roles.sh                   # the fit, then the calibrator
#   STAGES="fit" scripts/add_strike_roles.sh      # the fit only
#   DEST=other.pt RUN_DIR=dir scripts/add_strike_roles.sh   # elsewhere than the bundled file
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/strike_roles}
STAGES=${STAGES:-"fit calibrator"}
DEST=${DEST:-sportsngen/model/bundled/sportsngen-small.pt}
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show 43eca70:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

for s in $STAGES; do
    case $s in
    fit)
        "$PY" scripts/fit_head.py --model "$BASE" --head strike --strike-roles --steps 6000 \
            --lr 3e-4 --eval-every 500 --threads 2 --states "$RUN/strike_states.pt" \
            --out "$DEST" 2>&1 | grep -v "it/s"
        ;;
    calibrator) PYTHON="$PY" scripts/fit_calibrator.sh "$DEST" ;;
    *)  echo "unknown stage $s" >&2; exit 2 ;;
    esac
done
echo "$DEST: $(stat -c %s "$DEST") bytes"
