"""Choices and tuning of a deblurring run: one constant per default, one settings value.

Every default is written once, here, and imported wherever it is needed (the blur
operators, the CLI, the benchmarks). The paper's values say so; the comment above each
tuned constant points to its section of ``docs/defaults.md``, which gives the measurement
behind it, the command and commit that regenerate it, and the alternatives measured.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace

from .errors import InputError
from .sceneflow.settings import SceneFlowSettings

__all__ = [
    "ALPHA_MAX",
    "ALPHA_RULES",
    "NOISE_RULES",
    "CROSS_VIEW_ALPHAS",
    "CROSS_VIEW_KEEP",
    "CROSS_VIEW_STEP",
    "BOUNDARY_MASKS",
    "BOUNDARY_WEIGHTS",
    "DASK_CONNECT_TIMEOUT",
    "DEFAULT_ALPHA",
    "DEFAULT_BOUNDARY_WEIGHTS",
    "DEFAULT_KERNELS",
    "DEFAULT_MOTION_SOURCE",
    "DEFAULT_OBSERVATIONS",
    "GATE_MARGIN",
    "HELD_OUT_MIN_WEIGHT",
    "HELD_OUT_NOISE_RATIO",
    "HELD_OUT_SPAN",
    "HELD_OUT_STOP",
    "HELD_OUT_TIE",
    "LOCAL_ALPHA_WINDOW",
    "LOCAL_ALPHA_DOWN",
    "LOCAL_ALPHA_NOISE",
    "LOCAL_ALPHA_MODES",
    "DEFAULT_LOCAL_ALPHA",
    "MONOCULAR_BOUNDARY_WEIGHTS",
    "OBSERVATIONS",
    "OBSERVATION_ROBUST_SCALE",
    "NEIGHBOUR_TOLERANCE",
    "KERNELS",
    "MOTION_SOURCES",
    "NUM_CG",
    "NUM_IRLS",
    "NUM_SAMPLES",
    "PAPER_ALPHA",
    "PAPER_CG",
    "PAPER_IRLS",
    "ITERATIONS_RANGE",
    "SAMPLES_RANGE",
    "SEGMENTS_RANGE",
    "RELABEL_RANGE",
    "RELABEL_RADIUS",
    "DeblurSettings",
]

KERNELS = ("homography", "displacement")
INTERPOLATIONS = ("bilinear", "cubic")
MOTION_SOURCES = ("gt", "sceneflow", "initial-flow")
BOUNDARY_WEIGHTS = ("adaptive", "gated", "paper", "none")
BOUNDARY_MASKS = (None, "gt")
OBSERVATIONS = ("single", "other-view", "neighbours", "all")

# Seconds a Dask scheduler (a clip run's --scheduler) has to accept the connection and answer
# as a scheduler; an address that does not is refused after this long, not waited for.
DASK_CONNECT_TIMEOUT = 10.0
# The paper's N = 70 instants per exposure (Sec. 4).
# Why: docs/defaults.md#samples
NUM_SAMPLES = 70
# The paper's prior weight of Eq. 6.
PAPER_ALPHA = 1e-3
# The paper's iteration counts (Sec. 4); the paper's columns of the benches keep them.
PAPER_IRLS = 10
PAPER_CG = 25
# IRLS iterations x CG steps per iteration: fewer reweightings than the paper's regularise.
# Why: docs/defaults.md#iterations
NUM_IRLS = 4
NUM_CG = 25
# The paper's kernels (Eq. 3-4).
# Why: docs/defaults.md#kernels
DEFAULT_KERNELS = "homography"
# Keys' cubic sampling of the sharp image (the paper samples bilinearly).
# Why: docs/defaults.md#interpolation
DEFAULT_INTERPOLATION = "cubic"
# Estimated from the blurred stereo frames: every input has them, only rendered scenes have gt.
# Why: docs/defaults.md#motion-source
DEFAULT_MOTION_SOURCE = "sceneflow"
# 'held-out': from the noise rule's alpha up the grid while the solution's prediction of the
# held-out observations improves (stereodeblur.pipeline.alpha).
# Why: docs/defaults.md#alpha-rule
DEFAULT_ALPHA = "held-out"
# 'auto': the noise rule, raised by the motion's trust ('held-out''s floor); 'cross-view': one
# grid step above the best predictor of the other view.
# Why: docs/defaults.md#alpha-rule
ALPHA_RULES = ("auto", "cross-view", "held-out")
NOISE_RULES = ("auto", "held-out")
"""The rules whose alpha is at least the noise rule's (:func:`~.pipeline.weights.resolve_alpha`)."""
# The alphas 'held-out' and 'cross-view' choose among (also the calibration protocol's grid).
# Why: docs/defaults.md#cross-view
CROSS_VIEW_ALPHAS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
# 'cross-view' takes this many grid steps (x3) above the best predictor of the other view.
# Why: docs/defaults.md#cross-view
CROSS_VIEW_STEP = 1
# Share of the per-pixel prediction errors (the smallest) that the trimmed prediction counts.
# Why: docs/defaults.md#cross-view
CROSS_VIEW_KEEP = 0.9
# 'held-out' goes below the trust's raise of its floor only where the floor's untrimmed
# prediction error is within this many times 2 sigma^2; the local alpha's gate reuses it per
# pixel (pipeline.alpha.local_terms).
# Why: docs/defaults.md#noise-gate
HELD_OUT_NOISE_RATIO = 8.0
# That error counts the pixels the other view sees with at least this data weight.
# Why: docs/defaults.md#noise-gate
HELD_OUT_MIN_WEIGHT = 0.5
# 'held-out' takes the alpha nearest PAPER_ALPHA among predictors within this share of the best
# (a flat error curve).
# Why: docs/defaults.md#ties
HELD_OUT_TIE = 0.005
# Its search goes on until the last error is more than this share above the least ...
# Why: docs/defaults.md#search-stop-and-span
HELD_OUT_STOP = 0.1
# ... and the last alpha is at least this factor above the least's.
# Why: docs/defaults.md#search-stop-and-span
HELD_OUT_SPAN = 10.0
# With local_alpha, each pixel takes the alpha of the candidate whose solution predicts the
# held-out observations best in a Gaussian window of this share of the width
# (pipeline.alpha.local_scale).
# Why: docs/defaults.md#local-alpha
LOCAL_ALPHA_WINDOW = 0.1
# Below the chosen alpha only on a noisy frame (noise estimate at least LOCAL_ALPHA_NOISE), down
# to LOCAL_ALPHA_DOWN times less.
# Why: docs/defaults.md#local-alpha
LOCAL_ALPHA_DOWN = 10.0
LOCAL_ALPHA_NOISE = 0.012
# Where the prior weight varies: 'off' (one alpha per view, the paper's), 'noisy' (only on a
# frame whose noise estimate is at least LOCAL_ALPHA_NOISE) or 'always'.
LOCAL_ALPHA_MODES = ("off", "noisy", "always")
# Where the exposure time comes from (DeblurSettings.exposure): the scene's, or estimated per
# frame from its blurred frames (stereodeblur.blur.exposure).
EXPOSURE_SOURCES = ("given", "auto")
# Why: docs/defaults.md#local-alpha
DEFAULT_LOCAL_ALPHA = "noisy"
# Why: docs/defaults.md#boundary-handling
DEFAULT_BOUNDARY_WEIGHTS = "gated"
# 'gated': the dense flow's rows only where its trust beats the scene flow's by this margin
# (>= 0: the gate then lies within the boundary band, where the trusts are measured).
# Why: docs/defaults.md#gate-margin
GATE_MARGIN = 0.1
# The monocular baseline (initial flow, displacement kernels) the stereo method is compared
# with keeps 'adaptive': its anchor helps displacement kernels, which 'gated' drops.
# Why: docs/defaults.md#monocular-boundary-handling
MONOCULAR_BOUNDARY_WEIGHTS = "adaptive"
# The dense flow's rows near motion boundaries (DeblurSettings.boundary_flow).
# Why: docs/defaults.md#boundary-flow
DEFAULT_BOUNDARY_FLOW = True
# Pixels within this many px of a scene-flow segment boundary take the segment of another surface
# nearby whose flows come nearest the dense flows to both neighbouring frames
# (DeblurSettings.relabel_radius; pipeline.motion.RELABEL_MARGIN). 0 is the paper's.
# Why: docs/defaults.md#relabel-radius
RELABEL_RADIUS = 6
# The blurred images each view's sharp frame is estimated from; 'single' is the paper's.
# Why: docs/defaults.md#observations
DEFAULT_OBSERVATIONS = "all"
# Residual scale of the further observations' Cauchy weights.
# Why: docs/defaults.md#observation-robust-scale
OBSERVATION_ROBUST_SCALE = 0.01
# The neighbouring frames count fully while the view's single-observation estimate predicts them
# within this many times its error in the other view; beyond it their squared weight falls as that
# error ratio (inverse variance).
# Why: docs/defaults.md#neighbour-tolerance
NEIGHBOUR_TOLERANCE = 10.0

