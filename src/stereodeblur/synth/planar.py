"""The planar benchmark: one textured plane filling the view, moving rigidly (paper Sec. 4.1).

Each scene of :data:`PLANAR_MOTIONS` is one roughly fronto-parallel plane (tilted
by up to 6 degrees, drawn from ``seed``) a few metres in front of the stereo rig
at the middle of the clip, moving with a constant twist per frame interval. Twists
are *object* motions in left-camera coordinates: ``forward`` brings the plane
towards the camera (as if the camera moved forward), ``upward`` moves it towards
``-y``. The moderate motions are those of the paper's Table 2 and supplement
Sec. C (about 5 to 15 pixels of blur at 640 x 480); the strong ones make image
trajectories bend by about 3 pixels within one exposure at 640 x 480 (the case of
the paper's Fig. 3), where a linear 2D displacement model is only an
approximation (see :func:`curvature_px`).

Camera: ``fx = fy = 0.8 * width`` (the 65 degree field of view of the paper's
Bumblebee2), principal point at the image centre ``((W - 1) / 2, (H - 1) / 2)``,
baseline 0.12 m, 20 frames per second, exposure 0.04 s unless the motion says
otherwise. The texture is placed so that it covers both views at every instant
of the clip with at least one pixel per texel everywhere (smaller images get a
pre-filtered, smaller texture; see :func:`textured_plane`); at 640 x 480 the
paper's motions see 1.05 to 1.6 pixels per texel, ``strong_yaw`` up to 2.7.

Written scenes (:func:`write_rendered_scene`) follow ``SCENE_FORMAT.md`` with
colour ``"linear"``, plus ``gt/objects.json``::

    {
      "objects": [
        {"id": 0, "name": "plane", "texture": "astronaut",
         "normal": [nx, ny, nz],            # scaled normal, P^T n = 1
         "twist": [vx, vy, vz, wx, wy, wz]} # per frame interval, metres and radians
      ],
      "frame_rate": 20.0,
      "reference": "frame 0 centre"
    }

``normal`` is the plane at the centre of frame 0's exposure in left-camera
coordinates; a point ``P`` of the object at that instant is at ``R P + T``,
``[R, T] = exp(s * twist)``, ``s`` frame intervals later (see
:mod:`stereodeblur.geometry.rigid`). ``id`` is the object index used by the
renderer (the value of its object-id maps). Solids (spheres, cylinders, boxes of
:mod:`stereodeblur.synth.objects`) are written with ``"kind"``, ``"center"``,
``"frame"`` and their sizes instead of ``"normal"`` (see their ``describe``).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure, StereoCamera
from ..geometry.plane import move_plane
from ..geometry.rigid import se3_exp, so3_exp
from ..io.files import atomic_write
from .render import (
    PlanarObject,
    RenderedScene,
    SceneSetup,
    cast_rays,
    describe_object,
    intersect_plane,
    render_scene,
    track,
)
from .textures import TEXTURE_NAMES, load_texture

BASELINE = 0.12
FRAME_RATE = 20.0
EXPOSURE = 0.04
FOCAL_PER_WIDTH = 0.8
MAX_TILT_DEGREES = 6.0


@dataclass(frozen=True)
class PlanarMotion:
    """Motion of the plane of one benchmark scene.

    Attributes
    ----------
    twist : tuple of float
        ``(vx, vy, vz, wx, wy, wz)`` per frame interval, metres and radians.
    distance : float
        Depth of the plane on the optical axis at the middle of the clip, metres.
    exposure : float
        Exposure time in seconds (at most ``1 / FRAME_RATE``).
    description : str
    """

    twist: tuple[float, ...]
    distance: float = 3.0
    exposure: float = EXPOSURE
    description: str = ""


PLANAR_MOTIONS: dict[str, PlanarMotion] = {
    "upward": PlanarMotion((0.0, -0.07, 0.0, 0.0, 0.0, 0.0), description="upward translation"),
    "forward": PlanarMotion((0.0, 0.0, -0.12, 0.0, 0.0, 0.0), description="approach"),
    "forward_yaw": PlanarMotion((0.0, 0.0, -0.07, 0.0, 0.014, 0.0), description="approach and yaw"),
    "yaw": PlanarMotion((0.0, 0.0, 0.0, 0.0, 0.025, 0.0), description="yaw about the camera"),
    "forward_roll": PlanarMotion(
        (0.0, 0.0, -0.08, 0.0, 0.0, 0.02), description="approach and roll"
    ),
    "lateral_pitch": PlanarMotion(
        (0.05, 0.0, 0.0, 0.015, 0.0, 0.0), description="sideways translation and pitch"
    ),
    "strong_yaw": PlanarMotion(
        (0.0, 0.0, 0.0, 0.0, 0.15, 0.0), description="fast yaw: bent trajectories (Fig. 3)"
    ),
    "fast_approach": PlanarMotion(
        (0.0, 0.0, -0.25, 0.0, 0.0, 0.0),
        distance=1.5,
        description="fast approach of a near plane: accelerated trajectories",
    ),
    "long_exposure_roll": PlanarMotion(
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.25),
        exposure=1.0 / FRAME_RATE,
        description="roll with exposure = frame interval: arcs",
    ),
}
"""The planar scene set, by name."""

_NAMES = ", ".join(PLANAR_MOTIONS)


def planar_camera(size: tuple[int, int] = (640, 480)) -> StereoCamera:
    """The benchmark's stereo camera for images of ``size = (width, height)``."""
    width, height = size
    f = FOCAL_PER_WIDTH * width
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    return StereoCamera(K, BASELINE)


