"""Input options shared by the commands that read a clip (``deblur``, ``synth average``)."""

from __future__ import annotations

import argparse

from .base import positive_number
from .printer import print_warnings

# The library parameter (``InputError.parameter``) behind each input option.
SOURCE_OPTIONS = {
    "calib": "--calib",
    "exposure": "--exposure",
    "frame_rate": "--frame-rate",
    "color": "--color",
    "sequence": "--sequence",
}


def add_source_options(parser: argparse.ArgumentParser) -> None:
    """``--calib``, ``--exposure``, ``--frame-rate``, ``--color``, ``--sequence``."""
    g = parser.add_argument_group("input (scene folder, KITTI folder, or LEFT_VIDEO RIGHT_VIDEO)")
    g.add_argument("--calib", help="stereo calibration of a video pair: OpenCV YAML or camera.json")
    g.add_argument(
        "--exposure", type=positive_number, help="exposure in seconds (if the input has none)"
    )
    g.add_argument(
        "--frame-rate", type=positive_number, help="frames per second (if the input has none)"
    )
    g.add_argument(
        "--color",
        choices=["linear", "srgb"],
        help="encoding of the input's values (default: the input's, else linear)",
    )
    g.add_argument("--sequence", help="KITTI 2012/2015 sequence number, e.g. 5 or 000005")


def source_spec(args: argparse.Namespace, *, require_exposure: bool = True):
    """The :class:`~stereodeblur.io.sources.SourceSpec` of ``args.source`` and its options."""
    from ..io.sources import SourceSpec

    return SourceSpec.from_arguments(
        args.source,
        calib=args.calib,
        exposure=args.exposure,
        frame_rate=args.frame_rate,
        color=args.color,
        sequence=args.sequence,
        require_exposure=require_exposure,
    )


def open_source(spec):
    """Open ``spec`` and print the input's warnings (e.g. videos of different lengths)."""
    source = spec.open()
    print_warnings(source.warnings)
    return source


def input_paths(spec) -> list[str]:
    """Every file and folder the source reads (for the output-safety check)."""
    return [*spec.paths, *([spec.calib] if spec.calib else [])]
