"""DeblurSettings <-> command-line options: the one place that maps one to the other.

:data:`OPTIONS` lists, per :class:`~stereodeblur.settings.DeblurSettings` field, its option;
the option's default is the field's default. :func:`add_settings_options` adds options to a
parser, :func:`settings_from_arguments` builds the settings from parsed arguments and
:func:`arguments_for` gives the options that reproduce given settings.

Limits (``stereodeblur.settings``, which ``DeblurSettings`` also checks), checked by the option
types before anything is read or allocated:

- ``--samples`` in 2..1000. One sample is the frame's centre instant alone, an identity
  "blur" that returns the input, so a blur needs at least 2. Building the operator costs
  memory in proportion to samples x pixels (each sample adds 4 bilinear or 16 cubic weights
  per pixel before they are merged); 1000, 14 times the paper's N = 70, is past any gain.
- ``--irls`` and ``--cg`` in 1..1000: 0 iterations return the input unchanged; each IRLS
  iteration keeps its weights (one float per pixel).
- ``--alpha`` ``held-out``, ``auto``, ``cross-view`` or in (0, 1]: the prior weight of Eq. 6
  for images in [0, 1]; at 1 the prior already outweighs the data term, beyond it the result
  is flat.
- ``--segments`` in 1..100000 superpixels.
- ``--relabel-radius`` in 0..100 px: past the size of a superpixel the window holds segments of
  far-away surfaces.

Every option's help states its default, taken from the DeblurSettings field (``%(default)s``,
or :func:`on_off` for a switch), and the paper's value where the option has one.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from ..settings import ALPHA_MAX, ALPHA_RULES, PAPER_ALPHA, PAPER_CG, PAPER_IRLS, RANGE_WHOLE
from ..settings import ITERATIONS_RANGE as ITERATIONS
from ..settings import RELABEL_RANGE as RELABEL
from ..settings import SAMPLES_RANGE as SAMPLES
from ..settings import SEGMENTS_RANGE as SEGMENTS
from .base import integer


def _settings_module():
    from .. import settings

    return settings


_RULES = ", ".join(f"'{r}'" for r in ALPHA_RULES)


def alpha(text: str) -> float | str:
    """Option type of ``--alpha``: a rule of :data:`ALPHA_RULES` or a number in (0, 1]."""
    if text in ALPHA_RULES:
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {_RULES} or a number, got {text!r}") from None
    if not 0 < value <= ALPHA_MAX:
        raise argparse.ArgumentTypeError(f"must be {_RULES} or in (0, {ALPHA_MAX:g}], got {text!r}")
    return value


def on_off(value: bool) -> str:
    """A switch's state in a help text: ``'on'`` or ``'off'``."""
    return "on" if value else "off"


# The superpixel count of the scene flow when --segments is not given (a rule, not a number:
# stereodeblur.sceneflow.from_gt.default_num_segments; tests/cli/test_help.py checks the two agree).
SEGMENTS_RULE = "about 1200 at 640x480, scaled with the image area"


@dataclass(frozen=True)
class SettingOption:
    """The option of one DeblurSettings field."""

    field: str
    flag: str
    help: str  # a switch's help ends before its default, which is appended: "(default: on)"
    type: Callable[[str], object] | None = None
    choices: tuple[str, ...] | None = None
    metavar: str | None = None
    switch: bool = False  # a True/False field: --flag and --no-flag


def _options() -> tuple[SettingOption, ...]:
    s = _settings_module()
    return (*_paper_options(s), *_refinement_options(s))


