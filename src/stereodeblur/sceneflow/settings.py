"""Every tuning constant of the scene-flow estimator, in one frozen value.

Each field states where its default comes from. "Measured" points to the run that
chose or checked it (tables in ``benchmarks/results/`` and its README.md); "not tuned"
says the value was set once when the code was written (commit 4b95b69, the first
estimator, unless another is named) and only ever checked as part of the whole
(``stereodeblur bench sceneflow``: every planar and object scene within its targets,
``benchmarks/results/bench_sceneflow_640x480.md``).
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

    Defaults reproduce the estimator as benchmarked in ``benchmarks/README.md``;
    the reason for each is a comment next to it in the source. Every field is
    checked on construction (:class:`~stereodeblur.errors.InputError` naming it).
    """

    # --- census descriptors (sceneflow.census) Measured (stop 40; relative to the brightness since
    # 4b2311f): 0.004 took the training half's textured flow error 2.63 -> 2.39 px and its
    # deblurring +0.25 dB, the unseen test 40 +0.08 dB, but the real Middlebury pair's > 2 px
    # disparity errors 10.6 -> 12.5 % and fast_approach's AEP 0.33 -> 0.51 px (results/README.md,
    # "Scene-flow settings"): kept at 0.008.
    census_threshold: float = 0.008
    # Not tuned (4b2311f): the band is at least 1 x the std of a pixel difference's noise.
    census_noise_factor: float = 1.0
    # Measured (99d51ec): Gaussian of 1.5 px before the census of noisy frames took the noisy object
    # scenes' mean AEP from 1.09 to 0.64 px (results/README.md, scene-flow section).
    census_denoise: float = 1.5
    # Not tuned: largest gain that stretches a dark input to the full range (16 = 4 bits).
    max_gain: float = 16.0

    # --- superpixels (sceneflow.superpixels)
    # None: about 1200 at 640x480, scaled with the image area (paper, supplement B). Measured
    # (stop 61, results/README.md, "Smaller superpixels"): half as many cost bench paper's objects
    # 0.3 dB, twice or four times as many gain at most 0.15 dB there and 0.00 to -0.12 dB on the
    # training half.
    num_segments: int | None = None
    # Not tuned (speed): fits and data costs use a 2-pixel grid from this many pixels on,
    # the 640x480 time in benchmarks/README.md is with it.
    grid_from_pixels: int = 200_000

    # --- proposals (sceneflow.proposals)
    # Not tuned: RANSAC hypotheses per segment's plane fit (the value of fit_planes).
    plane_hypotheses: int = 24
    # Not tuned: inlier band (px of disparity) of the plane fits (the value of fit_planes).
    plane_threshold: float = 1.0
    # Not tuned: hypotheses / sampled pixels of the dominant (camera) motion.
    dominant_hypotheses: int = 48
    dominant_samples: int = 4000
    # Not tuned: global proposals (sequential RANSAC): at most this many, each explaining at
    # least min_global_fraction of the pixels, from global_hypotheses hypotheses each.
    max_global: int = 8
    min_global_fraction: float = 0.02
    global_hypotheses: int = 64
    global_samples: int = 4000
    # Not tuned: inlier bands of the global proposals (px of disparity and of flow).
    global_disparity_threshold: float = 1.0
    global_motion_threshold: float = 1.5
    # Not tuned: planes stay this many px of disparity in front of the camera on their segment.
    min_disparity: float = 0.05
    # Not tuned: disparity of the fronto-parallel plane used where nothing could be matched.
    fallback_disparity: float = 1.0

    # --- fusion (sceneflow.data_term, sceneflow.fusion)
    # Measured (stop 40, the 40 training scenes at 320x240, textured end-point error,
    # benchmarks/results/sceneflow_settings_train_320x240.md): 16 neighbours change no scene
    # by more than 0.09 px. Neighbours (longest shared border first) whose proposals a
    # segment may take.
    max_neighbours: int = 8
    # Measured (stop 40, the same table): weight 1, 3, 4, 6 and truncation 2, 8 each win
    # and lose on 3-6 scenes by up to 1-2 px, none better on clearly more scenes; kept.
    # Weight and truncation (px) of the smoothness term between segments.
    smoothness: float = 2.0
    truncation: float = 4.0
    # Measured (stop 40, the same table): 0.1 moves the mean by 0.006 px (it only prices
    # points behind a camera; a sample that leaves the view costs what a wrong match would).
    outside_cost: float = 0.4
    # Stop 58 (results/README.md, "A static scene's motion at the image border"): where a sample
    # leaves the view at t + 1, a wrong match's cost made the camera's own motion lose the border of
    # a static, finely striped scene to an aliased motion that stays in view (family_1059, 17 % of
    # the frame 60-78 px off). With a window > 0 the dominant motions (global proposals and the
    # largest regions') leave the view at the local mean cost of the initial flow's matches at t + 1
    # (a Gaussian window of this many px; 0: today's cost), if they leave it by at most
    # dominant_leave_reach times the 95th percentile of the initial flow's length. Off (0): on the
    # training half (40 scenes, 320x240) 16 px lowered the textured end-point error on 4 scenes and
    # raised it on 1, but the default's PSNR fell by 0.08 dB on average (street_0015 -2.8 dB;
    # calibrate_defaults_train_320x240_dominant_leave_stop58.md); reach not tuned.
    dominant_leave_window: float = 0.0
    dominant_leave_reach: float = 1.0
    # Stop 61 (results/README.md, "What leaves the view at t + 1 was in view at t - 1"): where a
    # sample leaves a view at t + 1, match it on the frame on the other side of t, under the
    # inverse motion, instead of paying a wrong match's cost. Off: at 320x240 it repairs
    # family_1059's border (11.9 -> 0.25 px) and gains 0.05 dB on the training half, but loses
    # 0.08 dB on 40 unseen scenes (family_1081 -1.74 dB;
    # calibrate_defaults_*_320x240_other_side_v2_stop61.md); at 640x480 family_1059 gets worse.
    other_side: bool = False
    # Measured (stop 40, the same table): edge_floor 0.5 and 1 win on 2 / 4 and lose on 1 / 5
    # scenes; kept. edge_contrast not tuned. Smoothness across a contrast edge falls to
    # edge_floor; edge_contrast is the mean grey difference (of [0, 1]) that counts as an edge.
    edge_floor: float = 0.25
    edge_contrast: float = 0.1
    # Not tuned: alpha-expansion sweeps over all labels.
    num_sweeps: int = 4
    # Rounds of refitting regions that chose one proposal and offering them again; the
    # largest max_regions regions of at least min_region_fraction of the image are offered
    # to every segment. Measured (stop 40, the same table): 4 rounds or 12 regions change
    # the mean by 0.04 / 0.002 px (4 rounds lose 1.15 px on family_0001); min_region_fraction
    # not tuned.
    num_region_rounds: int = 2
    max_regions: int = 6
    min_region_fraction: float = 0.02

    # --- continuous refinement (sceneflow.refine)
    # Not tuned: Gauss-Newton iterations, robust scale of the data term and prior weights
    # (the values of refine_proposals).
    refine_iterations: int = 6
    refine_scale: float = 0.25
    plane_prior: float = 0.1
    motion_prior: float = 1.0
    # None (today's estimator): the motion prior weighs per pixel. A share: a proposal's
    # motion prior weighs at most as much as on this share of the pixels, so that a large
    # region's images can correct a motion fitted to a failing dense flow. Not the default
    # yet: 0.003 took a sharp 80 px road (tests/sceneflow/test_driving.py) from 0.69 to
    # 0.41 px AEP and the 19 planar and object scenes at 320x240 from 0.277 to 0.272 px mean
    # AEP (long_exposure_roll 0.161 -> 0.056, forward 0.016 -> 0.029); bench planar / paper
    # not rerun with it.
    motion_prior_share: float | None = None

    # --- blur balancing (needs the exposure) Not tuned (905d486): balance the blur where its length
    # changes by > 15 % on at least half the pixels; with it fast_approach 640x480 goes from 0.8 to
    # 0.33 px AEP (results/README.md, scene-flow section), no other threshold was tried.
    blur_change: float = 0.15
    blur_change_share: float = 0.5
    # Not tuned: prior weights of the second refinement, led by the balanced images alone.
    balanced_prior: float = 0.0

    # --- occlusion (sceneflow.occlusion)
    # Not tuned: disparity margin (px) of the z-buffer tests.
    depth_margin: float = 0.5
    # Not tuned: flow jump (px) across a segment border that starts a motion-boundary band.
    boundary_jump: float = 0.5

    # --- diagnostics (warnings only, no effect on the result)
    # Not tuned: census cost of a good match, and the matched share below which to warn.
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
            if value is None and f.name == "motion_prior_share":
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
