"""The ``stereodeblur`` command: one parser per command, errors as one line: exit code 2 for
bad input, 1 for an output's storage that refuses writes (a full disk)."""

from __future__ import annotations

import atexit
import os
import sys

from ..errors import InputError, StorageError
from .base import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_USAGE, Parser
from .bench import add_parser as add_bench
from .deblur import add_parser as add_deblur
from .demo import add_parser as add_demo
from .kernels import add_parser as add_kernels
from .render_view import add_parser as add_render_view
from .sceneflow import add_parser as add_sceneflow
from .settings_options import option_for
from .synth import add_parser as add_synth

# Each adds its command's parser (and the function that runs it) to the subparsers.
COMMANDS = (
    add_deblur, add_sceneflow, add_demo, add_synth, add_render_view, add_kernels, add_bench
)  # fmt: skip
# Errors that mean "the input is not what was expected": one line, exit code 2.
INPUT_ERRORS = (InputError, FileNotFoundError, NotADirectoryError, IsADirectoryError)


def build_parser() -> Parser:
    """The parser of every command (each command module adds its own)."""
    parser = Parser(
        prog="stereodeblur",
        description="Remove motion blur from rectified stereo video "
        "(Sellent, Rother, Roth, ECCV 2016).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add_parser in COMMANDS:
        add_parser(sub)
    return parser


def _version() -> str:
    from .. import __version__

    return __version__


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exit:  # --help, --version, usage errors (already printed)
        return exit.code if isinstance(exit.code, int) else EXIT_USAGE
    args.argv = argv
    try:
        return args.func(args)
    except INPUT_ERRORS as err:
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        option = option_for(err.parameter) if isinstance(err, InputError) else None
        if option is not None:  # library errors name parameters; point at the option
            message += f" (option {option})"
        print(f"stereodeblur: error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except StorageError as err:  # not the input's fault: the run failed, exit 1
        print(f"stereodeblur: error: {err}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("stereodeblur: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # stdout closed early (e.g. piped into head): stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


def run() -> None:
    """``python -m stereodeblur.cli``: :func:`main`'s exit code as the process's exit status.

    An interrupted run exits with 130 once the exit handlers have run. Under ``-m``, CPython
    would end the process by SIGINT instead whenever a KeyboardInterrupt had left an ``exec``
    of a string (dataclass and namedtuple creation, numba's compiler), though caught later.
    """
    code = main()
    if code == EXIT_INTERRUPTED:
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)
