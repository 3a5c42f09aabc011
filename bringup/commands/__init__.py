"""One module per `constellation` subcommand (see bringup/cli.py)."""
