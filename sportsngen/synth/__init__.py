"""Synthetic tennis tracking: ball physics, player profiles, shot-cycle behaviour, rallies, matches.

Entry points: `generate_matches` (tracking data as `RallyData`), `service_points` (points table
only, fast), `named_profiles` / `get_profile` / `sample_population` (players), and
`sportsngen.synth.dataset.load_synthetic` (config-driven, cached on disk).
"""

from sportsngen.synth.generate import generate_matches, resolve_matchups, service_points
from sportsngen.synth.profiles import (
    PlayerProfile,
    average_profile,
    get_profile,
    named_profiles,
    sample_population,
)

__all__ = [
    "PlayerProfile",
    "average_profile",
    "generate_matches",
    "get_profile",
    "named_profiles",
    "resolve_matchups",
    "sample_population",
    "service_points",
]