def _paper_options(s) -> tuple[SettingOption, ...]:
    """The switches of the paper's method: kernels, motion, samples, prior weight, data terms
    and iterations (``s``: the settings module)."""
    return (
        SettingOption(
            "kernels",
            "--kernels",
            "blur kernels from 3D homographies (paper) or 2D displacements (baseline) "
            "(default: %(default)s)",
            choices=tuple(s.KERNELS),
        ),
        SettingOption(
            "interpolation",
            "--interpolation",
            "how the blur kernels sample the sharp image: bilinear (paper) or cubic (Keys; "
            "about 2.5x the operator's entries; default: %(default)s)",
            choices=tuple(s.INTERPOLATIONS),
        ),
        SettingOption(
            "motion_source",
            "--motion-source",
            "where the motion comes from (default: %(default)s)",
            choices=tuple(s.MOTION_SOURCES),
        ),
        SettingOption(
            "num_samples",
            "--samples",
            f"time samples per exposure, {SAMPLES[0]}..{SAMPLES[1]} "
            f"(default: %(default)s; paper: {s.NUM_SAMPLES})",
            type=integer(*SAMPLES),
            metavar="N",
        ),
        SettingOption(
            "alpha",
            "--alpha",
            "prior weight: a number in (0, 1] or a rule; 'held-out': from 'auto' up the grid "
            "alphas while the solution predicts the other view better, below it only where "
            "that prediction is within the noise (with --motion-source gt: from the noise "
            "level up; 2-6 solves per view); 'auto': from the input's noise level; "
            "'cross-view': the grid alpha that best predicts the other view, one step up "
            f"(6 solves per view) (default: %(default)s; paper: {PAPER_ALPHA:g})",
            type=alpha,
            metavar="ALPHA",
        ),
        SettingOption(
            "boundary_mask",
            "--boundary-mask",
            "gt: give the scene's gt/mixed pixels weight 0 (the paper's masked experiment) "
            "(default: none: every pixel keeps its weight)",
            choices=tuple(m for m in s.BOUNDARY_MASKS if m is not None),
        ),
        SettingOption(
            "observations",
            "--observations",
            "blurred images each view is estimated from: single (its own; paper), other-view, "
            "neighbours (its frames before and after) or all (default: %(default)s)",
            choices=tuple(s.OBSERVATIONS),
        ),
        SettingOption(
            "num_irls",
            "--irls",
            f"IRLS iterations, {ITERATIONS[0]}..{ITERATIONS[1]} "
            f"(default: %(default)s; paper: {PAPER_IRLS})",
            type=integer(*ITERATIONS),
            metavar="N",
        ),
        SettingOption(
            "num_cg",
            "--cg",
            f"CG steps per IRLS iteration, {ITERATIONS[0]}..{ITERATIONS[1]} "
            f"(default: %(default)s; paper: {PAPER_CG})",
            type=integer(*ITERATIONS),
            metavar="N",
        ),
    )


def _refinement_options(s) -> tuple[SettingOption, ...]:
    """The switches past the paper: segments, boundaries, range guard and local alpha
    (``s``: the settings module)."""
    return (
        SettingOption(
            "num_segments",
            "--segments",
            f"superpixels of the scene flow, {SEGMENTS[0]}..{SEGMENTS[1]} "
            f"(default: {SEGMENTS_RULE})",
            type=integer(*SEGMENTS),
            metavar="N",
        ),
        SettingOption(
            "boundary_flow",
            "--boundary-flow",
            "near motion boundaries, the blur from the dense optical flow where it predicts the "
            "neighbouring frames better; off: the scene flow's occlusion-aware blur "
            "everywhere, better with an exact scene flow",
            switch=True,
        ),
        SettingOption(
            "relabel_radius",
            "--relabel-radius",
            "pixels within N px of a scene-flow segment boundary take the nearby segment whose "
            f"flows match the dense optical flows best, {RELABEL[0]}..{RELABEL[1]} (default: "
            "%(default)s; 0: the estimate's own segments, as in the paper)",
            type=integer(*RELABEL),
            metavar="N",
        ),
        SettingOption(
            "range_guard",
            "--range-guard",
            "deblur with no motion where the estimate leaves [0, 1] over a region, and everywhere "
            f"if over {RANGE_WHOLE * 100:g} %% of the frame (the paper has none)",
            switch=True,
        ),
        SettingOption(
            "local_alpha",
            "--local-alpha",
            "with --alpha held-out, the prior weight per pixel: of the chosen alpha and the "
            "candidates above it (on noisy frames also below), the one whose solution predicts the "
            "other view and the neighbouring frames best around the pixel; noisy: on frames of "
            f"noise estimate >= {s.LOCAL_ALPHA_NOISE:g} only, always, or off: one alpha per view, "
            "as in the paper (default: %(default)s)",
            choices=tuple(s.LOCAL_ALPHA_MODES),
        ),
    )