# The range guard (DeblurSettings.range_guard; stereodeblur.deconv.intensity_range): an estimate
# more than RANGE_EXCESS outside [0, 1] at more than RANGE_SHARE of the pixels of a
# RANGE_WINDOW-pixel square, in regions of at least RANGE_AREA of the image, is solved again with no
# motion there.
# Why: docs/defaults.md#range-guard
RANGE_EXCESS = 0.05
RANGE_WINDOW = 15
RANGE_SHARE = 0.2
RANGE_AREA = 0.02
# Regions over more than RANGE_WHOLE of the image take the whole image (no motion anywhere): a
# motion that fails on a whole surface is also wrong where its solution stays in [0, 1].
# Why: docs/defaults.md#range-guard
RANGE_WHOLE = 0.1
# Why: docs/defaults.md#range-guard
DEFAULT_RANGE_GUARD = True


def range_guard_signature(settings) -> str:
    """The range guard's constants where ``settings`` use it, else '' (for result caches)."""
    if not settings.range_guard:
        return ""
    return (
        f" range guard {RANGE_EXCESS:g}/{RANGE_WINDOW}/{RANGE_SHARE:g}/{RANGE_AREA:g}"
        f"/{RANGE_WHOLE:g}"
    )


# Accepted ranges (inclusive), checked before any memory is spent. One sample is the centre
# instant alone, an identity "blur"; the operator's memory grows with samples x pixels (about
# 4.4 bytes per sample and pixel at 320x240), and 1000 is 14 times the paper's N = 70.
SAMPLES_RANGE = (2, 1000)
# Zero iterations return the input unchanged; the paper uses 10 x 25.
ITERATIONS_RANGE = (1, 1000)
SEGMENTS_RANGE = (1, 100_000)
RELABEL_RANGE = (0, 100)
# Eq. 6 on images in [0, 1]: at 1 the prior already outweighs the data term.
ALPHA_MAX = 1.0


