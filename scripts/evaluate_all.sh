#!/usr/bin/env bash
# Regenerate every figure and table behind docs/evaluation.md with the bundled model, in order
# (a few hours on 2 cores; each step prints its own figures and writes docs/figures/<study>/).
#
#   scripts/evaluate_all.sh            # everything
#   SKIP_TOP_P=1 scripts/evaluate_all.sh   # keep the model's stored default top-p
#
# The top-p sweep comes first because it stores the default top-p the other studies use. The
# prose of docs/evaluation.md quotes these outputs and is updated by hand after a run.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
run() { echo "+ $*"; "$@"; }

if [ -z "${SKIP_TOP_P:-}" ]; then
    run "$PY" scripts/top_p_sweep.py --points 60 --values 0.5 0.6 0.7 0.8 0.9 0.95 1.0 \
        --write-default
    # then the players' top-p alone, the ball's held at the value just chosen
    ball=$("$PY" -c "from sportsngen.model.export import read_extra; print(read_extra(
        'sportsngen/model/bundled/sportsngen-small.pt')['sim_defaults']['top_p_ball'])")
    run "$PY" scripts/top_p_sweep.py --points 60 --kind player --other "$ball" \
        --values 0.7 0.8 0.9 1.0 --write-default --out docs/figures/top_p_player
fi
run "$PY" scripts/check_simulation.py --points 500 --json docs/figures/check_simulation.json
run "$PY" scripts/check_simulation.py --points 500 --no-physical-limits \
    --json docs/figures/check_simulation_free.json
run "$PY" scripts/evaluation_report.py --points 100 --truth-points 1000 --seed 0
run "$PY" scripts/rally_outcome_study.py --rallies 400 --n 16 --save-calibrator
run "$PY" scripts/horizon_study.py --rallies 40 --n 4
run "$PY" scripts/counterfactual_demo.py --n 100
run "$PY" scripts/render_style_graphs.py --simulated outputs/eval/sportsngen_sim \
    --out docs/figures/style_sportsngen
run "$PY" scripts/render_style_graphs.py --out docs/figures/style
run "$PY" scripts/finetune_study.py --base bundled --player "Unseen M 002" --population-seed 200 \
    --work outputs/finetune_bundled --reuse
# The model studies train many tiny models (about 45 min together); results are cached in
# outputs/ and reused, so a second run only re-scores.
run "$PY" scripts/run_ablations.py --steps 800 --seeds 0 1 2
run "$PY" scripts/compare_heads.py --steps 2000 1000 --seeds 0 1 --seed-variants 2
