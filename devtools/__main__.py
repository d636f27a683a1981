"""``python -m devtools ...``: the developer command-line entry (see cli.py)."""

import sys

from .cli import main

sys.exit(main())
