"""Scenario set-up: the TOML files and their validation, the world a run derives from them, and
which participants a run has."""
