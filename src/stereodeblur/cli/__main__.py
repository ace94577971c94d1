"""``python -m stereodeblur.cli``."""

import sys

from .main import main

sys.exit(main())
