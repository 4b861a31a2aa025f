#!/usr/bin/env bash
# The bundled files' rally-outcome calibrator, refitted on a model file in place: RALLIES
# held-out rallies (150), N rollouts a branch point (16) (docs/model-card.md). About 15 minutes
# at two threads with the defaults.
#
#   [RALLIES=200 N=32] [WORKERS=8 THREADS=1 CHUNK=32] scripts/fit_calibrator.sh MODEL
#
# WORKERS processes share chunks of CHUNK branch points (the estimates then depend on CHUNK, not
# on WORKERS); CHUNK=0 (the default) rolls them out in one call, as the bundled files' were.
# CALIBRATOR (logistic, the default, or isotonic) is the kind of map stored, fitted on every
# branch point (docs/evaluation.md, twenty-ninth part: out of fold the isotonic map was worse
# than the raw rollouts).
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: $0 MODEL" >&2; exit 2; }
"${PYTHON:-.venv/bin/python}" scripts/rally_outcome_study.py --model "$1" \
    --rallies "${RALLIES:-150}" --n "${N:-16}" --workers "${WORKERS:-1}" \
    --chunk-items "${CHUNK:-0}" --threads "${THREADS:-2}" \
    --calibrator "${CALIBRATOR:-logistic}" --save-calibrator
