"""The ``constellation`` command line: the registry (main.py) and one thin module per subcommand."""
