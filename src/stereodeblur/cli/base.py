"""What every command's parser shares: the parser class, exit codes and option types.

Option types raise :class:`argparse.ArgumentTypeError`, so a bad value ends as argparse's one
line ``stereodeblur <command>: error: argument --size: ...`` with exit code 2.
"""

from __future__ import annotations

import argparse
import math

# 2: the input or the arguments are at fault; 1: the run failed otherwise (a frame's
# computation, a full disk); 130: interrupted.
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

# Image sizes the synthetic scenes, the demo and the benchmarks accept: below 16 px the
# scene flow has no room for its windows, above 8192 px one float RGB frame is 800 MB.
MIN_SIDE = 16
MAX_SIDE = 8192


class Parser(argparse.ArgumentParser):
    """``argparse`` parser whose errors are one line with exit code 2.

    Options are matched by their whole name only (no abbreviations): a prefix such as
    ``--frame`` is not silently taken for ``--frames``.
    """

    def __init__(self, *args, allow_abbrev: bool = False, **kwargs):
        super().__init__(*args, allow_abbrev=allow_abbrev, **kwargs)

    def error(self, message):
        self.exit(EXIT_USAGE, f"stereodeblur: error: {message}\n")


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """``-q/--quiet``: no progress lines on stderr."""
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="print no progress lines on stderr; warnings and errors still show (default: off)",
    )


def size(text: str) -> tuple[int, int]:
    """Option type ``WIDTHxHEIGHT`` -> ``(width, height)``, each side in 16..8192."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT (e.g. 640x480), got {text!r}"
        ) from None
    if not (MIN_SIDE <= width <= MAX_SIDE and MIN_SIDE <= height <= MAX_SIDE):
        raise argparse.ArgumentTypeError(
            f"each side must be in {MIN_SIDE}..{MAX_SIDE} pixels, got {text!r}"
        )
    return width, height


def size_text(value: tuple[int, int]) -> str:
    """``(640, 480)`` -> ``'640x480'`` (a default for a size option)."""
    return f"{value[0]}x{value[1]}"


def sizes(text: str) -> tuple[tuple[int, int], ...]:
    """Option type: comma-separated ``WIDTHxHEIGHT`` sizes."""
    return tuple(size(part.strip()) for part in text.split(","))


def add_size(parser: argparse.ArgumentParser, default: tuple[int, int]) -> None:
    """``--size WIDTHxHEIGHT`` with a library default."""
    parser.add_argument(
        "--size", type=size, default=size_text(default), help="WIDTHxHEIGHT (default: %(default)s)"
    )


def add_sizes(parser: argparse.ArgumentParser, default) -> None:
    """``--sizes W1xH1,W2xH2,...`` with a library default (a sequence of sizes)."""
    parser.add_argument(
        "--sizes",
        type=sizes,
        default=",".join(map(size_text, default)),
        help="comma-separated WIDTHxHEIGHT (default: %(default)s)",
    )


def names(text: str) -> tuple[str, ...]:
    """Option type: comma-separated names (empty entries dropped)."""
    return tuple(part.strip() for part in text.split(",") if part.strip())


def integer(low: int, high: int | None = None):
    """Option type: an integer in ``low..high`` (no upper bound for None)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low or (high is not None and value > high):
            span = f">= {low}" if high is None else f"in {low}..{high}"
            raise argparse.ArgumentTypeError(f"must be {span}, got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def positive_number(text: str) -> float:
    """Option type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value
