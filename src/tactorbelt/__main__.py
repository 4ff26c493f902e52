"""``python -m tactorbelt``: the same as the ``tactorbelt`` command."""

from tactorbelt.cli import main

main()
