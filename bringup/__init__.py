"""The application around the flight software: scenarios, the two engines, recording, analysis,
deployment files and the ``constellation`` command line (README "Layout"; docs/design.md section 2)."""
