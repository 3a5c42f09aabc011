"""Errors a user can fix; the CLI prints them as one line without a traceback.

Checked by tests/unit/test_cli_exit.py (printed as one line, exit code 2).
"""


class UserError(Exception):
    """Bad input from the user (a file, a flag, a bag): the message names what and where."""
