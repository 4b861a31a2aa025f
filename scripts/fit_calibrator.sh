#!/usr/bin/env bash
# The bundled files' rally-outcome calibrator, refitted on a model file in place: RALLIES
# held-out rallies (150), N rollouts a branch point (16) (docs/model-card.md). About 15 minutes
# at two threads with the defaults.
#
#   [RALLIES=200 N=32] scripts/fit_calibrator.sh MODEL
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: $0 MODEL" >&2; exit 2; }
"${PYTHON:-.venv/bin/python}" scripts/rally_outcome_study.py --model "$1" \
    --rallies "${RALLIES:-150}" --n "${N:-16}" --threads 2 --save-calibrator
