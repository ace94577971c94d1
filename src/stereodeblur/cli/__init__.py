"""The ``stereodeblur`` command line: parse, configure, call the library, write.

A leaf package: nothing in the library imports it. ``main`` is the console entry point
(``stereodeblur = "stereodeblur.cli:main"``); each command is a module with its parser
(``add_parser``) and its runner; :mod:`.settings_options` maps DeblurSettings to options and
back; :mod:`.printer` prints the progress reports. Bad input is one line on stderr with exit
code 2, never a traceback.
"""

from .base import EXIT_USAGE
from .main import build_parser, main

__all__ = ["EXIT_USAGE", "build_parser", "main"]
