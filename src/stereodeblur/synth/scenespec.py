"""Scenes of the randomised family as values: the spec, its split, its renderer setup, its files.

See :mod:`stereodeblur.synth.family` for what the family holds and how scenes are drawn;
this module turns a drawn :class:`FamilySpec` into the renderer's objects
(:func:`family_setup`) and into a scene folder (:func:`write_family_scene`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure
from ..geometry.plane import move_plane
from ..geometry.rigid import se3_exp, so3_exp
from ..progress import ProgressCallback, report
from .objects import Solid, _moved, add_noise, solid_object
from .patterns import SurfaceTexture, make_texture
from .planar import FRAME_RATE, _exposure_instants, planar_camera, textured_plane
from .render import PlanarObject, SceneSetup, render_scene

NUM_FRAMES = 3
MIDDLE = 1.0
"""Frame whose centre the geometry is given at (and whose blur is chosen)."""

BLUR_RANGE = (5.0, 80.0)
"""Longest blur of frame 1, pixels: the target is drawn log-uniformly inside."""

BLUR_BORDER_FRACTION = 0.025
"""Border (fraction of the width) left out of the longest blur, as the benches' PSNR."""

NOISE_MAX = 0.02
SIZES = ((320, 240), (640, 480))
"""The sizes the protocol renders; any size works."""

TRAIN_SEEDS = range(0, 1000)
TEST_SEEDS = range(1000, 2000)

PHOTO_MAGNIFICATION = 2.5
"""Pixels per texel of photographs where a surface faces the camera (as the object set)."""

SUPERSAMPLING = 3
"""Rays per pixel side: images are means over the pixel's area (as a sensor's are), so that
surfaces seen minified (far road and facades) do not alias (see
:func:`~stereodeblur.synth.render.render_scene`)."""

PATTERN_MAGNIFICATION = 1.0
"""Pixels per texel of procedural patterns: a stripe period in texels is one in pixels."""

FAMILY_KINDS = ("family", "street")


