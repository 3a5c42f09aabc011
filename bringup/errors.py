"""Errors a user can fix; the CLI prints them as one line without a traceback."""


class UserError(Exception):
    """Bad input from the user (a file, a flag, a bag): the message names what and where."""
