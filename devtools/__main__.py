"""``python -m devtools ...``: the developer command-line entry (see cli.py)."""

from addon.cli import exit_process

from .cli import main

exit_process(main())
