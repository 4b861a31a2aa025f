"""Match reports: one self-contained HTML file per match (win-probability timeline, key
moments, rallies, what-if shots, statistics), for simulated and recorded matches, and the
calibration back-test of the live win probability. `python -m sportsngen.report --help`.

Nothing here is imported by `import sportsngen`; the rally views need the tracking code (torch)
and are imported only when a report has rallies.
"""
