"""A fixed BPSec key for the tests that build satellites or bundle agents themselves.

Runs through the CLI or the launcher take the deployment's key or one generated for the run
(bringup/engine/keys.py); these tests need one key shared by every agent they build.
"""

TEST_BPSEC_KEY = bytes.fromhex("5e" * 32)
