"""``python -m addon ...``: the command-line entry (see cli.py). Ctrl-C is taken over before
anything slow is imported (interrupts.py)."""

from .interrupts import interrupts

interrupts.start()

from .cli import exit_process, main  # noqa: E402  (after the interrupts: it imports numpy)

exit_process(main())
