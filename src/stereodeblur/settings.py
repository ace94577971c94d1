"""Choices and tuning of a deblurring run: one constant per default, one settings value.

Every default is written once, here, and imported wherever it is needed (the blur
operators, the CLI, the benchmarks). The comment above each constant says where the
value comes from: the paper, or the measurement that chose it; ``results/README.md`` in
these comments is ``benchmarks/results/README.md``, the record of every measurement
(``benchmarks/README.md`` says how each figure is produced).
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
# The paper's N = 70 instants per exposure (Sec. 4); the speed table of results/README.md ("Speed
# and memory") and every quality table are measured with it.
NUM_SAMPLES = 70
# The paper's prior weight of Eq. 6; its columns in results/README.md "Paper Tables 3 and 4" use it.
PAPER_ALPHA = 1e-3
# The paper's iteration counts (Sec. 4); the paper's columns of the benches keep them.
PAPER_IRLS = 10
PAPER_CG = 25
# 4 IRLS x 25 CG: fewer reweightings regularise; on the training scenes +0.41 / +0.36 dB at
# 320x240 and +0.37 / +0.56 dB at 640x480 over 10 x 25 (true motion / scene flow; worst scene
# -0.42 dB; 3 x 25 loses 0.87 dB on one), 40 % less time (results/iterations_train_*.md).
NUM_IRLS = 4
NUM_CG = 25
# The paper's kernels (Eq. 3-4); results/README.md "Paper Tables 3 and 4": '3D homographies' and
# 'ours'.
DEFAULT_KERNELS = "homography"
# Keys' cubic sampling: it reproduces rendered blur with 1.3-1.8x less error than the paper's
# bilinear; train split (40 scenes, 320x240) +0.77 / +0.57 dB on average (true motion / scene flow),
# worst scene -0.26 / -1.16 dB (results/calibrate_defaults_train_320x240_cubic.md); test split +0.89
# / +0.83 dB (320x240), +1.04 / +1.00 dB (640x480, 24 scenes); results/README.md.
DEFAULT_INTERPOLATION = "cubic"
# Estimated from the blurred stereo frames: every input has them, only rendered scenes have gt (the
# CLI's default; results/README.md "Paper Tables 3 and 4" measures ours with it).
DEFAULT_MOTION_SOURCE = "sceneflow"
# 'held-out': from the noise rule's alpha up the grid while the solution's prediction of the other
# view improves (stereodeblur.pipeline.alpha). Train split, 40 scenes at 320x240, gated, 4 x 25:
# 0.37 / 0.37 dB below the best grid alpha on average, worst 1.35 / 1.54 (true motion / scene flow),
# against 'auto' 1.03 / 1.11, worst 5.55 / 5.83, and 'cross-view' 0.44 / 0.32, worst 2.58 / 2.56
# (benchmarks/study_alpha_choice.py; results/alpha_rules_train_320x240.md). Test split: never more
# than 0.04 dB below 'auto', +0.23 / +0.46 dB on average (results/calibrate_defaults_test_*); bench
# paper's noisy planar scenes -0.47 dB (results/README.md). Its noise gate (HELD_OUT_NOISE_RATIO)
# since stop 29: results/README.md, issue 12 section. With the true motion (no trust raise; stop
# 33): train 0.27 -> 0.32 dB mean gap, worst 1.76 -> 1.60 dB; test 0.60 -> 0.35, worst 5.87 -> 1.60
# dB (results/calibrate_defaults_*_true_motion_rule.md). Scored by every held-out observation with
# the scene flow and --observations all (stop 46): train 34.09 -> 34.19 dB; test 29.34 -> 29.41 dB,
# worst gap 4.79 -> 2.21 dB (results/calibrate_defaults_{train,test}_320x240*_stop46.md); 40 fresh
# training scenes: mean gap 0.26 dB, worst 1.77 dB
# (results/calibrate_defaults_train2_320x240_stop47.md).
DEFAULT_ALPHA = "held-out"
# 'auto': noise- and trust-driven (results/README.md "Where the defaults come from",
# benchmarks/calibrate_alpha.py); the default until stop 23, and 'held-out''s floor. 'cross-view':
# the best predictor of the other view one grid step up (alpha_choice_train_*.md).
ALPHA_RULES = ("auto", "cross-view", "held-out")
NOISE_RULES = ("auto", "held-out")
"""The rules whose alpha is at least the noise rule's (:func:`~.pipeline.weights.resolve_alpha`)."""
# The calibration protocol's grid (issue 12); alpha='cross-view' solves at each of them.
CROSS_VIEW_ALPHAS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
# Training study: the best predictor of the other view is one grid step (x3) below the best
# alpha on most scenes (mean 0.52 -> 0.25 dB below the best with gt motion, 0.50 -> 0.20 dB
# with the scene flow, boundary handling 'none').
CROSS_VIEW_STEP = 1
# Training study: all pixels instead of the 90 % best predicted ones lost up to 5 dB where
# occlusions dominate the error (family_0000, gt motion).
CROSS_VIEW_KEEP = 0.9
# Train split (40 scenes, 320x240; benchmarks/results/held_out_train_320x240.md): 'held-out'
# goes below the trust's raise of its floor only where the floor's untrimmed prediction error
# is within this many times 2 sigma^2; the default's rows "`held-out` upwards": 4, 8 and 16
# alike (0.33 / 0.38 dB below the best alpha); stop 28's candidate rows: 2 worse. The local
# alpha's gate reuses it per pixel (pipeline.alpha.local_terms; stop 55, LOCAL_ALPHA_MODES).
HELD_OUT_NOISE_RATIO = 8.0
# That error counts the pixels the other view sees with at least this data weight: counting every
# seen pixel (> 0) counted the exposures that leave the view (weight 0.1) and lost 1.44 dB on bench
# planar's strong_yaw with stop 28's candidate (results/README.md, issue 12 section).
HELD_OUT_MIN_WEIGHT = 0.5
# 'held-out' takes the alpha nearest PAPER_ALPHA among predictors within this share of the best (a
# flat error curve). Train split, 40 scenes at 320x240, from recorded error curves: mean gap to the
# best grid alpha 0.32 / 0.36 -> 0.25 / 0.33 dB (true motion / scene flow), no scene more than 0.27
# dB worse; 0.01-0.05 gained as much on average but lost 1.2-1.8 dB on two scenes
# (results/README.md, issue 12 section; results/held_out_tie_train_320x240.md).
HELD_OUT_TIE = 0.005
# Its search goes on until the last error is more than this share above the least: stopping at the
# first rise left family_1032 (true motion) 9.26 dB below its best, where the range guard acted at
# the floor only and made a bump of 7.6 %. Replayed on the recorded error curves (train and test, 40
# scenes each, 320x240) no choice changes, at 3.1 -> 3.5 solves per view (results/README.md, issue
# 12 section).
HELD_OUT_STOP = 0.1
# ... and spans at least this factor above the best predictor's alpha before it stops: the true
# motion on the noiseless, hatched family_1060 (fresh test scene) stopped after the noise rule's
# 2.1e-5 and 3e-5, which predict best and ring; 1e-4 and up fit the view's own frame better
# (pipeline.alpha.undominated), 1e-3 is taken: 21.06 -> 22.26 dB; none of the 240 cells of the
# training and test halves changes (results/README.md, issue 12, "The search spans a decade").
HELD_OUT_SPAN = 10.0
# 'held-out' with local_alpha (stop 54; results/README.md, "A prior weight that varies over the
# view"): at each pixel the alpha of the candidate whose solution predicts the held-out observations
# best in a Gaussian window of this share of the width (pipeline.alpha.local_scale); 0.1 from
# blending the candidates' solutions after the fact (20 fresh test scenes, skip 120, and 5 training
# scenes): 0.025 and 0.05 lost 1.9 and 0.8 dB on family_0000, 0.15 gained less.
LOCAL_ALPHA_WINDOW = 0.1
# Below the chosen alpha only on a noisy frame (noise estimate at least LOCAL_ALPHA_NOISE), down
# to LOCAL_ALPHA_DOWN times less. Train split (40 scenes, 320x240, true motion / scene flow):
# down to one more grid alpha on every frame -0.03 / -0.02 dB (family_0006 -6.79, noise 0.009:
# a finely striped disc), never down +0.09 / +0.02 (worst -0.13), down on noisy frames +0.17 /
# +0.12 (worst -0.25); going down against not, +0.34 dB over the 20 cells of noise 0.012 or more
# (one lost 0.25), -0.22 dB over the 60 quieter ones (20 lost, down to -6.91 dB)
# (results/calibrate_defaults_train_320x240_local_alpha*_stop54.md).
LOCAL_ALPHA_DOWN = 10.0
LOCAL_ALPHA_NOISE = 0.012
# Where the prior weight varies: 'off' (one alpha per view, the paper's), 'noisy' (only on a
# frame whose noise estimate is at least LOCAL_ALPHA_NOISE) or 'always'.
LOCAL_ALPHA_MODES = ("off", "noisy", "always")
# 'noisy' (stop 55; results/README.md "On noisy frames only, where the motion explains them"):
# 'always' cost bench paper 36.53 -> 36.47 dB (its frames are all quiet, so the map only rises
# there); 'noisy' leaves quiet frames as 'off' (both benches identical) and gives, over 'off' (true
# motion / scene flow), +0.08 / +0.09 dB on the train split (40 scenes, 320x240; worst family_0014
# -0.25), +0.06 / +0.03 on the test split at 320x240 and +0.09 / +0.05 at 640x480 (worst -0.12),
# +0.38 on 20 fresh test scenes (results/calibrate_defaults_*_stop55.md).
DEFAULT_LOCAL_ALPHA = "noisy"
# results/README.md "Where the defaults come from": Eq. 5 and zero weights lost on every object
# scene; 'gated' over 'adaptive': 40 test scenes at 320x240 (benchmarks/results/
# calibrate_defaults_test_320x240.md) +0.09 / +0.24 dB (true motion / scene flow), scenes more than
# 0.5 dB below the paper's settings 9 -> 6 / 15 -> 9; bench paper's objects +0.09 / -0.07 dB, planar
# scenes unchanged (benchmarks/results/paper_handlings_640x480.md).
DEFAULT_BOUNDARY_WEIGHTS = "gated"
# 'gated': the dense flow's rows only where its trust beats the scene flow's by this margin
# (>= 0: the gate then lies within the boundary band, where the trusts are measured).
# Training scenes, estimated motion: 0.1 and 0.25 alike (boundary_study_train_320x240.md,
# 64 scenes at alpha 1e-3: +0.28 / +0.26 dB over the paper's w = 1, worst -0.53 / -0.41, all
# rows -2.48; alpha_choice_train_320x240.md, 24 scenes: best alpha 0.20 dB below the paper's
# at worst for both); bench paper's object scenes at 640x480 (benchmarks/results/
# paper_handlings_640x480.md): 0.1 +0.09 / -0.07 dB against 'adaptive', 0.25 -0.12 / -0.41.
GATE_MARGIN = 0.1
# The monocular baseline (initial flow, displacement kernels) the stereo method is compared
# with keeps 'adaptive': its anchor helps displacement kernels, which 'gated' drops (test
# split, 40 scenes at 320x240: 28.50 dB against 27.99 dB; calibrate_defaults_test_320x240.md).
MONOCULAR_BOUNDARY_WEIGHTS = "adaptive"
# The dense flow's rows near motion boundaries (DeblurSettings.boundary_flow). bench paper's
# object scenes at 640x480 (benchmarks/results/boundary_rows_640x480.md), noiseless / noisy:
# with the estimated scene flow 32.65 / 31.82 dB, against 32.20 / 30.52 with its own
# occlusion-aware rows (-2.77 dB on spheres_noisy); with the true motion 33.26 / 32.57 against
# 34.49 / 33.54. Off pays only where the scene flow's boundaries are exact.
DEFAULT_BOUNDARY_FLOW = True
# Pixels within this many px of a scene-flow segment boundary take the segment of another surface
# nearby whose flows come nearest the dense flows to both neighbouring frames
# (DeblurSettings.relabel_radius; results/README.md, "Boundaries from the dense flow"; 6 px as the
# oracle of boundary_rows.py; by pipeline.motion.RELABEL_MARGIN since stop 35): bench paper's
# objects 32.65 / 31.82 -> 33.11 / 32.27 dB (noiseless / noisy), planar unchanged; the training
# split 33.34 -> 33.43 dB (worst -0.23), then the test split 31.40 -> 31.49 dB (worst -0.26)
# (results/calibrate_defaults_train_320x240_relabel3.md, ..._test_320x240_relabel3_grid.md). 0 is
# the paper's.
RELABEL_RADIUS = 6
# The other view's blurred frame as a second data term (alpha chosen from the view's own): train
# split (40 scenes, 320x240) +0.44 / +0.27 dB over the single observation (true motion / scene
# flow), worst -0.33 / -0.66 dB (results/observations_train_320x240.md); bench paper's objects +0.40
# / +0.30 dB, planar +0.67 / +0.75 dB (noiseless / noisy;
# results/paper_observations_640x480_other_view.md); then the test split +0.37 / +0.16 dB
# (calibrate_defaults_test_320x240.md); 1.3x the time. 'single' is the paper's. 'all' since stop 44
# (the neighbouring frames too, weighed by NEIGHBOUR_TOLERANCE): train split +0.26 / +0.15 dB over
# 'other-view' (true motion / scene flow; worst -0.28 / -0.76, a failed scene flow;
# calibrate_defaults_train_320x240_stop44.md); test split +0.13 dB (worst -0.76, the same kind;
# calibrate_defaults_test_320x240_all.md); bench paper +0.42 dB, objects +0.36 / +0.32
# (paper_observations_640x480_all.md); bench planar's scene flow at 320x240 -0.10 dB (yaw -0.72);
# 2.5x the time of 'other-view' per 640x480 stereo frame (results/README.md, speed table), which is
# the faster setting. Stop 45 (the neighbouring frames in one gather): train +0.69 / +0.43 dB over
# 'other-view' (calibrate_defaults_train_320x240_stop45.md), test +0.21 dB over stop 44, bench paper
# +0.57 dB, bench planar 320x240 +1.09 dB; 1.7-2.1x.
DEFAULT_OBSERVATIONS = "all"
# Residual scale of the further observations' Cauchy weights: without them they lose 1-4 dB
# with the estimated scene flow, with 0.01 they gain 0.2-0.3 dB (issue 13 study,
# benchmarks/README.md "Multi-observation study", 320x240 object scenes).
OBSERVATION_ROBUST_SCALE = 0.01
# The neighbouring frames count fully while the view's single-observation estimate predicts them
# within this many times its error in the other view; beyond it their squared weight falls as that
# error ratio (inverse variance). Train half (320x240, scene flow): a noiseless scene whose
# neighbours the estimate predicts 1000x worse than the other view (family_0002) 51.35 -> 56.61 dB
# (single 56.59); 1 and 4 gave back 0.69 / 0.39 dB of family_0003's gain (ratios 2.8 and 10); no
# other training scene changed. Test half: family_1048 49.95 -> 50.61 dB, two more within 0.02 dB
# (results/README.md, issue 13 section).
NEIGHBOUR_TOLERANCE = 10.0

