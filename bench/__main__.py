"""``python -m bench`` — the levelset-bench command line."""

import sys

from .cli import main

sys.exit(main())
