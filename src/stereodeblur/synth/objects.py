"""The object benchmark: several rigidly moving solids in front of a textured background.

The scenes of :data:`OBJECT_SCENES` play the part of the paper's ray-traced
scenes (*apples*, *bunny*, *chair*, *squares*, *triplane*; Sec. 4, Tables 2-4):
textured spheres, boxes, a cylinder and tilted bounded planes, each with its own
constant twist per frame interval, in front of an unbounded textured background
plane (static, panning or approaching). Every blurred frame is the mean of
``num_samples`` exact instantaneous ray-cast images
(:func:`stereodeblur.synth.render.render_scene`), so motion boundaries mix
foreground and background exactly as a camera would; ``gt/mixed`` marks the pixels
whose object changes during the exposure.

Geometry is given at the middle of the clip, instant ``m = (num_frames - 1) / 2``
(frame 1 of the default three), and moved back to the reference pose at instant 0
(the centre of frame 0) with the object's own motion. An object that spins about
its own centre ``c`` with angular velocity ``omega`` while ``c`` moves with
velocity ``v`` has the twist ``(v - omega x c, omega)`` (left-camera coordinates,
per frame interval). Motions are casual: about 3 to 20 pixels of blur at 640 x 480.

Camera and timing are those of the planar set (:func:`~stereodeblur.synth.planar.
planar_camera`: ``fx = 0.8 * width``, baseline 0.12 m, 20 frames per second,
exposure 0.04 s). Textures are scaled with the image size, about
:data:`MAGNIFICATION` = 2.5 pixels per texel where an object faces the camera
(the background 2.5 to 5).

Noise: the ``_noisy`` variant of a scene adds white Gaussian noise of deviation
``noise`` (:data:`NOISE_SIGMA` = 0.01) to the blurred frames only, then clips to
[0, 1]. The noise is drawn from ``np.random.default_rng(seed)``, one
``standard_normal((H, W, 3))`` array per frame, left view frames 0, 1, ... then
the right view's, in that order (see :func:`add_noise`). Sharp images, disparity,
flow and masks are those of the clean scene.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure
from ..geometry.plane import move_plane
from ..geometry.rigid import se3_exp, so3_exp
from .planar import (
    EXPOSURE,
    FRAME_RATE,
    _exposure_instants,
    _resize,
    planar_camera,
    textured_plane,
    write_rendered_scene,
)
from .render import (
    BoxObject,
    CylinderObject,
    PlanarObject,
    RenderedScene,
    SceneSetup,
    SphereObject,
    periodic_texture,
    render_scene,
)
from .textures import load_texture

NOISE_SIGMA = 0.01
"""Noise deviation of the ``_noisy`` variants (intensities in [0, 1])."""

MAGNIFICATION = 2.5
"""Pixels per texel where an object faces the camera at its centre's depth.

