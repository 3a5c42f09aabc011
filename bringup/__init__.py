"""The application around the flight software: scenarios, the two engines, recording, analysis,
deployment files and the ``constellation`` command line (README "Layout"; DESIGN.md section 2)."""
