"""Public scheduling benchmarks the project's planner is run on (each in a package of its own).

- :mod:`bringup.benchmarks.aeossp`: AstroReason-Bench ``aeossp_standard`` cases (agile EO satellites
  with TLEs, slew, settle and battery), docs/guide/aeossp.md.
"""
