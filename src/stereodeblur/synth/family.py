"""A seeded, randomised family of rendered scenes for calibrating defaults honestly.

:func:`family_scene` draws a scene from its ``seed`` (pure geometry, nothing rendered):
an unbounded background plane (3 to 9 m away, tilted by up to 23 degrees) and zero to
three foreground solids (bounded planes, boxes, spheres, cylinders), each with a
:class:`~stereodeblur.synth.patterns.SurfaceTexture` of a random kind (fine stripes and
hatching of period 2 to 8 px at any angle, photographs, nearly flat, high-contrast
edges, bright nearly saturated). The camera moves with a random combination of forward,
roll, yaw and lateral components (plus a little pitch and vertical motion); about half
the solids also move on their own. :func:`stereodeblur.synth.street.street_scene` draws
the semi-real driving scenes of the same family.

Motion scale
------------
Every twist is scaled together so that the *longest blur* of frame 1 of the left view
(:mod:`stereodeblur.synth.blurlength`: the longest true image path over the exposure,
pixels at least :data:`BLUR_BORDER` from the edge, on every second pixel) equals a target
drawn log-uniformly from :data:`BLUR_RANGE`; the measured value is ``blur_px``. The duty
cycle (exposure times frame rate, 20 frames per second) is drawn from 0.5 to 1.0; the
noise deviation is 0 for a third of the scenes, otherwise drawn from 0.002 to 0.02.

Split
-----
:func:`split`: seeds 0-999 are the training half (tune on these), seeds 1000-1999 the
test half (report on these only; never look at them while tuning). The rule is fixed.

Conventions
-----------
Geometry is given at the centre of frame 1 (the middle of the three frames) in
left-camera coordinates and moved back to the renderer's reference pose (centre of frame
0) with each object's twist. Twists are object motions per frame interval
(:mod:`stereodeblur.synth.render`): a camera moving with twist ``xi_c`` gives every
static object the twist ``-xi_c``; a solid's own motion (``velocity`` of its centre,
``omega`` about it) is added to that. The camera twist is
``(lateral, vertical, forward, pitch, yaw, roll)``: metres and radians per frame
interval, x right, y down, z forward. Camera: :func:`~stereodeblur.synth.planar.
planar_camera` (``fx = 0.8 * width``, baseline 0.12 m).

Written scenes (:func:`write_family_scene`) are those of
:func:`~stereodeblur.synth.planar.write_rendered_scene` (three frames, gt sharp,
disparity, flow, mixed, ``gt/objects.json``) plus ``gt/family.json``, the spec.
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
from .blurlength import longest_blur, scale_for_blur
from .objects import Solid, _moved, add_noise, solid_object
from .patterns import SurfaceTexture, draw_texture, make_texture
from .planar import FRAME_RATE, _exposure_instants, planar_camera, textured_plane
from .render import PlanarObject, SceneSetup, cast_rays, render_scene

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
        Instants averaged per blurred frame.
    description : str
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

    @property
    def name(self) -> str:
        """Folder name, e.g. ``family_0007`` or ``street_1003``."""
        return f"{self.kind}_{self.seed:04d}"

    def textures(self) -> list[SurfaceTexture]:
        """Every surface texture of the scene, backdrop first."""
        own = [p.texture for p in self.parts]
        return ([self.backdrop.texture] if self.backdrop is not None else []) + own


class Rejected(Exception):
    """A drawn scene that breaks a rule (objects behind the camera, views not covered)."""


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


def _scaled(parts, backdrop, camera_twist, k: float):
    def own(part: Part) -> Part:
        solid = part.solid
        velocity = tuple(float(k * c) for c in solid.velocity)
        omega = tuple(float(k * c) for c in solid.omega)
        return replace(part, solid=replace(solid, velocity=velocity, omega=omega))

    return tuple(own(p) for p in parts), tuple(float(k * c) for c in camera_twist)


def _check_in_front(spec: FamilySpec, camera) -> None:
    """Solids stay 0.3 m in front of the camera over the clip's exposures."""
    tau = spec.duty_cycle
    instants = np.linspace(-MIDDLE - tau / 2, NUM_FRAMES - 1 - MIDDLE + tau / 2, 9)
    for obj in middle_objects(spec, camera):
        if isinstance(obj, PlanarObject):
            continue
        for s in instants:
            R, T = obj.pose(s)
            if (R @ obj.center + T)[2] - obj.bounding_radius < 0.3:
                raise Rejected(f"{obj.name} comes closer than 0.3 m to the camera")


