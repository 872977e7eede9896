"""``python -m livox_viz``: the command line."""

import sys

from .cli import main

sys.exit(main())
