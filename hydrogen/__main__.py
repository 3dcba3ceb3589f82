"""``python -m hydrogen ...``: the same as the ``hydrogen`` command."""
import sys

from .cli import main

sys.exit(main())
