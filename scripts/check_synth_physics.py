"""Physical sanity of generated tracking, per surface (`sportsngen.eval.synth_physics`).

Toss contact height, the ball never below its radius nor through the net cord, players' peak
speed and acceleration, and the median ball speed ratio after/before a bounce.

    python scripts/check_synth_physics.py     # 600 points a surface, ~15 s
"""

from __future__ import annotations

from sportsngen.eval.synth_physics import check_synth_physics

if __name__ == "__main__":
    check_synth_physics()