def _check_covered(spec: FamilySpec, camera, *, stride: int = 6) -> None:
    """Every pixel of both views sees a surface at the clip's first, middle and last instant."""
    setup = family_setup(spec, blank=True)
    tau = spec.duty_cycle
    for s in (-tau / 2, MIDDLE, NUM_FRAMES - 1 + tau / 2):
        for view in ("left", "right"):
            hits = cast_rays(setup.objects, camera, view, spec.size, s, points=False)
            if np.any(hits.object_id[::stride, ::stride] < 0):
                raise Rejected(f"the {view} view is not covered at instant {s:.2f}")


def finish_spec(draft: FamilySpec) -> FamilySpec:
    """``draft`` (unit motion) scaled to its ``blur_target``, checked; raises :class:`Rejected`."""
    camera = planar_camera(draft.size)
    border = max(4, round(BLUR_BORDER_FRACTION * draft.size[0]))
    objects = middle_objects(draft, camera)
    try:
        k, _ = scale_for_blur(
            objects, camera, draft.size, draft.duty_cycle, draft.blur_target, border=border
        )
    except ValueError as error:
        raise Rejected(str(error)) from None
    parts, camera_twist = _scaled(draft.parts, draft.backdrop, draft.camera_twist, k)
    spec = replace(draft, parts=parts, camera_twist=camera_twist)
    blur = longest_blur(
        middle_objects(spec, camera), camera, spec.size, spec.duty_cycle, border=border
    )
    num_samples = int(min(160, max(48, math.ceil(1.5 * blur))))
    spec = replace(spec, blur_px=blur, num_samples=num_samples)
    _check_in_front(spec, camera)
    try:
        _check_covered(spec, camera)
    except ValueError as error:  # the backdrop cannot fill a view
        raise Rejected(str(error)) from None
    return spec


def draw_common(rng: np.random.Generator) -> dict:
    """Duty cycle, noise and blur target of one scene."""
    duty = float(rng.uniform(0.5, 1.0))
    noise = 0.0 if rng.random() < 1 / 3 else float(rng.uniform(0.002, NOISE_MAX))
    low, high = BLUR_RANGE
    target = float(np.exp(rng.uniform(np.log(low * 1.1), np.log(high * 0.97))))
    return {"duty_cycle": duty, "noise": noise, "blur_target": target}


def _camera_motion(rng: np.random.Generator) -> tuple[np.ndarray, str]:
    """A unit-scale camera twist combining forward, roll, yaw and lateral components."""
    names = ("forward", "roll", "yaw", "lateral")
    scales = {"forward": 0.1, "roll": 0.03, "yaw": 0.02, "lateral": 0.05}
    index = {"forward": 2, "roll": 5, "yaw": 4, "lateral": 0}
    chosen = [n for n in names if rng.random() < 0.55] or [names[int(rng.integers(4))]]
    twist = np.zeros(6)
    for n in chosen:
        twist[index[n]] = scales[n] * rng.uniform(0.3, 1.0) * rng.choice([-1.0, 1.0])
    if "forward" in chosen:
        twist[2] = abs(twist[2])  # the camera moves forward, towards the scene
    twist[1] = 0.01 * rng.uniform(-1, 1)  # a little vertical motion and pitch
    twist[3] = 0.004 * rng.uniform(-1, 1)
    return twist, "+".join(chosen)


_SOLID_KINDS = ("square", "box", "sphere", "cylinder")