def _check_count(name: str, value, limits: tuple[int, int], *, optional: bool = False) -> None:
    if optional and value is None:
        return
    low, high = limits
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Integral)
        or not low <= value <= high
    ):
        raise InputError(
            f"{name} must be a whole number in {low}..{high}, got {value!r}", parameter=name
        )


@dataclass(frozen=True)
class DeblurSettings:
    """Choices and tuning of one deblurring run; defaults as in this module's constants.

    Parameters
    ----------
    kernels : {'homography', 'displacement'}
        Blur kernels from plane-induced homographies (paper Eq. 3-4) or from straight
        2D displacements (Kim and Lee 2015).
    interpolation : {'bilinear', 'cubic'}
        How the blur kernels sample the sharp image (homography kernels) or splat it
        (displacement kernels): bilinearly (the paper) or by Keys' cubic convolution
        (:mod:`stereodeblur.blur.trajectories`), which smooths it less and gives the
        operator about 2.5x the entries.
    motion_source : {'sceneflow', 'gt', 'initial-flow'}
        ``'sceneflow'`` (default): estimated from the blurred stereo frames; ``'gt'``:
        fitted to the scene's ground truth; ``'initial-flow'``: the monocular dense optical
        flow (needs ``kernels='displacement'``). See :mod:`stereodeblur.pipeline`.
    num_samples : int
        Time samples over the exposure (paper: N = 70).
    alpha : float, 'held-out', 'auto' or 'cross-view'
        Prior weight of Eq. 6. ``'held-out'`` (default) deblurs each view at the ``'auto'``
        alpha and at every alpha of :data:`CROSS_VIEW_ALPHAS` above it and keeps the one
        whose solution best predicts the other view, below the ``'auto'`` alpha's raise by
        the motion's trust only where that prediction is within :data:`HELD_OUT_NOISE_RATIO`
        of the noise (:mod:`stereodeblur.pipeline.alpha`); without the other view
        (``motion_source='initial-flow'``, a given motion of one view) it is ``'auto'``.
        With further ``observations`` the candidates are solved from the view's own frame
        and the chosen alpha is solved once more with them.
        ``'auto'`` sets it from the noise level of the blurred frame
        (:func:`stereodeblur.deconv.noise.auto_alpha`), and with ``boundary_weights``
        'gated' or 'adaptive' at least to what the share of pixels whose motion is not
        trusted calls for (:func:`stereodeblur.deconv.trust.alpha_from_trust`).
        ``'cross-view'`` deblurs each view at every alpha of :data:`CROSS_VIEW_ALPHAS` and
        keeps the one one step above the best predictor of the other view (needs a scene
        flow). The paper's is 0.001 (:data:`PAPER_ALPHA`).
    num_irls, num_cg : int
        Iteration counts (default 4 x 25, :data:`NUM_IRLS`; paper: 10 x 25).
    num_segments : int or None
        Superpixels of the scene flow (estimated or fitted to gt); it overrides
        ``sceneflow.num_segments``. None there too: 1200 at 640x480, scaled with the area.
    seed : int
        Seed of the scene-flow estimator's random choices.
    boundary_weights : {'adaptive', 'gated', 'paper', 'none'}
        Handling of the pixels the blur model cannot explain (motion boundaries, motion
        errors; Sec. 3): ``'adaptive'`` keeps ``w = 1`` (but a small weight
        where the exposure path leaves the view); near the motion's flow discontinuities
        it takes the blur from the initial optical flow where the motion has one
        (:func:`stereodeblur.pipeline.boundary_motion`); without a dense flow, or with
        displacement kernels, it anchors the estimate to the blurred frame where the motion
        fails to predict both neighbouring frames instead (:mod:`stereodeblur.deconv.trust`),
        and homography kernels become occlusion-aware (:func:`stereodeblur.pipeline.visibility`);
        ``'gated'`` (default) the same without the anchor, and with the dense flow's rows only
        where
        the dense flow predicts the neighbouring frames better than the motion by more than
        :data:`GATE_MARGIN` in trust (:func:`stereodeblur.pipeline.gate_trusts`);
        ``'paper'`` Eq. 5 as published (:class:`~stereodeblur.deconv.weights.PaperWeights`,
        updated every IRLS iteration) started from the scene flow's occlusion mask (from 1
        without a scene flow); ``'none'`` ``w = 1``.
    boundary_mask : {None, 'gt'}
        ``'gt'``: the scene's gt/mixed pixels get weight 0 throughout (the paper's
        masked experiment, Table 2), on top of ``boundary_weights``.
    observations : {'single', 'other-view', 'neighbours', 'all'}
        The blurred images each view's sharp frame is estimated from: ``'single'`` its own
        (the paper's); ``'other-view'`` also the other view's frame,
        ``'neighbours'`` also the view's frames before and after, ``'all'`` (default) both
        (:mod:`stereodeblur.pipeline.observations`; weighted by their residual,
        :data:`OBSERVATION_ROBUST_SCALE`; with the other view, the neighbouring frames also
        by how well the view's own estimate predicts them against it,
        :data:`NEIGHBOUR_TOLERANCE`). They need a scene flow: with
        ``motion_source='initial-flow'`` or a given motion of one view every frame has its
        single observation.
    boundary_flow : bool
        With ``boundary_weights`` ``'gated'`` or ``'adaptive'``, homography kernels and a
        scene flow (estimated or given): take the blur near motion boundaries from the dense
        optical flow (default). False: the scene flow's own occlusion-aware rows everywhere, as
        with the true motion; better only where the scene flow's boundaries are exact
        (:data:`DEFAULT_BOUNDARY_FLOW`).
    relabel_radius : int
        With an estimated or given scene flow and ``boundary_weights`` ``'gated'`` or
        ``'adaptive'``: each pixel within this many px of a segment boundary takes the segment
        within as many px whose flows come nearest the view's dense optical flows to both
        neighbouring frames (:func:`~stereodeblur.sceneflow.relabel.relabel_by_flow`;
        :data:`RELABEL_RADIUS`). 0: the estimate's own segments (the paper's).
    range_guard : bool
        Where the estimate leaves [0, 1] over a whole region (:data:`RANGE_EXCESS`,
        :data:`RANGE_WINDOW`, :data:`RANGE_SHARE`), the motion cannot have made the frame
        there: those pixels are deblurred once more with no motion (their blurred frame kept,
        the further observations that see them dropped;
        :mod:`stereodeblur.deconv.intensity_range`); every pixel where such regions cover more
        than :data:`RANGE_WHOLE` of the frame. Default on; the paper has no such step.
    local_alpha : {'noisy', 'always', 'off'}
        With ``alpha='held-out'`` and held-out observations: the chosen alpha is scaled per
        pixel to the candidate that predicts them best around the pixel
        (:func:`stereodeblur.pipeline.alpha.local_scale`, :data:`LOCAL_ALPHA_WINDOW`) in the
        final solve; ``'noisy'`` only on a frame whose noise estimate is at least
        :data:`LOCAL_ALPHA_NOISE`. ``'off'``: one alpha for the whole view (the paper's).
    exposure : {'given', 'auto'}
        ``'given'`` (default): the exposure time the scene states (``scene.info.exposure``);
        ``'auto'``: estimated per frame from the blurred frames of both views and their
        optical flow (:func:`stereodeblur.pipeline.estimate_exposure`); a frame
        found sharp (exposure 0) passes through.
    sceneflow : SceneFlowSettings
        Tuning of the scene-flow estimator (:mod:`stereodeblur.sceneflow.settings`).

    Every field is checked on construction (:class:`~stereodeblur.errors.InputError`).
    """

    kernels: str = DEFAULT_KERNELS
    interpolation: str = DEFAULT_INTERPOLATION
    motion_source: str = DEFAULT_MOTION_SOURCE
    num_samples: int = NUM_SAMPLES
    alpha: float | str = DEFAULT_ALPHA
    num_irls: int = NUM_IRLS
    num_cg: int = NUM_CG
    num_segments: int | None = None
    seed: int = 0
    boundary_weights: str = DEFAULT_BOUNDARY_WEIGHTS
    boundary_mask: str | None = None
    observations: str = DEFAULT_OBSERVATIONS
    boundary_flow: bool = DEFAULT_BOUNDARY_FLOW
    relabel_radius: int = RELABEL_RADIUS
    range_guard: bool = DEFAULT_RANGE_GUARD
    local_alpha: str = DEFAULT_LOCAL_ALPHA
    exposure: str = "given"
    sceneflow: SceneFlowSettings = field(default_factory=SceneFlowSettings)

    def __post_init__(self):
        if self.kernels not in KERNELS:
            raise InputError(f"kernels must be one of {', '.join(KERNELS)}, got {self.kernels!r}")
        if self.interpolation not in INTERPOLATIONS:
            raise InputError(
                f"interpolation must be one of {', '.join(INTERPOLATIONS)}, "
                f"got {self.interpolation!r}",
                parameter="interpolation",
            )
        if self.motion_source not in MOTION_SOURCES:
            raise InputError(
                f"motion source must be one of {', '.join(MOTION_SOURCES)}, "
                f"got {self.motion_source!r}"
            )
        if self.motion_source == "initial-flow" and self.kernels != "displacement":
            raise InputError("motion_source='initial-flow' needs kernels='displacement'")
        if self.motion_source == "initial-flow" and self.alpha == "cross-view":
            raise InputError(
                "alpha='cross-view' needs a disparity: motion_source 'sceneflow' or 'gt', "
                "not 'initial-flow'",
                parameter="alpha",
            )
        _check_count("num_samples", self.num_samples, SAMPLES_RANGE)
        _check_count("num_irls", self.num_irls, ITERATIONS_RANGE)
        _check_count("num_cg", self.num_cg, ITERATIONS_RANGE)
        _check_count("num_segments", self.num_segments, SEGMENTS_RANGE, optional=True)
        _check_count("relabel_radius", self.relabel_radius, RELABEL_RANGE)
        if isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral):
            raise InputError(f"seed must be a whole number, got {self.seed!r}")
        if self.alpha not in ALPHA_RULES:
            if isinstance(self.alpha, str | bool) or not (
                isinstance(self.alpha, numbers.Real)
                and math.isfinite(self.alpha)
                and 0 < self.alpha <= ALPHA_MAX
            ):
                raise InputError(
                    f"alpha must be 'held-out', 'auto', 'cross-view' or in (0, {ALPHA_MAX:g}], "
                    f"got {self.alpha!r}",
                    parameter="alpha",
                )
        if self.boundary_weights not in BOUNDARY_WEIGHTS:
            raise InputError(
                f"boundary weights must be one of {', '.join(BOUNDARY_WEIGHTS)}, "
                f"got {self.boundary_weights!r}"
            )
        if self.boundary_mask not in BOUNDARY_MASKS:
            raise InputError(f"boundary mask must be 'gt' or None, got {self.boundary_mask!r}")
        if self.observations not in OBSERVATIONS:
            raise InputError(
                f"observations must be one of {', '.join(OBSERVATIONS)}, got {self.observations!r}"
            )
        if not isinstance(self.boundary_flow, bool):
            raise InputError(f"boundary_flow must be True or False, got {self.boundary_flow!r}")
        if not isinstance(self.range_guard, bool):
            raise InputError(f"range_guard must be True or False, got {self.range_guard!r}")
        if self.local_alpha not in LOCAL_ALPHA_MODES:
            raise InputError(
                f"local_alpha must be one of {', '.join(LOCAL_ALPHA_MODES)}, "
                f"got {self.local_alpha!r}"
            )
        if self.exposure not in EXPOSURE_SOURCES:
            raise InputError(
                f"exposure must be one of {', '.join(EXPOSURE_SOURCES)}, got {self.exposure!r}",
                parameter="exposure",
            )
        if not isinstance(self.sceneflow, SceneFlowSettings):
            raise InputError(
                f"sceneflow must be a SceneFlowSettings, got {type(self.sceneflow).__name__}"
            )

    @property
    def estimator(self) -> SceneFlowSettings:
        """The scene-flow estimator's settings, with ``num_segments`` if it is given."""
        if self.num_segments is None:
            return self.sceneflow
        return replace(self.sceneflow, num_segments=self.num_segments)

    @property
    def segments(self) -> int | None:
        """Superpixels of the scene flow: ``num_segments``, else ``sceneflow.num_segments``."""
        return self.estimator.num_segments
