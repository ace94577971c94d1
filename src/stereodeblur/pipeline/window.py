"""The frame window: every frame one stereo frame's deblurring reads, each read once.

Frame ``index`` is deblurred with the motion towards its *neighbour*: the next frame, or
the previous one for the last frame of a clip (:func:`neighbour_of`). The frame on the
*other side* (``2 index - neighbour``) adds the backward dense flow and a second
prediction to the trust in the motion, where it exists (not for the first or last frame).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure, StereoCamera

if TYPE_CHECKING:
    from ..io.protocol import StereoScene
    from ..settings import DeblurSettings

VIEWS = ("left", "right")


def neighbour_of(index: int, num_frames: int) -> int:
    """The frame whose motion deblurs ``index``: the next one, or the previous for the last."""
    return index + 1 if index + 1 < num_frames else index - 1


def other_side(index: int, num_frames: int) -> int | None:
    """The frame on the other side of ``index`` from its neighbour, None if there is none."""
    other = 2 * index - neighbour_of(index, num_frames)
    return other if 0 <= other < num_frames else None


def check_index(scene: StereoScene, index: int) -> None:
    """An :class:`InputError` unless ``index`` is a frame of ``scene`` with a neighbour."""
    if not 0 <= index < scene.num_frames:
        raise InputError(f"frame {index} is out of range: the scene has {scene.num_frames} frames")
    if scene.num_frames < 2:
        raise InputError(f"{scene.root}: deblurring needs at least 2 frames, the scene has 1")


def check_views(views) -> tuple[str, ...]:
    """``views`` as a tuple without repeats, each 'left' or 'right'."""
    views = (views,) if isinstance(views, str) else tuple(dict.fromkeys(views))
    if not views or any(v not in VIEWS for v in views):
        raise InputError(f"views must be 'left' and/or 'right', got {views}")
    return views


TRUST_HANDLINGS = ("adaptive", "gated")
"""Boundary handlings that measure the motion's trust on the neighbouring frames."""


def occlusion_aware(settings: DeblurSettings) -> bool:
    """Whether ``settings``' homography kernels let each instant show the surface covering
    the pixel then (where no dense flow's rows replace them)."""
    return settings.boundary_weights in TRUST_HANDLINGS and settings.kernels == "homography"


def uses_boundary_flow(settings: DeblurSettings) -> bool:
    """Whether ``settings`` take the blur near motion boundaries from the dense flow."""
    return occlusion_aware(settings) and settings.boundary_flow


def observation_kinds(settings: DeblurSettings) -> tuple[str, ...]:
    """The further observations ``settings.observations`` asks for: ``'other-view'``,
    ``'neighbours'``; none without a scene flow (``motion_source='initial-flow'``)."""
    if settings.motion_source == "initial-flow":
        return ()
    kinds = {"single": (), "all": ("other-view", "neighbours")}
    return kinds.get(settings.observations, (settings.observations,))


def predicts_other_view(settings: DeblurSettings) -> bool:
    """Whether each view's alpha is chosen by predicting the other view: ``'cross-view'``,
    and ``'held-out'`` where the motion has a disparity (not ``'initial-flow'``)."""
    if settings.alpha == "held-out":
        return settings.motion_source != "initial-flow"
    return settings.alpha == "cross-view"


def views_read(settings: DeblurSettings, views) -> tuple[str, ...]:
    """The views whose frames and motion a pass deblurring ``views`` reads: both where each
    view's alpha predicts the other view or observes it, else ``views``."""
    if predicts_other_view(settings) or "other-view" in observation_kinds(settings):
        return VIEWS
    return tuple(views)


def relabels(settings: DeblurSettings) -> bool:
    """Whether ``settings`` move the scene flow's segment boundaries to the dense flow's
    (``relabel_radius``; with an estimated or given scene flow and occlusion handling)."""
    return (
        settings.motion_source == "sceneflow"
        and occlusion_aware(settings)
        and settings.relabel_radius > 0
    )


def uses_dense_flow(settings: DeblurSettings) -> bool:
    """Whether a run with ``settings`` computes the views' dense optical flow."""
    return settings.motion_source == "initial-flow" or (
        settings.motion_source == "sceneflow"
        and (uses_boundary_flow(settings) or relabels(settings))
    )


