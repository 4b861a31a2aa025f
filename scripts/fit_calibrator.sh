#!/usr/bin/env bash
# The bundled files' rally-outcome calibrator, refitted on a model file in place: 150 held-out
# rallies, 16 rollouts a branch point (docs/model-card.md). About 15 minutes at two threads.
#
#   scripts/fit_calibrator.sh MODEL
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: $0 MODEL" >&2; exit 2; }
"${PYTHON:-.venv/bin/python}" scripts/rally_outcome_study.py --model "$1" --rallies 150 --n 16 \
    --threads 2 --save-calibrator
