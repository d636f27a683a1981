"""``python -m addon ...``: the command-line entry (see cli.py)."""

from .cli import exit_process, main

exit_process(main())
