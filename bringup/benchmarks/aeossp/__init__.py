"""AstroReason-Bench ``aeossp_standard``: read a case, check a solution, plan one.

- :mod:`.case`: the case files (mission.yaml, satellites.yaml, tasks.yaml) as typed objects.
- :mod:`.geometry`: SGP4 of the case TLEs, off-nadir, visibility, slew law, sun and shadow.
- :mod:`.check`: our own feasibility check and the metrics WCR, CR, TAT, PC.
- :mod:`.planner`: the per-satellite DP (onboard / central) and a greedy-by-weight baseline.

The user's page is docs/guide/aeossp.md.
"""
