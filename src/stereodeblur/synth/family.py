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

Rendering
---------
As the object set (:func:`stereodeblur.synth.render.render_scene`), with ``num_samples``
instants per blurred frame (1.5 per pixel of the longest blur, 48 to 160) and
supersampling (:data:`~stereodeblur.synth.scenespec.SUPERSAMPLING` rays per pixel side):
images are means over each pixel's area, as a sensor's are, so that surfaces seen
minified (the far road, stripes of 2 px) do not alias in the sharp ground truth.

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

import math
from dataclasses import replace

import numpy as np

from ..errors import InputError
from .blurlength import longest_blur, scale_for_blur
from .objects import Solid
from .patterns import draw_texture
from .planar import planar_camera
from .render import PlanarObject, cast_rays
from .scenespec import (  # noqa: F401 (the family's public names, re-exported)
    BLUR_BORDER_FRACTION,
    BLUR_RANGE,
    FAMILY_KINDS,
    MIDDLE,
    NOISE_MAX,
    NUM_FRAMES,
    PATTERN_MAGNIFICATION,
    PHOTO_MAGNIFICATION,
    SIZES,
    TEST_SEEDS,
    TRAIN_SEEDS,
    Backdrop,
    FamilySpec,
    Part,
    family_setup,
    middle_objects,
    seeds_of,
    spec_json,
    split,
    write_family_scene,
)


class Rejected(Exception):
    """A drawn scene that breaks a rule (objects behind the camera, views not covered)."""


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
    rays = spec.supersampling**2  # every pixel offset equally often
    num_samples = rays * math.ceil(min(160, max(48, 1.5 * blur)) / rays)
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
