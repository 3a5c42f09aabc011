"""The application around the flight software: scenarios, the two engines, recording, analysis,
deployment files and the ``constellation`` command line (README "Layout"; docs/design.md section 2)."""


def __getattr__(name: str):
    """``bringup.__version__``: the project's version, from pyproject.toml in a source checkout or the
    installed distribution's metadata (bringup/scenario/provenance.py version)."""
    if name == "__version__":
        from bringup.scenario.provenance import version

        return version()
    raise AttributeError(f"module 'bringup' has no attribute {name!r}")