Well above 1, so that the bilinear interpolation of the blur operators reproduces
the rendered (point-sampled) images: at 1.3 pixels per texel the operator built
from the exact motion misses rendered blur by an rms of about 0.01 on objects,
the size of the blur itself for slow motions; at 2.5 by about 0.003-0.006."""

NOISY_SUFFIX = "_noisy"


# --- object specifications (geometry at the middle of the clip, scale-free) ------------------


@dataclass(frozen=True)
class Background:
    """The unbounded background plane.

    ``depth`` on the optical axis and ``tilt`` (a rotation vector of its normal from
    ``+z``) at the middle of the clip; ``(velocity, omega)`` is its twist about the
    camera's origin (the opposite of a camera motion).
    """

    texture: str
    depth: float = 6.0
    tilt: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    omega: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Solid:
    """One foreground object at the middle of the clip.

    ``kind`` is ``'sphere'`` (``size = (radius,)``), ``'cylinder'`` (``(radius,
    half_height)``), ``'box'`` (three half sizes) or ``'square'`` (a bounded plane,
    ``(half_width, half_height)``, facing ``-z`` before ``orientation`` turns it).
    ``orientation`` is a rotation vector (radians) of the local frame; ``velocity``
    (metres per frame interval) moves the centre, ``omega`` (radians per frame
    interval) spins the object about its centre.
    """

    kind: str
    texture: str
    center: tuple[float, float, float]
    size: tuple[float, ...]
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    omega: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = ""


@dataclass(frozen=True)
class ObjectScene:
    """A scene of the object set: what it stands for, the background and the solids."""

    description: str
    background: Background
    solids: tuple[Solid, ...]


# fmt: off
OBJECT_SCENES: dict[str, ObjectScene] = {
    "spheres": ObjectScene(
        "three spinning textured spheres before a wall, camera drifting (the paper's apples)",
        Background("gravel", velocity=(0.03, 0.0, 0.0)),
        (
            Solid("sphere", "coffee", (-0.8, 0.2, 3.0), (0.55,), name="left sphere",
                  velocity=(0.10, -0.02, 0.0), omega=(0.0, 0.25, 0.05)),
            Solid("sphere", "rocket", (0.75, 0.15, 3.4), (0.5,), name="right sphere",
                  velocity=(-0.07, 0.03, -0.05), omega=(0.2, 0.0, -0.1)),
            Solid("sphere", "astronaut", (0.0, -0.5, 2.7), (0.42,), name="top sphere",
                  velocity=(0.02, 0.07, 0.04), omega=(-0.15, 0.25, 0.0)),
        ),
    ),
    "boxes": ObjectScene(
        "three turning boxes before a panning wall (the paper's chair)",
        Background("brick", omega=(0.0, 0.006, 0.0)),
        (
            Solid("box", "immunohistochemistry", (-0.7, -0.1, 3.0), (0.5, 0.4, 0.4),
                  velocity=(0.07, 0.0, 0.0), omega=(0.0, 0.12, 0.0),
                  orientation=(0.3, 0.5, 0.1), name="left box"),
            Solid("box", "motorcycle", (0.75, -0.3, 2.8), (0.35, 0.35, 0.35),
                  velocity=(-0.04, 0.05, -0.03), omega=(0.15, 0.0, 0.1),
                  orientation=(0.6, -0.4, 0.2), name="cube"),
            Solid("box", "coffee", (0.1, 0.75, 3.2), (0.8, 0.08, 0.4),
                  velocity=(0.0, -0.03, -0.08), omega=(0.0, 0.0, 0.05),
                  orientation=(0.25, 0.1, 0.0), name="slab"),
        ),
    ),
    "squares": ObjectScene(
        "four tilted textured squares, each moving its own way (the paper's squares)",
        Background("camera", velocity=(0.0, 0.02, 0.0)),
        (
            Solid("square", "astronaut", (-0.75, -0.4, 2.8), (0.5, 0.5), name="top left",
                  velocity=(0.08, 0.03, 0.0), omega=(0.0, 0.0, 0.08),
                  orientation=(0.2, 0.35, 0.0)),
            Solid("square", "rocket", (0.8, -0.45, 3.4), (0.55, 0.55), name="top right",
                  velocity=(-0.05, 0.04, -0.08), omega=(0.1, 0.0, 0.0),
                  orientation=(-0.3, -0.25, 0.1)),
            Solid("square", "coffee", (-0.7, 0.6, 3.2), (0.55, 0.45), name="bottom left",
                  velocity=(0.0, -0.07, 0.06), omega=(0.0, 0.1, 0.0),
                  orientation=(0.1, -0.4, -0.1)),
            Solid("square", "immunohistochemistry", (0.55, 0.45, 2.6), (0.4, 0.4),
                  velocity=(-0.07, -0.02, 0.0), omega=(0.0, 0.0, -0.12),
                  orientation=(0.35, 0.2, 0.3), name="bottom right"),
        ),
    ),
    "triplane": ObjectScene(
        "three large tilted planes: yawing, approaching, rising (the paper's triplane)",
        Background("grass"),
        (
            Solid("square", "motorcycle", (-1.1, 0.0, 3.6), (0.75, 1.1), name="left plane",
                  omega=(0.0, 0.15, 0.0), orientation=(0.0, 0.5, 0.0)),
            Solid("square", "astronaut", (0.0, 0.1, 3.0), (0.6, 0.75), name="middle plane",
                  velocity=(0.0, 0.0, -0.2), orientation=(0.15, 0.0, 0.0)),
            Solid("square", "coffee", (1.1, -0.05, 3.4), (0.7, 1.05), name="right plane",
                  velocity=(0.0, -0.1, 0.0), orientation=(0.0, -0.5, 0.05)),
        ),
    ),
    "cylinder_mix": ObjectScene(
        "a spinning cylinder, a sphere and a box while the camera approaches (the paper's bunny)",
        Background("brick", depth=6.5, tilt=(0.0, 0.2, 0.0), velocity=(0.0, 0.0, -0.1)),
        (
            Solid("cylinder", "motorcycle", (-0.45, 0.05, 2.8), (0.42, 0.7), name="cylinder",
                  velocity=(0.05, 0.0, -0.04), omega=(0.0, 0.3, 0.0),
                  orientation=(1.45, 0.0, 0.1)),
            Solid("sphere", "immunohistochemistry", (0.8, -0.3, 3.3), (0.45,), name="sphere",
                  velocity=(-0.06, 0.04, 0.0), omega=(0.1, -0.2, 0.0)),
            Solid("box", "astronaut", (0.6, 0.65, 2.7), (0.3, 0.2, 0.28), name="box",
                  velocity=(-0.03, -0.05, -0.05), omega=(0.1, 0.1, 0.15),
                  orientation=(0.4, 0.7, 0.0)),
        ),
    ),
}
# fmt: on
"""The object scene set, by name (each also exists as ``NAME_noisy``)."""

_NAMES = ", ".join(OBJECT_SCENES)


# --- building the renderer's objects ---------------------------------------------------------


def _twist(center, velocity, omega) -> np.ndarray:
    """Twist spinning about ``center`` with ``omega`` while ``center`` moves with ``velocity``."""
    c, v, w = (np.asarray(a, dtype=np.float64) for a in (center, velocity, omega))
    return np.concatenate([v - np.cross(w, c), w])


def _texture_patch(name: str, width: int, height: int) -> np.ndarray:
    """Texture ``name`` cropped to the aspect ``width : height`` and resized to that many texels."""
    texture = load_texture(name)
    h, w = texture.shape[:2]
    width, height = max(2, int(round(width))), max(2, int(round(height)))
    if w * height > h * width:  # too wide: crop columns
        keep = max(2, round(h * width / height))
        start = (w - keep) // 2
        texture = texture[:, start : start + keep]
    else:
        keep = max(2, round(w * height / width))
        start = (h - keep) // 2
        texture = texture[start : start + keep]
    if (width, height) == texture.shape[1::-1]:
        return np.ascontiguousarray(texture)
    if width <= texture.shape[1]:
        return _resize(texture, width, height)
    import cv2

    return cv2.resize(texture, (width, height), interpolation=cv2.INTER_LINEAR)


def solid_object(
    solid: Solid,
    fx: float,
    *,
    patch=None,
    magnification: float = MAGNIFICATION,
    texel_size: float | None = None,
):
    """The renderer's object for ``solid``, in its middle-of-clip pose.

    ``patch(width, height)`` makes the texture of that many texels (default: the
    photograph ``solid.texture`` cropped and resized); ``magnification`` is the number
    of pixels per texel where the object faces the camera at its centre's depth, unless
    ``texel_size`` (scene units) is given.
    """
    center = np.asarray(solid.center, dtype=np.float64)
    frame = so3_exp(np.asarray(solid.orientation, dtype=np.float64))
    twist = _twist(center, solid.velocity, solid.omega)
    texel = texel_size or center[2] * magnification / fx  # scene units per texel
    name = solid.name or solid.kind
    if patch is None:

        def patch(width, height):
            return _texture_patch(solid.texture, width, height)

    if solid.kind == "sphere":
        (radius,) = solid.size
        half_turn = np.pi * radius / texel
        texture = periodic_texture(patch(half_turn, half_turn + 1))
        return SphereObject(center, radius, frame, twist, texture, name, solid.texture)
    if solid.kind == "cylinder":
        radius, half_height = solid.size
        half_turn = max(2, round(np.pi * radius / texel))
        rows = 2 * half_height / (np.pi * radius / half_turn) + 1
        texture = periodic_texture(patch(half_turn, rows))
        return CylinderObject(
            center, radius, half_height, frame, twist, texture, name, solid.texture
        )
    if solid.kind == "box":
        half = np.asarray(solid.size, dtype=np.float64)
        side = 2 * half.max() / texel * 1.3 + 1
        texture = patch(side, side)
        return BoxObject(center, half, frame, twist, texture, texel, name, solid.texture)
    if solid.kind == "square":
        half_w, half_h = solid.size
        texture = patch(2 * half_w / texel + 1, 2 * half_h / texel + 1)
        h, w = texture.shape[:2]
        texel = max(2 * half_w / (w - 1), 2 * half_h / (h - 1))
        axes = np.stack([frame[:, 0], frame[:, 1]])
        unit = -frame[:, 2]
        normal = unit / (unit @ center)
        return PlanarObject(
            normal, twist, texture, center, axes, texel, name, solid.texture, bounded=True
        )
    raise ValueError(f"unknown solid kind {solid.kind!r}")


def _moved(obj, M: np.ndarray):
    """``obj`` with its reference pose moved by the rigid transform ``M`` (4 x 4)."""
    R, T = M[:3, :3], M[:3, 3]
    if isinstance(obj, PlanarObject):
        return replace(
            obj,
            normal=move_plane(obj.normal, R, T),
            origin=R @ obj.origin + T,
            axes=obj.axes @ R.T,
        )
    return replace(obj, center=R @ obj.center + T, frame=R @ obj.frame)


def _background(spec: Background, camera, size, exposure, num_frames, middle) -> PlanarObject:
    unit = so3_exp(np.asarray(spec.tilt, dtype=np.float64)) @ np.array([0.0, 0.0, 1.0])
    point = np.array([0.0, 0.0, spec.depth])
    twist = np.concatenate([spec.velocity, spec.omega]).astype(np.float64)
    back = se3_exp(-middle * twist)
    normal = move_plane(unit / (unit @ point), back[:3, :3], back[:3, 3])
    return textured_plane(
        load_texture(spec.texture),
        camera,
        size,
        normal,
        twist,
        _exposure_instants(exposure, num_frames),
        name="background",
        texture_name=spec.texture,
        min_magnification=MAGNIFICATION,
        max_magnification=2 * MAGNIFICATION,
    )


def _base_name(name: str) -> tuple[str, bool]:
    base = name.removesuffix(NOISY_SUFFIX)
    if base not in OBJECT_SCENES:
        raise InputError(
            f"unknown object scene {name!r}, expected one of {_NAMES} (each also as NAME_noisy)"
        )
    return base, name != base


def object_setup(
    name: str, *, size: tuple[int, int] = (640, 480), num_frames: int = 3
) -> SceneSetup:
    """The geometry of object scene ``name`` (nothing rendered); see the module docstring.

    Parameters
    ----------
    name : str
        A key of :data:`OBJECT_SCENES` (a ``_noisy`` suffix is ignored here).
    size : tuple of int
        ``(width, height)``.
    num_frames : int
        The geometry of :data:`OBJECT_SCENES` is at instant ``(num_frames - 1) / 2``.
    """
    base, _ = _base_name(name)
    spec = OBJECT_SCENES[base]
    camera = planar_camera(size)
    exposure = Exposure(FRAME_RATE, EXPOSURE)
    middle = (int(num_frames) - 1) / 2
    objects = [_background(spec.background, camera, size, exposure, num_frames, middle)]
    for solid in spec.solids:
        obj = solid_object(solid, camera.fx)
        objects.append(_moved(obj, se3_exp(-middle * obj.twist)))
    return SceneSetup(base, camera, exposure, size, num_frames, tuple(objects))


def add_noise(scene: RenderedScene, sigma: float, *, seed: int = 0) -> RenderedScene:
    """``scene`` with white Gaussian noise of deviation ``sigma`` added to its blurred frames.

    The noise is drawn from ``np.random.default_rng(seed)``: one
    ``standard_normal((H, W, 3))`` per frame, left frames first, then right, each
    scaled by ``sigma``; the noisy frames are clipped to [0, 1]. Everything else is
    kept. The name gets the suffix ``_noisy``.
    """
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be a non-negative number, got {sigma!r}")
    rng = np.random.default_rng(seed)
    frames = {}
    for view in ("left", "right"):
        noisy = []
        for frame in scene.frames[view]:
            noise = rng.standard_normal(frame.shape) * sigma
            noisy.append(np.clip(frame + noise, 0.0, 1.0).astype(np.float32))
        frames[view] = tuple(noisy)
    return replace(scene, name=scene.name + NOISY_SUFFIX, frames=frames)


def make_object_scene(
    name: str,
    *,
    size: tuple[int, int] = (640, 480),
    num_frames: int = 3,
    num_samples: int = 48,
    noise: float = 0.0,
    seed: int = 0,
) -> RenderedScene:
    """Render object scene ``name``: blurred stereo frames and their ground truth.

    Parameters
    ----------
    name : str
        A key of :data:`OBJECT_SCENES`, or one with the suffix ``_noisy`` (which sets
        ``noise`` to :data:`NOISE_SIGMA` unless given).
    size : tuple of int
        ``(width, height)``.
    num_frames : int
    num_samples : int
        Instantaneous images averaged per blurred frame (at least 48 for the benchmark).
    noise : float
        Deviation of the Gaussian noise added to the blurred frames (:func:`add_noise`).
    seed : int
        Seed of the noise.
    """
    _, noisy = _base_name(name)
    if noisy and noise == 0.0:
        noise = NOISE_SIGMA
    scene = render_scene(
        object_setup(name, size=size, num_frames=num_frames), num_samples=num_samples
    )
    return add_noise(scene, noise, seed=seed) if noise > 0 else scene


def write_object_set(
    root: str | os.PathLike,
    *,
    size: tuple[int, int] = (640, 480),
    names=None,
    noise_variants: bool = True,
    num_samples: int = 48,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> list[Path]:
    """Render every object scene (or those in ``names``) and write it to ``root/<name>/``.

    With ``noise_variants`` each scene is also written with noise of deviation
    :data:`NOISE_SIGMA` (seed ``seed``) to ``root/<name>_noisy/``, from the same
    rendering. ``names`` may hold ``NAME_noisy`` entries to write that variant alone.
    ``progress`` is called with each scene's name before it is rendered.
    """
    names = list(OBJECT_SCENES) if names is None else list(names)
    wanted: dict[str, set[bool]] = {}
    for name in names:
        base, noisy = _base_name(name)
        wanted.setdefault(base, set()).update({noisy, True} if noise_variants else {noisy})
    paths = []
    for base, variants in wanted.items():
        if progress is not None:
            progress(base)
        scene = make_object_scene(base, size=size, num_samples=num_samples)
        if False in variants:
            paths.append(write_rendered_scene(scene, Path(root) / base))
        if True in variants:
            noisy = add_noise(scene, NOISE_SIGMA, seed=seed)
            paths.append(write_rendered_scene(noisy, Path(root) / noisy.name))
    return paths
