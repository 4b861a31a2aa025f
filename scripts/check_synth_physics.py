"""Physical sanity of generated tracking, per surface (`sportsngen.eval.synth_physics`): toss
height, ball against ground and net cord, players' speed and acceleration, bounce speed ratio.

    python scripts/check_synth_physics.py     # 600 points a surface, ~15 s
"""

from __future__ import annotations

from sportsngen.eval.synth_physics import check_synth_physics

if __name__ == "__main__":
    check_synth_physics()
