#!/usr/bin/env bash
# The bundled files' rally-outcome calibrator, refitted on a model file in place: RALLIES
# held-out rallies (150), N rollouts a branch point (16) (docs/model-card.md). About 15 minutes
# at two threads with the defaults.
#
#   [SEEDS="0 1"] [RALLIES=200 N=32] [WORKERS=8 THREADS=1 CHUNK=32] [OUT=DIR] \
#       scripts/fit_calibrator.sh MODEL
#
# WORKERS processes share chunks of CHUNK branch points (the estimates then depend on CHUNK, not
# on WORKERS); CHUNK=0 (the default) rolls them out in one call, as the bundled files' were.
# CALIBRATOR (logistic, the default, or isotonic) is the kind of map stored, fitted on every
# branch point (docs/evaluation.md, twenty-ninth part: out of fold the isotonic map was worse
# than the raw rollouts). With several SEEDS each seed's held-out rallies are rolled out into
# OUT-seedS and the map is fitted on them pooled (OUT-pooled): one seed's map learns that
# sample's luck (docs/evaluation.md, seventy-fourth part). OUT defaults to docs/figures/outcome.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: $0 MODEL" >&2; exit 2; }
py="${PYTHON:-.venv/bin/python}"
out="${OUT:-docs/figures/outcome}"
read -r -a seeds <<< "${SEEDS:-0}"
common=(--model "$1" --rallies "${RALLIES:-150}" --calibrator "${CALIBRATOR:-logistic}")
study() {   # seed, out dir, extra options
    "$py" scripts/rally_outcome_study.py "${common[@]}" --n "${N:-16}" --seed "$1" \
        --workers "${WORKERS:-1}" --chunk-items "${CHUNK:-0}" --threads "${THREADS:-2}" \
        --out "$2" "${@:3}"
}
if [ "${#seeds[@]}" -eq 1 ]; then
    study "${seeds[0]}" "$out" --save-calibrator
    exit 0
fi
files=()
for s in "${seeds[@]}"; do
    study "$s" "$out-seed$s"
    files+=("$out-seed$s/branch_points.csv")
done
"$py" scripts/rally_outcome_study.py "${common[@]}" --seed "${seeds[0]}" --from-points \
    "${files[@]}" --kernel-n 0 --save-calibrator --out "$out-pooled"