@dataclass(frozen=True)
class FrameWindow:
    """The frames, camera and exposure of one stereo frame's deblurring.

    Parameters
    ----------
    index : int
        The frame to deblur.
    neighbour : int
        The frame its motion leads to (:func:`neighbour_of`).
    other : int or None
        The frame on the other side (:func:`other_side`).
    images : mapping of (view, frame) to ndarray
        Read-only float32 frames, linear, ``(H, W)`` or ``(H, W, 3)``.
    camera : StereoCamera
    exposure : Exposure
    num_frames : int
        Frames per view in the scene.
    """

    index: int
    neighbour: int
    other: int | None
    images: MappingProxyType
    camera: StereoCamera
    exposure: Exposure
    num_frames: int

    def frame(self, view: str, frame: int) -> np.ndarray:
        """Frame ``frame`` of ``view``; a KeyError if the window did not read it."""
        try:
            return self.images[view, frame]
        except KeyError:
            message = f"the window of frame {self.index} holds no {view} frame {frame}"
            raise KeyError(message) from None

    def blurred(self, view: str) -> np.ndarray:
        """The frame to deblur in ``view``."""
        return self.frame(view, self.index)

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the frames."""
        return next(iter(self.images.values())).shape[:2]


def frames_needed(
    index: int, num_frames: int, views, settings: DeblurSettings, *, motion=True, estimate=True
):
    """The ``(view, frame)`` pairs deblurring frame ``index`` of ``views`` reads.

    ``motion=False``: the motion is given, only the views' own frames are needed;
    ``estimate=False``: the scene flow is given, the views' dense flows are still computed.
    """
    neighbour, other = neighbour_of(index, num_frames), other_side(index, num_frames)
    needed = [(view, index) for view in views]
    source = settings.motion_source if motion else None
    if source == "sceneflow" and estimate:
        needed += [(v, i) for i in (index, neighbour) for v in VIEWS]
        if settings.estimator.other_side and other is not None:
            needed += [(v, other) for v in VIEWS]
    elif source == "gt":
        needed.append(("left", index))  # the superpixels are cut on the left frame
    sides = (neighbour,) if other is None else (neighbour, other)
    sides_read = settings.boundary_weights in TRUST_HANDLINGS
    sides_read |= "neighbours" in observation_kinds(settings)  # observations of the view
    if (motion and uses_dense_flow(settings)) or sides_read:
        needed += [(view, i) for view in views for i in sides]
    if motion:  # the exposure (estimated, or checked)
        needed += [(view, i) for view in views for i in (index, *sides)]
    return list(dict.fromkeys(needed))


def read_window(
    scene: StereoScene,
    index: int,
    views,
    settings: DeblurSettings,
    *,
    motion: bool = True,
    estimate: bool = True,
    known=None,
) -> FrameWindow:
    """Read the frames deblurring frame ``index`` of ``views`` needs, each once.

    ``motion``, ``estimate``: as for :func:`frames_needed`. ``known``: frames already in
    memory, ``{(view, frame): image}``, taken instead of reading them.
    """
    check_index(scene, index)
    views = check_views(views)
    known = known or {}
    images = {}
    needed = frames_needed(
        index, scene.num_frames, views, settings, motion=motion, estimate=estimate
    )
    for view, frame in needed:
        image = known.get((view, frame))
        if image is None:
            image = scene.read_frame(view, frame)
        image = np.asarray(image).view()  # read-only here, the caller's array stays writable
        image.setflags(write=False)
        images[view, frame] = image
    return FrameWindow(
        index,
        neighbour_of(index, scene.num_frames),
        other_side(index, scene.num_frames),
        MappingProxyType(images),
        scene.info.camera,
        scene.info.exposure,
        scene.num_frames,
    )


def gt_files(index: int, num_frames: int, settings: DeblurSettings, views=VIEWS, *, motion=True):
    """``(kind, view, frame, required)`` of every gt file deblurring frame ``index`` of
    ``views`` reads (``motion=False``: the motion is given, only the masks').

    With ``motion_source='gt'``: the left view's disparity at ``index`` and its neighbour,
    the flow between them (for the last frame the flow to it, inverted), and, optional,
    the flow into ``index`` (the backward flow); with ``boundary_mask='gt'`` the views'
    gt/mixed masks.
    """
    files = []
    if motion and settings.motion_source == "gt":
        neighbour = neighbour_of(index, num_frames)
        files += [
            ("disparity", "left", index, True),
            ("disparity", "left", neighbour, True),
            ("flow", "left", min(index, neighbour), True),
        ]
        if neighbour > index and index > 0:
            files.append(("flow", "left", index - 1, False))
    if settings.boundary_mask == "gt":
        files += [("mixed", view, index, True) for view in views]
    return files


def gt_needs(
    scene: StereoScene, index: int, settings: DeblurSettings, *, views=VIEWS
) -> list[Path]:
    """The ground-truth files deblurring frame ``index`` of ``views`` with ``settings`` needs.

    Empty for runs that read no ground truth; optional files are not listed.
    """
    check_index(scene, index)
    views = check_views(views)
    return [
        Path(scene.gt_path(kind, view, frame))
        for kind, view, frame, required in gt_files(index, scene.num_frames, settings, views)
        if required
    ]


def check_gt(
    scene: StereoScene, index: int, settings: DeblurSettings, views=VIEWS, *, motion=True
) -> None:
    """An :class:`InputError` naming the first file of :func:`gt_needs` that is missing.

    ``motion=False``: the motion is given, only the views' gt/mixed masks are needed.
    """
    check_index(scene, index)
    for kind, view, frame, required in gt_files(
        index, scene.num_frames, settings, views, motion=motion
    ):
        if required and not scene.has_gt(kind, view, frame):
            what = "motion_source='gt'" if kind != "mixed" else "boundary_mask='gt'"
            raise InputError(f"{what} needs {scene.gt_path(kind, view, frame)}, which is missing")