# Library parameters of the synthetic scenes and benchmarks that are options of their commands.
OTHER_OPTIONS = {"scenes": "--scenes", "yaw": "--yaw", "depth": "--depth"}

BOUNDARY_HELP = (
    "motion boundaries: gated (near motion boundaries the blur from the dense optical flow "
    "where it predicts the neighbouring frames clearly better than the motion; without a "
    "dense flow, each instant shows the surface covering the pixel then and pixels showing "
    "surfaces hidden at the frame centre are down-weighted), adaptive (the dense flow's blur in "
    "the whole band, and without one the blurred frame kept where the motion does not predict "
    "the neighbouring frames) or paper (Eq. 5 data weights as published) "
    "(default: %(default)s)"
)


def _defaults() -> dict:
    fields = dataclasses.fields(_settings_module().DeblurSettings)
    return {f.name: f.default for f in fields if f.default is not dataclasses.MISSING}


def add_settings_options(
    parser: argparse.ArgumentParser,
    fields: Iterable[str] | None = None,
    *,
    title: str = "method (every variant of the paper's tables is a combination)",
) -> None:
    """Add the options of ``fields`` (default: every field with an option) to ``parser``, in
    an argument group of that ``title``."""
    options = {o.field: o for o in _options()}
    wanted = list(options) + ["boundary_weights"] if fields is None else list(fields)
    defaults = _defaults()
    g = parser.add_argument_group(title)
    for name in wanted:
        if name == "boundary_weights":
            _add_boundary_weights(g, defaults[name])
            continue
        o = options[name]
        if o.switch:
            g.add_argument(
                o.flag,
                dest=name,
                action=argparse.BooleanOptionalAction,
                default=defaults[name],
                help=f"{o.help} (default: {on_off(defaults[name])})",
            )
            continue
        g.add_argument(
            o.flag,
            dest=name,
            type=o.type,
            choices=o.choices,
            default=defaults[name],
            help=o.help,
            metavar=o.metavar,
        )
    parser.set_defaults(settings_fields=tuple(wanted))


def _add_boundary_weights(group, default: str) -> None:
    choices = [w for w in _settings_module().BOUNDARY_WEIGHTS if w != "none"]
    exclusive = group.add_mutually_exclusive_group()
    exclusive.add_argument(
        "--boundary-weights", dest="boundary_weights", choices=choices, default=default,
        help=BOUNDARY_HELP,
    )  # fmt: skip
    exclusive.add_argument(
        "--no-boundary-weights",
        dest="boundary_weights",
        action="store_const",
        const="none",
        help=f"no motion-boundary handling, w = 1 (default: off: --boundary-weights {default})",
    )


def settings_from_arguments(args: argparse.Namespace, base=None):
    """DeblurSettings of ``base`` (default: the defaults) with the parsed options' values."""
    settings = _settings_module().DeblurSettings() if base is None else base
    values = vars(args)
    return dataclasses.replace(settings, **{name: values[name] for name in args.settings_fields})


def option_for(parameter: str | None) -> str | None:
    """The option that sets library parameter ``parameter`` (a settings field or an input
    parameter such as ``exposure``), or None."""
    from .sources import SOURCE_OPTIONS

    if parameter == "boundary_weights":
        return "--boundary-weights"
    flags = {o.field: o.flag for o in _options()} | SOURCE_OPTIONS | OTHER_OPTIONS
    return flags.get(parameter)


def arguments_for(settings) -> list[str]:
    """Command-line options that give ``settings`` (fields without an option excepted)."""
    out: list[str] = []
    for o in _options():
        value = getattr(settings, o.field)
        if o.switch:
            out.append(o.flag if value else "--no-" + o.flag[2:])
        elif value is not None:
            out += [o.flag, repr(value) if isinstance(value, float) else str(value)]
    if settings.boundary_weights == "none":
        out.append("--no-boundary-weights")
    else:
        out += ["--boundary-weights", settings.boundary_weights]
    return out