def _resize(texture: np.ndarray, width: int, height: int) -> np.ndarray:
    """Area-averaging (anti-aliased) resize of a float32 texture."""
    import cv2

    return cv2.resize(texture, (width, height), interpolation=cv2.INTER_AREA)


def _fit_texture(texture, extent, min_magnification: float, max_magnification: float):
    """``texture`` shrunk or mirror-extended so that covering ``extent`` (pixels along the
    plane's two axes) magnifies it by a scale in ``[min_magnification, max_magnification]``;
    returns it and that scale (pixels per texel)."""
    texture = np.asarray(texture, dtype=np.float32)
    h, w = texture.shape[:2]
    scale = max(extent[0] / (w - 1), extent[1] / (h - 1))
    if scale < min_magnification:
        shrink = scale / min_magnification
        new_w = max(2, round((w - 1) * shrink) + 1)
        new_h = max(2, round((h - 1) * shrink) + 1)
        texture = _resize(texture, new_w, new_h)
        h, w = texture.shape[:2]
        scale = max(extent[0] / (w - 1), extent[1] / (h - 1))
    if scale > max_magnification:
        need_w = max(w, math.ceil(extent[0] / max_magnification) + 1)
        need_h = max(h, math.ceil(extent[1] / max_magnification) + 1)
        pad_w, pad_h = need_w - w, need_h - h
        texture = np.pad(
            texture,
            ((pad_h // 2, pad_h - pad_h // 2), (pad_w // 2, pad_w - pad_w // 2), (0, 0)),
            mode="symmetric",
        )
        h, w = texture.shape[:2]
        scale = max(extent[0] / (w - 1), extent[1] / (h - 1))
    return texture, scale


def textured_plane(
    texture: np.ndarray,
    camera: StereoCamera,
    size: tuple[int, int],
    normal: np.ndarray,
    twist: np.ndarray,
    instants: np.ndarray,
    *,
    name: str = "plane",
    texture_name: str = "",
    min_magnification: float = 1.0,
    max_magnification: float = 2.0,
    margin: float = 2.0,
) -> PlanarObject:
    """An unbounded textured plane whose texture covers both views at all ``instants``.

    The view rectangles of both cameras are mapped onto the plane at every instant;
    the texture is centred on the bounding box of these regions (plus ``margin``
    pixels) and scaled to cover it. Its scale, in pixels per texel where the plane
    is seen most minified (over both views, all instants, along the most minified
    direction), is kept in ``[min_magnification, max_magnification]``: a texture
    that would be minified more is first shrunk with an area filter (pre-filtering
    against aliasing); one that would be magnified more is extended by mirroring at
    its edges. Elsewhere the plane is magnified more, by its perspective.

    Parameters
    ----------
    texture : ndarray, shape (h, w, 3)
    camera : StereoCamera
    size : tuple of int
        ``(width, height)``.
    normal : ndarray, shape (3,)
        Scaled normal at instant 0, left-camera coordinates.
    twist : ndarray, shape (6,)
    instants : ndarray
        Instants at which the plane must fill both views.

    Raises
    ------
    ValueError
        If the plane does not fill a view at one of the instants.
    """
    normal = np.asarray(normal, dtype=np.float64)
    if normal[2] <= 0:
        raise ValueError(f"the plane must cross the optical axis in front, got normal {normal}")
    width, height = size
    unit = normal / np.linalg.norm(normal)
    e1 = np.array([1.0, 0.0, 0.0]) - unit[0] * unit
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(unit, e1)
    center = np.array([0.0, 0.0, 1.0 / normal[2]])  # hit of the optical axis at instant 0
    # Probes: the view's corners (coverage) and a 3 x 3 grid of pixels, each with
    # neighbours half a pixel away along x and y (local scale).
    corners_x = np.array([-0.5, width - 0.5, -0.5, width - 0.5])
    corners_y = np.array([-0.5, -0.5, height - 0.5, height - 0.5])
    gx, gy = np.meshgrid(np.linspace(0, width - 1, 3), np.linspace(0, height - 1, 3))
    gx, gy = gx.ravel(), gy.ravel()
    probe_x = np.concatenate([corners_x, gx, gx + 0.5, gx])
    probe_y = np.concatenate([corners_y, gy, gy, gy + 0.5])
    coords, footprints = [], []
    for s in np.asarray(instants, dtype=np.float64).reshape(-1):
        for view in ("left", "right"):
            depth, P = intersect_plane(normal, twist, camera, view, probe_x, probe_y, s)
            if not np.all(np.isfinite(depth)):
                raise ValueError(
                    f"plane {name!r} does not fill the {view} view at instant {s:.3f}: "
                    "fewer frames or a slower motion needed"
                )
            ab = np.stack([(P - center) @ e1, (P - center) @ e2], -1)
            coords.append(ab[:4])
            grid, along_x, along_y = np.split(ab[4:], 3)
            jacobian = np.stack([along_x - grid, along_y - grid], -1) * 2.0  # metres per pixel
            footprints.append(np.linalg.svd(jacobian, compute_uv=False)[:, 0])
    # Scene units per pixel where the plane is seen most minified.
    footprint = float(np.max(footprints))
    coords = np.concatenate(coords) / footprint
    low, high = coords.min(0) - margin, coords.max(0) + margin
    extent = high - low  # (along e1, along e2), in pixels of that footprint
    texture, scale = _fit_texture(texture, extent, min_magnification, max_magnification)
    middle = (low + high) / 2 * footprint
    return PlanarObject(
        normal=normal,
        twist=np.asarray(twist, dtype=np.float64),
        texture=texture,
        origin=center + middle[0] * e1 + middle[1] * e2,
        axes=np.stack([e1, e2]),
        texel_size=scale * footprint,
        name=name,
        texture_name=texture_name,
    )


def _exposure_instants(exposure: Exposure, num_frames: int, per_frame: int = 17) -> np.ndarray:
    """Dense instants covering every frame's exposure and centre."""
    tau = exposure.duty_cycle
    offsets = np.linspace(-tau / 2, tau / 2, per_frame)
    return np.concatenate([i + np.append(offsets, 0.0) for i in range(num_frames)])


def planar_setup(
    name: str,
    *,
    size: tuple[int, int] = (640, 480),
    num_frames: int = 3,
    seed: int = 0,
    texture: str | None = None,
) -> SceneSetup:
    """The geometry of planar scene ``name`` (nothing rendered).

    Parameters
    ----------
    name : str
        A key of :data:`PLANAR_MOTIONS`.
    size : tuple of int
        ``(width, height)``.
    num_frames : int
    seed : int
        Draws the plane's tilt (up to 6 degrees about x and y).

    At the middle of the clip, instant ``(num_frames - 1) / 2``, the plane crosses
    the optical axis at the motion's ``distance`` with that tilt; the scene's
    reference pose (instant 0, the centre of frame 0) follows from the motion.
    texture : str, optional
        A name of :data:`~stereodeblur.synth.textures.TEXTURE_NAMES`; by default
        the scenes cycle through them in order.
    """
    if name not in PLANAR_MOTIONS:
        raise InputError(
            f"unknown planar scene {name!r}, expected one of {_NAMES}",
            parameter="scenes",
        )
    motion = PLANAR_MOTIONS[name]
    if texture is None:
        texture = TEXTURE_NAMES[list(PLANAR_MOTIONS).index(name) % len(TEXTURE_NAMES)]
    camera = planar_camera(size)
    exposure = Exposure(FRAME_RATE, motion.exposure)
    rng = np.random.default_rng(seed)
    tilt = np.deg2rad(rng.uniform(-MAX_TILT_DEGREES, MAX_TILT_DEGREES, 2))
    unit = so3_exp(np.array([tilt[0], tilt[1], 0.0])) @ np.array([0.0, 0.0, 1.0])
    # The plane as placed at the middle of the clip, moved back to instant 0.
    middle = unit / (motion.distance * unit[2])
    back = se3_exp(-(num_frames - 1) / 2 * np.asarray(motion.twist, dtype=np.float64))
    normal = move_plane(middle, back[:3, :3], back[:3, 3])
    plane = textured_plane(
        load_texture(texture),
        camera,
        size,
        normal,
        np.array(motion.twist),
        _exposure_instants(exposure, num_frames),
        texture_name=texture,
    )
    return SceneSetup(name, camera, exposure, size, num_frames, (plane,))


def make_planar_scene(
    name: str,
    *,
    size: tuple[int, int] = (640, 480),
    num_frames: int = 3,
    num_samples: int = 48,
    seed: int = 0,
) -> RenderedScene:
    """Render planar scene ``name``: blurred stereo frames and their ground truth.

    ``num_samples`` instants are averaged per blurred frame (at least 32 for a
    smooth blur; the benchmark uses 48). See :func:`planar_setup` for the rest.
    """
    setup = planar_setup(name, size=size, num_frames=num_frames, seed=seed)
    return render_scene(setup, num_samples=num_samples)


def _norm(vectors: np.ndarray) -> np.ndarray:
    return np.hypot(vectors[..., 0], vectors[..., 1])


@dataclass(frozen=True)
class Curvature:
    """How far true image trajectories leave the linear displacement model, in pixels.

    Attributes
    ----------
    max_px, mean_px : float
        Largest and mean (over pixels) deviation.
    blur_max_px, blur_mean_px : float
        Largest and mean length of the true trajectories over the exposure.
    """

    max_px: float
    mean_px: float
    blur_max_px: float
    blur_mean_px: float


def curvature_px(
    scene: SceneSetup | RenderedScene,
    frame: int,
    *,
    num_samples: int | None = None,
    border: int = 10,
) -> Curvature:
    """Deviation of the true left-view trajectories of ``frame`` from the displacement model.

    For the point seen at pixel ``x`` at the centre of ``frame``, ``p(s)`` is its
    true image position ``s`` frame intervals later (exact, from the geometry),
    ``f = p(1) - x`` and ``b = p(-1) - x`` its forward and backward flow. The
    displacement model (Kim and Lee; paper Table 1) places it at ``x + s f`` for
    ``s > 0`` and ``x + |s| b`` for ``s < 0``. The deviation of a pixel is the largest
    ``|p(s) - model(s)|`` over the exposure's sample instants; it is reported for
    pixels at least ``border`` pixels from the image edge that see an object.
    Works from geometry only, so a :class:`~stereodeblur.synth.render.SceneSetup`
    needs no rendering. Occlusions are ignored (every point is followed).

    Parameters
    ----------
    scene : SceneSetup or RenderedScene
    frame : int
    num_samples : int, optional
        Instants per exposure; the scene's own number, or 48.
    border : int
        Pixels ignored along each image edge.
    """
    if num_samples is None:
        num_samples = getattr(scene, "num_samples", 48)
    camera, size, objects = scene.camera, scene.size, scene.objects
    width, height = size
    if 2 * border >= min(width, height):
        raise ValueError(f"border {border} leaves no pixels of a {width}x{height} image")
    hits = cast_rays(objects, camera, "left", size, frame)
    grid = np.stack(np.meshgrid(np.arange(width), np.arange(height)), -1).astype(np.float64)
    forward, backward = track(objects, camera, "left", hits, [frame + 1, frame - 1]) - grid
    tau = scene.exposure.duty_cycle
    fractions = scene.exposure.sample_fractions(int(num_samples))
    deviation = np.zeros((height, width))
    length = np.zeros((height, width))
    # Path length over [-tau/2, tau/2] through the samples; deviation at the samples.
    instants = np.concatenate([[-tau / 2], fractions, [tau / 2]])
    previous = None
    for j, s in enumerate(instants):
        p = track(objects, camera, "left", hits, [frame + s])[0]
        if previous is not None:
            length += _norm(p - previous)
        previous = p
        if 0 < j < len(instants) - 1:
            model = grid + (s * forward if s > 0 else -s * backward)
            deviation = np.maximum(deviation, _norm(p - model))
    keep = np.zeros((height, width), dtype=bool)
    keep[border : height - border, border : width - border] = True
    keep &= hits.object_id >= 0
    if not keep.any():
        raise ValueError(f"no object is seen away from the border in frame {frame}")
    return Curvature(
        max_px=float(deviation[keep].max()),
        mean_px=float(deviation[keep].mean()),
        blur_max_px=float(length[keep].max()),
        blur_mean_px=float(length[keep].mean()),
    )


def write_rendered_scene(
    scene: RenderedScene, root: str | os.PathLike, *, overwrite: bool = False
) -> Path:
    """Write ``scene`` to the folder ``root`` (SCENE_FORMAT.md plus ``gt/objects.json``).

    Frames and sharp images are 16-bit linear PNGs; disparity and mixed masks for
    both views, flow for the left view, and ``gt/objects.json`` (module docstring).
    """
    from ..io.scene import CameraInfo, SceneWriter

    root = Path(root)
    info = CameraInfo(scene.camera, scene.exposure, "linear")
    writer = SceneWriter(root, info, overwrite=overwrite)
    for view in ("left", "right"):
        for i in range(scene.num_frames):
            writer.write_frame(view, i, scene.frames[view][i], bit_depth=16)
            writer.write_gt_sharp(view, i, scene.sharp[view][i])
            writer.write_gt_disparity(view, i, scene.disparity[view][i])
            writer.write_gt_mixed(view, i, scene.mixed[view][i])
    for i, flow in enumerate(scene.flow):
        writer.write_gt_flow("left", i, flow)
    objects = {
        "objects": [describe_object(k, obj) for k, obj in enumerate(scene.objects)],
        "frame_rate": scene.exposure.frame_rate,
        "reference": "frame 0 centre",
    }
    atomic_write(root / "gt" / "objects.json", (json.dumps(objects, indent=2) + "\n").encode())
    return root


def write_planar_set(
    root: str | os.PathLike,
    *,
    size: tuple[int, int] = (640, 480),
    names=None,
    progress: Callable[[str], None] | None = None,
) -> list[Path]:
    """Render and write every planar scene (or those in ``names``) to ``root/<name>/``.

    ``progress`` is called with each scene's name before it is rendered.
    """
    names = list(PLANAR_MOTIONS) if names is None else list(names)
    unknown = [n for n in names if n not in PLANAR_MOTIONS]
    if unknown:
        raise InputError(
            f"unknown planar scene {unknown[0]!r}, expected one of {_NAMES}",
            parameter="scenes",
        )
    paths = []
    for name in names:
        if progress is not None:
            progress(name)
        scene = make_planar_scene(name, size=size)
        paths.append(write_rendered_scene(scene, Path(root) / name))
    return paths