# The range guard (DeblurSettings.range_guard; stereodeblur.deconv.intensity_range): an estimate
# more than RANGE_EXCESS outside [0, 1] at more than RANGE_SHARE of the pixels of a
# RANGE_WINDOW-pixel square, in regions of at least RANGE_AREA of the image, is solved again with no
# motion there. Fitted on the train split (benchmarks/results/range_guard_train_320x240.md and the
# variants in results/README.md "The range guard"): without RANGE_AREA it acted on 5 / 8 / 9 of 40
# scenes (true motion / scene flow / monocular), mostly on 0.1-1.5 % of the pixels (bright surfaces,
# ringing), and lost up to 1.43 dB (family_0009); with 2 % it acts only where the motion is aliased
# on stripes (family_0014: scene flow 11.38 -> 15.35 dB). A share of 0.1 acted on family_0001's true
# motion (68 px blur over 2 px hatching) and lost 1.0 dB there; a 31-pixel window gave family_1015
# (test, scene flow) 25.95 dB instead of 27.44; an excess of 0.02 gave family_0014 15.81 dB but
# acted on more of family_1015 to no gain.
RANGE_EXCESS = 0.05
RANGE_WINDOW = 15
RANGE_SHARE = 0.2
RANGE_AREA = 0.02
# Regions over more than RANGE_WHOLE of the image take the whole image (no motion anywhere): a
# scene flow aliased on a whole striped backdrop is also wrong where its solution stays in
# [0, 1]. Train half (benchmarks/results/range_guard_whole_train_320x240.md): family_0014's
# scene flow, 24 % guarded, 15.69 -> 23.14 dB (its blurred input) with 0.2 or less, unchanged
# with 0.3. Every region on the train half was one of a failed motion, so the floor of 0.1 is
# not fitted: it keeps the 4 % region of a motion that pays off (test family_1003, +7.5 dB).
RANGE_WHOLE = 0.1
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
