"""Every tuning constant of the scene-flow estimator, in one frozen value.

The comment above each field says what it does and points to its section of
``docs/defaults.md``: the measurement that chose or checked it, or, for the constants set
once when the estimator was written, how the estimator is checked as a whole
(``stereodeblur bench sceneflow``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from ..errors import InputError

__all__ = ["SceneFlowSettings"]

# Fields whose value must be a whole number >= 1 (or, for num_segments, None).
_COUNTS = (
    "num_segments",
    "grid_from_pixels",
    "plane_hypotheses",
    "dominant_hypotheses",
    "dominant_samples",
    "global_hypotheses",
    "global_samples",
    "max_global",
    "max_neighbours",
    "max_regions",
    "num_sweeps",
    "refine_iterations",
)
# Fields that are shares in [0, 1].
_SHARES = (
    "min_global_fraction",
    "min_region_fraction",
    "edge_floor",
    "blur_change_share",
    "match_cost",
    "min_matched",
    "motion_prior_share",
)
# Fields that must be > 0 (the rest of the floats only >= 0).
_POSITIVE = (
    "census_threshold",
    "max_gain",
    "matching_gamma",
    "census_gamma",
    "min_disparity",
    "fallback_disparity",
    "plane_threshold",
    "global_disparity_threshold",
    "global_motion_threshold",
    "edge_contrast",
    "refine_scale",
    "dominant_leave_reach",
)


@dataclass(frozen=True)
class SceneFlowSettings:
    """Tuning constants of :func:`stereodeblur.sceneflow.estimate_scene_flow`.

    The comment above each field says what it does; ``docs/defaults.md`` says why it has
    its default. Every field is checked on construction
    (:class:`~stereodeblur.errors.InputError` naming it).
    """

    # --- census descriptors (sceneflow.census)
    # Two pixels count as similar within this band at a quarter of full brightness, scaled with
    # the square root of the brightness and never below the noise.
    # Why: docs/defaults.md#census-band
    census_threshold: float = 0.008
    # The band is at least this many times the std of a pixel difference's noise.
    # Why: docs/defaults.md#constants-set-once
    census_noise_factor: float = 1.0
    # The census compares grey ** census_gamma (1: linear light, the band scaled per pixel;
    # 0.5: the square root, with one band, the band above at every brightness, for shot noise;
    # None: 0.5 where the frame's noise grows with its brightness so that it would flatten the
    # dark parts in linear light, else 1).
    # Why: docs/defaults.md#census-encoding
    census_gamma: float | None = None
    # Deviation (px) of the Gaussian applied to noisy frames before the census.
    # Why: docs/defaults.md#census-denoising
    census_denoise: float = 1.5
    # Largest gain that stretches a dark input to the full range (16 = 4 bits).
    # Why: docs/defaults.md#constants-set-once
    max_gain: float = 16.0
    # The 8-bit frames of the initial matches (SGBM, DIS) are the gained grey raised to this
    # power (0.5: square root, as the census band; 1: linear light).
    # Why: docs/defaults.md#matching-encoding
    matching_gamma: float = 0.5

    # --- superpixels (sceneflow.superpixels)
    # None: about 1200 at 640x480, scaled with the image area (paper, supplement B).
    # Why: docs/defaults.md#segments
    num_segments: int | None = None
    # Fits and data costs use a 2-pixel grid from this many pixels on (speed).
    # Why: docs/defaults.md#constants-set-once
    grid_from_pixels: int = 200_000

    # --- proposals (sceneflow.proposals)
    # Why (this group): docs/defaults.md#constants-set-once
    # RANSAC hypotheses per segment's plane fit (the value of fit_planes).
    plane_hypotheses: int = 24
    # Inlier band (px of disparity) of the plane fits (the value of fit_planes).
    plane_threshold: float = 1.0
    # Hypotheses / sampled pixels of the dominant (camera) motion.
    dominant_hypotheses: int = 48
    dominant_samples: int = 4000
    # Global proposals (sequential RANSAC): at most this many, each explaining at least
    # min_global_fraction of the pixels, from global_hypotheses hypotheses each.
    max_global: int = 8
    min_global_fraction: float = 0.02
    global_hypotheses: int = 64
    global_samples: int = 4000
    # Inlier bands of the global proposals (px of disparity and of flow).
    global_disparity_threshold: float = 1.0
    global_motion_threshold: float = 1.5
    # Planes stay this many px of disparity in front of the camera on their segment.
    min_disparity: float = 0.05
    # Disparity of the fronto-parallel plane used where nothing could be matched.
    fallback_disparity: float = 1.0

    # --- fusion (sceneflow.data_term, sceneflow.fusion)
    # Neighbours (longest shared border first) whose proposals a segment may take.
    # Why: docs/defaults.md#fusion-constants
    max_neighbours: int = 8
    # Weight and truncation (px) of the smoothness term between segments.
    # Why: docs/defaults.md#fusion-constants
    smoothness: float = 2.0
    truncation: float = 4.0
    # Data cost per view of a point behind a camera (a sample that leaves the view costs what a
    # wrong match would).
    # Why: docs/defaults.md#fusion-constants
    outside_cost: float = 0.4
    # With a window > 0 the dominant motions (global proposals and the largest regions') leave
    # the view at t + 1 at the local mean cost of the initial flow's matches there (a Gaussian
    # window of this many px; 0: a wrong match's cost), if they leave it by at most
    # dominant_leave_reach times the 95th percentile of the initial flow's length.
    # Why: docs/defaults.md#leaving-cost-of-dominant-motions
    dominant_leave_window: float = 0.0
    dominant_leave_reach: float = 1.0
    # Where a sample leaves a view at t + 1, match it on the frame on the other side of t, under
    # the inverse motion, instead of paying a wrong match's cost.
    # Why: docs/defaults.md#other-side
    other_side: bool = False
    # Smoothness across a contrast edge falls to edge_floor; edge_contrast is the mean grey
    # difference (of [0, 1]) that counts as an edge.
    # Why: docs/defaults.md#fusion-constants
    edge_floor: float = 0.25
    edge_contrast: float = 0.1
    # Alpha-expansion sweeps over all labels.
    # Why: docs/defaults.md#constants-set-once
    num_sweeps: int = 4
    # Rounds of refitting regions that chose one proposal and offering them again; the
    # largest max_regions regions of at least min_region_fraction of the image are offered
    # to every segment.
    # Why: docs/defaults.md#fusion-constants
    num_region_rounds: int = 2
    max_regions: int = 6
    min_region_fraction: float = 0.02

    # --- continuous refinement (sceneflow.refine)
    # Gauss-Newton iterations, robust scale of the data term and prior weights (the values of
    # refine_proposals).
    # Why: docs/defaults.md#constants-set-once
    refine_iterations: int = 6
    refine_scale: float = 0.25
    plane_prior: float = 0.1
    motion_prior: float = 1.0
    # None: the motion prior weighs per pixel. A share: a proposal's motion prior weighs at most
    # as much as on this share of the pixels, so that a large region's images can correct a
    # motion fitted to a failing dense flow.
    # Why: docs/defaults.md#motion-prior-share
    motion_prior_share: float | None = None

    # --- blur balancing (needs the exposure): balance the blur where its length changes by more
    # than blur_change on at least blur_change_share of the pixels.
    # Why: docs/defaults.md#blur-balancing
    blur_change: float = 0.15
    blur_change_share: float = 0.5
    # Prior weights of the second refinement, led by the balanced images alone.
    # Why: docs/defaults.md#constants-set-once
    balanced_prior: float = 0.0

    # --- occlusion (sceneflow.occlusion)
    # Why (this group): docs/defaults.md#constants-set-once
    # Disparity margin (px) of the z-buffer tests.
    depth_margin: float = 0.5
    # Flow jump (px) across a segment border that starts a motion-boundary band.
    boundary_jump: float = 0.5

    # --- diagnostics (warnings only, no effect on the result)
    # Census cost of a good match, and the matched share below which to warn.
    match_cost: float = 0.3
    min_matched: float = 0.1

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in _COUNTS:
                if value is None and f.name == "num_segments":
                    continue
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise InputError(
                        f"SceneFlowSettings.{f.name} must be a whole number >= 1, got {value!r}"
                    )
                continue
            if f.name == "num_region_rounds":
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise InputError(
                        f"SceneFlowSettings.{f.name} must be a whole number >= 0, got {value!r}"
                    )
                continue
            if value is None and f.name in ("motion_prior_share", "census_gamma"):
                continue
            if f.type in (bool, "bool"):  # a switch
                if not isinstance(value, bool):
                    raise InputError(
                        f"SceneFlowSettings.{f.name} must be True or False, got {value!r}"
                    )
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(f"SceneFlowSettings.{f.name} must be a number, got {value!r}")
            value = float(value)
            if not (value == value and abs(value) != float("inf")):
                raise InputError(f"SceneFlowSettings.{f.name} must be finite, got {value!r}")
            if f.name in _SHARES and not 0.0 <= value <= 1.0:
                raise InputError(f"SceneFlowSettings.{f.name} must lie in [0, 1], got {value!r}")
            if f.name in _POSITIVE and value <= 0:
                raise InputError(f"SceneFlowSettings.{f.name} must be > 0, got {value!r}")
            if value < 0:
                raise InputError(f"SceneFlowSettings.{f.name} must be >= 0, got {value!r}")