def _draw_solid(rng: np.random.Generator, depth_limit: float, index: int) -> Part:
    kind = _SOLID_KINDS[int(rng.integers(len(_SOLID_KINDS)))]
    z = float(rng.uniform(1.8, max(2.0, 0.7 * depth_limit)))
    x = z * 0.625 * float(rng.uniform(-0.7, 0.7))
    y = z * 0.47 * float(rng.uniform(-0.7, 0.7))
    extent = z * float(rng.uniform(0.08, 0.2))
    sizes = {
        "square": (extent * rng.uniform(0.8, 1.4), extent * rng.uniform(0.8, 1.4)),
        "box": tuple(extent * rng.uniform(0.5, 1.0, 3)),
        "sphere": (extent,),
        "cylinder": (extent * 0.7, extent * rng.uniform(0.8, 1.5)),
    }
    orientation = tuple(float(a) for a in rng.uniform(-0.6, 0.6, 3))
    velocity, omega = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    if rng.random() < 0.5:  # moves on its own too
        velocity = tuple(float(c) for c in 0.05 * rng.uniform(-1, 1, 3))
        omega = tuple(float(c) for c in 0.1 * rng.uniform(-1, 1, 3))
    texture = draw_texture(rng)
    solid = Solid(
        kind,
        texture.label(),
        (x, y, z),
        tuple(float(s) for s in sizes[kind]),
        velocity=velocity,
        omega=omega,
        orientation=orientation,
        name=f"{kind} {index}",
    )
    return Part(solid, texture)


def _draft_family(seed: int, size, rng: np.random.Generator, common: dict) -> FamilySpec:
    depth = float(rng.uniform(3.0, 9.0))
    tilt = (float(rng.uniform(-0.4, 0.4)), float(rng.uniform(-0.4, 0.4)), 0.0)
    texture = draw_texture(rng)
    parts = tuple(_draw_solid(rng, depth, i) for i in range(int(rng.integers(0, 4))))
    if not parts and texture.kind == "flat":  # a scene is never flat throughout
        texture = draw_texture(rng, "photo")
    backdrop = Backdrop(texture, depth, tilt)
    twist, motion = _camera_motion(rng)
    textures = ", ".join(t.label() for t in [backdrop.texture] + [p.texture for p in parts])
    return FamilySpec(
        seed=seed,
        kind="family",
        split=split(seed),
        size=size,
        camera_twist=tuple(float(c) for c in twist),
        backdrop=backdrop,
        parts=parts,
        blur_px=math.nan,
        num_samples=0,
        description=f"camera {motion}; {len(parts)} solids; {textures}",
        **common,
    )


def _check_size(size) -> tuple[int, int]:
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError):
        raise InputError(f"size must be (width, height), got {size!r}") from None
    if width < 32 or height < 24:
        raise InputError(f"size must be at least 32 x 24, got {width} x {height}")
    return width, height


def draw_spec(seed: int, size, kind: str, drafter, *, attempts: int = 50) -> FamilySpec:
    """The first draft of ``drafter(seed, size, rng, common)`` that passes :func:`finish_spec`.

    ``common`` (:func:`draw_common`: blur target, noise, duty cycle) is drawn once, so
    that redrawing a rejected geometry does not bias the blur lengths.
    """
    size = _check_size(size)
    split(seed)
    rng = np.random.default_rng([int(seed), FAMILY_KINDS.index(kind)])
    common = draw_common(rng)
    reasons = []
    for _ in range(attempts):
        try:
            return finish_spec(drafter(int(seed), size, rng, common))
        except Rejected as why:
            reasons.append(str(why))
    raise RuntimeError(f"no valid {kind} scene for seed {seed}: {reasons[-1]}")


def family_scene(seed: int, *, size: tuple[int, int] = (320, 240)) -> FamilySpec:
    """The family scene of ``seed`` at ``size = (width, height)`` (module docstring)."""
    return draw_spec(seed, size, "family", _draft_family)


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
    scene = render_scene(family_setup(spec), num_samples=samples)
    if spec.noise > 0:
        scene = add_noise(scene, spec.noise, seed=spec.seed)
    write_rendered_scene(scene, partial)
    (partial / "gt" / "family.json").write_text(spec_json(spec), encoding="utf-8")
    partial.rename(root)
    report(progress, f"{spec.name}: written")
    return root