def split(seed: int) -> str:
    """``'train'`` for seeds 0-999, ``'test'`` for seeds 1000-1999 (module docstring)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise InputError(f"seed must be an integer, got {seed!r}")
    if seed in TRAIN_SEEDS:
        return "train"
    if seed in TEST_SEEDS:
        return "test"
    raise InputError(f"seed must be in 0-1999 (0-999 train, 1000-1999 test), got {seed}")


def seeds_of(part: str, count: int) -> list[int]:
    """The first ``count`` seeds of the split ``part`` (``'train'`` or ``'test'``)."""
    seeds = {"train": TRAIN_SEEDS, "test": TEST_SEEDS}.get(part)
    if seeds is None:
        raise InputError(f"split must be 'train' or 'test', got {part!r}")
    if not 0 <= count <= len(seeds):
        raise InputError(f"the {part} split has {len(seeds)} seeds, asked for {count}")
    return list(seeds[:count])


@dataclass(frozen=True)
class Part:
    """One foreground object: a solid of :mod:`~stereodeblur.synth.objects` and its texture.

    ``solid.velocity`` and ``solid.omega`` are its own motion (added to the camera's);
    ``texel_size`` (scene units) overrides the magnification rule if not None.
    """

    solid: Solid
    texture: SurfaceTexture
    texel_size: float | None = None


@dataclass(frozen=True)
class Backdrop:
    """An unbounded plane behind everything, static in the world, filling both views.

    ``depth`` on the optical axis and ``tilt`` (rotation vector of its normal from
    ``+z``) at the centre of frame 1.
    """

    texture: SurfaceTexture
    depth: float
    tilt: tuple[float, float, float]


@dataclass(frozen=True)
class FamilySpec:
    """One scene of the family, fully determined (rendering only follows from it).

    Attributes
    ----------
    seed : int
    kind : {'family', 'street'}
    split : {'train', 'test'}
    size : tuple of int
        ``(width, height)``.
    duty_cycle : float
        Exposure time times frame rate.
    camera_twist : tuple of float
        Camera motion per frame interval (module conventions), already scaled.
    backdrop : Backdrop or None
    parts : tuple of Part
        Own motions already scaled.
    noise : float
        Deviation of the Gaussian noise on the blurred frames.
    blur_target, blur_px : float
        Drawn and reached longest blur of frame 1 (left view), pixels.
    num_samples : int
        Instants averaged per blurred frame (a multiple of ``supersampling**2``).
    description : str
    supersampling : int
        Rays per pixel side (:data:`SUPERSAMPLING`).
    """

    seed: int
    kind: str
    split: str
    size: tuple[int, int]
    duty_cycle: float
    camera_twist: tuple[float, ...]
    backdrop: Backdrop | None
    parts: tuple[Part, ...]
    noise: float
    blur_target: float
    blur_px: float
    num_samples: int
    description: str = ""
    supersampling: int = SUPERSAMPLING

    @property
    def name(self) -> str:
        """Folder name, e.g. ``family_0007`` or ``street_1003``."""
        return f"{self.kind}_{self.seed:04d}"

    def textures(self) -> list[SurfaceTexture]:
        """Every surface texture of the scene, backdrop first."""
        own = [p.texture for p in self.parts]
        return ([self.backdrop.texture] if self.backdrop is not None else []) + own


def _blank(width, height) -> np.ndarray:
    """A black texture of the shape :func:`make_texture` gives (geometry only)."""
    return np.zeros((max(2, int(round(height))), max(2, int(round(width))), 3), np.float32)


def _patch_maker(texture: SurfaceTexture, blank: bool):
    if blank:
        return _blank
    return lambda width, height: make_texture(texture, width, height)


def _magnification(texture: SurfaceTexture) -> float:
    return PHOTO_MAGNIFICATION if texture.kind == "photo" else PATTERN_MAGNIFICATION


def _part_object(part: Part, fx: float, camera_twist: np.ndarray, *, blank: bool = False):
    """The renderer's object of ``part`` at the centre of frame 1 (camera motion included)."""
    obj = solid_object(
        part.solid,
        fx,
        patch=_patch_maker(part.texture, blank),
        magnification=_magnification(part.texture),
        texel_size=part.texel_size,
    )
    return replace(obj, twist=obj.twist - camera_twist)


def _backdrop_normal(backdrop: Backdrop) -> np.ndarray:
    unit = so3_exp(np.asarray(backdrop.tilt, dtype=np.float64)) @ np.array([0.0, 0.0, 1.0])
    return unit / (unit[2] * backdrop.depth)


def _probe_backdrop(backdrop: Backdrop, twist: np.ndarray) -> PlanarObject:
    """The backdrop's geometry at the centre of frame 1 with a blank texture (measuring)."""
    normal = _backdrop_normal(backdrop)
    origin = np.array([0.0, 0.0, 1.0 / normal[2]])
    unit = normal / np.linalg.norm(normal)
    e1 = np.array([1.0, 0.0, 0.0]) - unit[0] * unit
    e1 /= np.linalg.norm(e1)
    axes = np.stack([e1, np.cross(unit, e1)])
    return PlanarObject(normal, twist, np.zeros((2, 2, 3), np.float32), origin, axes, 1.0)


def _final_backdrop(
    backdrop: Backdrop, camera, size, exposure, twist, *, blank: bool = False
) -> PlanarObject:
    """The backdrop in the reference pose, its texture covering both views all clip long.

    ``blank``: a 2 x 2 black texture (geometry only; still checks that it fills the views).
    """
    back = se3_exp(-MIDDLE * twist)
    normal = move_plane(_backdrop_normal(backdrop), back[:3, :3], back[:3, 3])
    instants = _exposure_instants(exposure, NUM_FRAMES)
    texture = backdrop.texture
    magnification = _magnification(texture)
    if blank:
        return textured_plane(
            _blank(2, 2),
            camera,
            size,
            normal,
            twist,
            instants,
            min_magnification=0.0,
            max_magnification=math.inf,
        )
    if texture.kind == "photo":
        from .textures import load_texture

        source = load_texture(texture.photo)
    else:
        source = np.zeros((2, 2, 3), np.float32)
    plane = textured_plane(
        source,
        camera,
        size,
        normal,
        twist,
        instants,
        name="backdrop",
        texture_name=texture.label(),
        min_magnification=magnification,
        max_magnification=2 * magnification if texture.kind == "photo" else magnification,
    )
    if texture.kind != "photo":
        h, w = plane.texture.shape[:2]
        plane = replace(plane, texture=make_texture(texture, w, h))
    return plane


def middle_objects(spec_like, camera) -> list:
    """The objects at the centre of frame 1 with blank textures, for measuring."""
    camera_twist = np.asarray(spec_like.camera_twist, dtype=np.float64)
    objects = []
    if spec_like.backdrop is not None:
        objects.append(_probe_backdrop(spec_like.backdrop, -camera_twist))
    objects += [_part_object(p, camera.fx, camera_twist, blank=True) for p in spec_like.parts]
    return objects


def family_setup(spec: FamilySpec, *, blank: bool = False) -> SceneSetup:
    """The renderer's :class:`~stereodeblur.synth.render.SceneSetup` of ``spec``.

    ``blank``: black textures of the same shapes (the geometry only, quickly).
    """
    camera = planar_camera(spec.size)
    exposure = Exposure(FRAME_RATE, spec.duty_cycle / FRAME_RATE)
    camera_twist = np.asarray(spec.camera_twist, dtype=np.float64)
    objects = []
    if spec.backdrop is not None:
        objects.append(
            _final_backdrop(spec.backdrop, camera, spec.size, exposure, -camera_twist, blank=blank)
        )
    for part in spec.parts:
        obj = _part_object(part, camera.fx, camera_twist, blank=blank)
        objects.append(_moved(obj, se3_exp(-MIDDLE * obj.twist)))
    return SceneSetup(spec.name, camera, exposure, spec.size, NUM_FRAMES, tuple(objects))


def spec_json(spec: FamilySpec) -> str:
    """``spec`` as JSON text (what ``gt/family.json`` holds)."""
    return json.dumps({"name": spec.name, **asdict(spec)}, indent=1) + "\n"


def write_family_scene(
    spec: FamilySpec,
    root: str | os.PathLike,
    *,
    num_samples: int | None = None,
    progress: ProgressCallback | None = None,
) -> Path:
    """Render ``spec`` and write it to the new scene folder ``root``.

    The scene is written to ``root`` + ``.partial`` and renamed at the end, so ``root``
    exists only complete. ``num_samples`` overrides ``spec.num_samples`` (tests).

    Raises
    ------
    InputError
        If ``root`` exists.
    """
    from .planar import write_rendered_scene

    root = Path(root)
    if root.exists():
        raise InputError(f"scene folder {root} exists already")
    partial = root.with_name(root.name + ".partial")
    if partial.exists():
        shutil.rmtree(partial)
    report(progress, f"{spec.name}: rendering")
    samples = spec.num_samples if num_samples is None else int(num_samples)
    scene = render_scene(family_setup(spec), num_samples=samples, supersampling=spec.supersampling)
    if spec.noise > 0:
        scene = add_noise(scene, spec.noise, seed=spec.seed)
    write_rendered_scene(scene, partial)
    (partial / "gt" / "family.json").write_text(spec_json(spec), encoding="utf-8")
    partial.rename(root)
    report(progress, f"{spec.name}: written")
    return root
