#!/usr/bin/env bash
# A model file's per-player tables refitted on the current generator's tracks, the decoder,
# the heads, the sampling defaults and the rally-outcome calibrator kept: the chain of
# docs/model-card.md's fifty-second to fifty-fourth parts, in their order, each stage reading
# the file the stage before wrote ($RUN/<stage>.pt). Run it after a generator version changes
# a named player's play (docs/evaluation.md, seventy-second part: version 6.4).
#   strike   the hitters', opponents' and returns' rally-error tables on the named players'
#            round robins, read 8 frames after each strike at four of the head's draws, then
#            the hitters' surfaces table on top (fit_strike_bias.py --pressure --surface;
#            about 15-25 minutes reading the states, a minute fitting)
#   reach    each receiver's reach for the return (fit_return_reach.py; about 4 minutes)
#   lateral  the serve head's lateral bands per server, each wide shift beside them
#            (fit_serve_bias.py --lateral; about 8 minutes)
#   top      each player's top running speed (fit_top_speed.py; about 1 minute)
#
#   scripts/refit_tables.sh BASE OUT                     # every stage, the last copied to OUT
#   STAGES="reach lateral top" scripts/refit_tables.sh BASE OUT   # from an earlier run's files
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 2 ] || { echo "usage: $0 BASE OUT" >&2; exit 2; }
PY=${PYTHON:-.venv/bin/python}
RUN=${RUN_DIR:-outputs/refit_tables}
STAGES=${STAGES:-"strike reach lateral top"}
mkdir -p "$RUN"
quiet() { tr '\r' '\n' | grep -v "it/s\|pt/s\|^$" || true; }
prev="$1"
last=""
for s in strike reach lateral top; do
    out="$RUN/$s.pt"
    case " $STAGES " in *" $s "*) ;; *) prev="$out"; continue ;; esac
    case $s in
    strike)   # the malloc setting keeps the read's memory flat (it grew past 24 GB without)
        MALLOC_MMAP_THRESHOLD_=65536 "$PY" scripts/fit_strike_bias.py --model "$prev" \
            --more-data synthetic_named --more-data-only --pressure --view 8 --draws 4 \
            --surface --states "$RUN/strike_states.pt" --out "$out" --threads 2 2>&1 | quiet ;;
    reach)
        "$PY" scripts/fit_return_reach.py --model "$prev" --more-data synthetic_named \
            --out "$out" 2>&1 | quiet ;;
    lateral)
        "$PY" scripts/fit_serve_bias.py --model "$prev" --more-data synthetic_named \
            --lateral --out "$out" --threads 2 2>&1 | quiet ;;
    top)
        "$PY" scripts/fit_top_speed.py --model "$prev" --more-data synthetic_named \
            --out "$out" 2>&1 | quiet ;;
    esac
    prev="$out"
    last="$out"
done
[ -n "$last" ] || { echo "no stage of $STAGES is known" >&2; exit 2; }
cp "$last" "$2"
echo "$2: $(stat -c %s "$2") bytes"
