"""``python -m stereodeblur.cli``."""

from .main import run

run()
