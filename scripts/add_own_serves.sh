#!/usr/bin/env bash
# Reproduce the bundled model from the one before it (commit 0b2b131, itself made by
# scripts/add_strike_roles.sh): its decoder and every other head frozen, the serve head refitted
# alone on the decoder's states at the recorded serves of its own training split (with the
# training's turned windows) and at the serves the model plays from its own tosses for the
# same points, each paired with the record's serve (sportsngen.train.own_states;
# docs/evaluation.md, twenty-first part). 3,000 steps at lr 3e-4, kept at the best validation
# NLL. Then the sampling defaults: FORCE=1 adds the forced strike where the rule for balls in
# reach gives up (strike_in_reach_force), and the rule's reach is REACH metres (1.5, the
# generator's players' reach; docs/evaluation.md, twenty-third part). Then the per-server
# shifts of the serve head's odds of a long and a wide serve (scripts/fit_serve_bias.py on the
# training split's serves and those of conf/data/synthetic_named.yaml; twenty-fourth part).
# Then the rally-outcome calibrator refitted on the new file (200 rallies, 32 rollouts each, in
# chunks of CHUNK=32 branch points over WORKERS=2 processes of one thread; twenty-fifth part).
# As run: about 10 minutes at two threads for the fit, 5 for the shifts, 21 for the
# calibrator. The stage `receiver`, not among the
# defaults and not in the bundled file, adds the per-server start time of the receivers
# (scripts/fit_receiver_start.py; docs/evaluation.md, twenty-fifth part: no check statistic
# moved). The stage `contact` adds the shifts of the ball's odds of a contact by where it is
# from its hitter (scripts/fit_contact_reach.py on the training split, 6 minutes), and `chase`
# stores the rule that a player late for the ball does not slow down (keep_chasing). Since the
# twenty-seventh part the bundled file is the twenty-sixth part's (commit 92f6781's, itself
# this script's default stages) with those two and the calibrator refitted:
#   git show 92f6781:sportsngen/model/bundled/sportsngen-small.pt > x.pt
#   DEST=x.pt STAGES="contact chase calibrator" scripts/add_own_serves.sh
# (twenty-eighth part: the rule behind keep_chasing changed in the code, so at that commit the
# same command gives the bundled file; as run, the stage calibrator alone on the file before.)
# The stage `refresh` stores refresh_frames=REFRESH (25): past the model's window the rollout
# re-reads the last window every REFRESH frames, training's view (twenty-ninth part); since then
#   DEST=x.pt STAGES="contact chase refresh calibrator" scripts/add_own_serves.sh
#
#   scripts/add_own_serves.sh                     # the fit, defaults and shifts, then the calibrator
#   STAGES="fit bias" scripts/add_own_serves.sh   # the fit, defaults and shifts only
#   DEST=other.pt RUN_DIR=dir scripts/add_own_serves.sh   # elsewhere than the bundled file
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/own_serves}
DEST=${DEST:-sportsngen/model/bundled/sportsngen-small.pt}
FORCE=${FORCE:-1}
REACH=${REACH:-1.5}
STAGES=${STAGES:-"fit bias calibrator"}
WORKERS=${WORKERS:-2}
CHUNK=${CHUNK:-32}
REFRESH=${REFRESH:-25}
mkdir -p "$RUN"
BASE="$RUN/base.pt"
[ -f "$BASE" ] || git show 0b2b131:sportsngen/model/bundled/sportsngen-small.pt > "$BASE"

for s in $STAGES; do
    case $s in
    fit)
        "$PY" scripts/fit_head.py --model "$BASE" --head serve --own-serves --steps 3000 \
            --lr 3e-4 --eval-every 250 --threads 2 --out "$DEST" 2>&1 | grep -v "it/s"
        if [ "$FORCE" = 1 ]; then
            "$PY" scripts/set_sim_defaults.py "$DEST" strike_in_reach_force=true
        fi
        "$PY" scripts/set_sim_defaults.py "$DEST" strike_in_reach_m="$REACH"
        ;;
    bias)
        "$PY" scripts/fit_serve_bias.py --model "$DEST" --more-data synthetic_named \
            --out "$DEST" 2>&1 | grep -v "it/s"
        ;;
    receiver)
        "$PY" scripts/fit_receiver_start.py --model "$DEST" --more-data synthetic_named \
            --out "$DEST" 2>&1 | grep -v "it/s"
        ;;
    contact)
        "$PY" scripts/fit_contact_reach.py --model "$DEST" --out "$DEST" 2>&1 \
            | grep -v "it/s"
        ;;
    chase)
        "$PY" scripts/set_sim_defaults.py "$DEST" keep_chasing=true
        ;;
    refresh)
        "$PY" scripts/set_sim_defaults.py "$DEST" refresh_frames="$REFRESH"
        ;;
    calibrator)
        RALLIES=200 N=32 WORKERS="$WORKERS" CHUNK="$CHUNK" THREADS=1 PYTHON="$PY" \
            scripts/fit_calibrator.sh "$DEST" ;;
    *)  echo "unknown stage $s" >&2; exit 2 ;;
    esac
done
echo "$DEST: $(stat -c %s "$DEST") bytes"
