"""Simulation with the learned engine: rollouts, rally rules, event labels, matches.

    from sportsngen.sim import Simulator
    sim = Simulator.from_pretrained()
"""

from sportsngen.sim.match import MatchResult
from sportsngen.sim.simulator import Simulator

__all__ = ["MatchResult", "Simulator"]
