"""``python -m maniskill_tidy.cli``."""

import sys

from maniskill_tidy.cli import main

sys.exit(main())
