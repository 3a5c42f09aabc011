"""``python -m bringup.cli``: the ``constellation`` command line."""

from bringup.cli.main import entry

if __name__ == "__main__":
    entry()
