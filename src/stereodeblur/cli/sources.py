"""Input options shared by the commands that read a clip (``deblur``, ``sceneflow``,
``synth average``): the source, its timing and colour, and the frame selection."""

from __future__ import annotations

import argparse

from ..errors import InputError
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

SOURCE_HELP = "input: a scene folder, a KITTI 2012/2015/raw folder, or two videos LEFT RIGHT"
FRAMES_SYNTAX = (
    "one frame '5', a list '1,3' or half-open ranges '10:200' ('4:' to the last), in the "
    "source's own numbers: a scene's or a video's from 0, a KITTI raw drive's file numbers, "
    "KITTI 2012/2015's frame numbers in the sequence (10, 11 for the image pairs); results "
    "keep the source's frame names"
)

# What the exposure time is when neither the source nor --exposure gives one.
_NO_EXPOSURE = {
    True: ", else 'auto': estimated per frame from the blurred frames (KITTI, a video whose "
    "calibration has none)",
    False: ", else 0: frames taken as sharp",
}
AUTO = "auto"


def exposure_value(text: str) -> float | str:
    """Option type of ``deblur --exposure``: a number > 0 or 'auto'."""
    return AUTO if text == AUTO else positive_number(text)


def add_source_argument(parser: argparse.ArgumentParser) -> None:
    """The positional ``source``: one folder, or two video files."""
    parser.add_argument("source", nargs="+", help=SOURCE_HELP + " (with --calib)")


def add_frames_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--frames``: the frames ``what`` (e.g. 'to deblur'), in :func:`select_frames`' syntax."""
    parser.add_argument("--frames", help=f"frames {what}: {FRAMES_SYNTAX} (default: every frame)")


def add_source_options(parser: argparse.ArgumentParser, *, require_exposure: bool = True) -> None:
    """``--calib``, ``--exposure``, ``--frame-rate``, ``--color``, ``--sequence``.

    ``require_exposure``: whether the command needs an exposure time (as
    :meth:`SourceSpec.from_arguments <stereodeblur.io.sources.SourceSpec.from_arguments>`);
    the help of ``--exposure`` says what happens without one.
    """
    g = parser.add_argument_group(
        "input (scene folder, KITTI folder, or LEFT_VIDEO RIGHT_VIDEO)",
        "A value given here overrides the one the source states.",
    )
    g.add_argument(
        "--calib",
        metavar="FILE",
        help="stereo calibration of a video pair: OpenCV YAML (P1, P2 or Q) or camera.json; "
        "for an unrectified rig, whose frames are rectified on reading: OpenCV YAML with M1, "
        "D1, M2, D2, R, T, a Kalibr camchain.yaml, or a folder with ROS left.yaml and "
        "right.yaml (no default: a video pair needs it; folders hold their own calibration "
        "and refuse it)",
    )
    g.add_argument(
        "--exposure",
        type=exposure_value if require_exposure else positive_number,
        metavar="SECONDS|auto" if require_exposure else "SECONDS",
        help="exposure time in seconds"
        + (", or 'auto': estimated per frame from the blurred frames" if require_exposure else "")
        + f"; overrides the one the source states (default: the source's"
        f"{_NO_EXPOSURE[require_exposure]})",
    )
    g.add_argument(
        "--frame-rate",
        type=positive_number,
        metavar="FPS",
        help="frames per second; overrides the source's (default: the source's: a scene's "
        "camera.json, a video's container or calibration, 10 for KITTI 2012/2015, a KITTI raw "
        "drive's timestamps)",
    )
    g.add_argument(
        "--color",
        choices=["linear", "srgb"],
        help="encoding of the input's values; frames are deblurred in linear light and written "
        "back in this encoding (default: a scene folder's camera.json, linear if it has no "
        "'color'; sRGB for KITTI and videos, unless a camera.json given with --calib says)",
    )
    g.add_argument(
        "--sequence",
        metavar="N",
        help="KITTI 2012/2015 sequence number, e.g. 5 or 000005 (default: the folder's only "
        "sequence; a folder holding several needs it)",
    )


def source_spec(args: argparse.Namespace, *, require_exposure: bool = True):
    """The :class:`~stereodeblur.io.sources.SourceSpec` of ``args.source`` and its options
    (``--exposure auto``: the source's exposure is not needed)."""
    from ..io.sources import SourceSpec

    auto = args.exposure == AUTO
    return SourceSpec.from_arguments(
        args.source,
        calib=args.calib,
        exposure=None if auto else args.exposure,
        frame_rate=args.frame_rate,
        color=args.color,
        sequence=args.sequence,
        require_exposure=require_exposure and not auto,
    )


def open_source(spec):
    """Open ``spec`` and print the input's warnings (e.g. videos of different lengths)."""
    source = spec.open()
    print_warnings(source.warnings)
    return source


def input_paths(spec) -> list[str]:
    """Every file and folder the source reads (for the output-safety check)."""
    return [*spec.paths, *([spec.calib] if spec.calib else [])]


def select_frames(text: str | None, source):
    """The indices of the frames ``--frames`` selects, in ``source``'s own numbers, checked
    against the clip (before the selection is expanded); every frame for None."""
    from ..clip.frames import parse_frames

    try:
        return parse_frames(text, source.num_frames, first=source.numbering.first)
    except InputError as err:
        raise InputError(f"--{err}") from None
