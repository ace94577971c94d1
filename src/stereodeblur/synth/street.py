"""Semi-real driving scenes: photographs on the depth map of a street, camera driving through.

:func:`street_scene` draws, from its ``seed``, a street seen from a car: a ground plane
(the camera 1.2 to 1.7 m above it) textured with a photograph (gravel, brick, grass),
facades on both sides (3 to 7 m from the camera's path, 4 to 12 m high) and a backdrop at
the end of the street (30 to 45 m away), each with a photograph (sometimes a bright or a
striped one: white walls, fences), and one to four parked cars (boxes of about 1.8 x 1.5
x 4.4 m, photographs or bright paint), one of which may drive on its own. The camera
drives forward with a little yaw, roll and pitch; the motion is scaled, as for the
family (:mod:`stereodeblur.synth.family`), so that the longest blur of frame 1 is drawn
from 5 to 80 px (at the bottom corners, on the road, for most scenes). Same camera,
timing, noise, split rule and file layout as the family; ``kind`` is ``'street'``.

Photographs are placed at 2.5 pixels per texel where a surface is 4 m away (finer
further away). Surfaces are bounded planes and boxes of the renderer; every pixel of
both views sees one of them all clip long (checked when drawing).
"""

from __future__ import annotations

import math

import numpy as np

from .family import draw_spec
from .objects import Solid
from .patterns import SurfaceTexture, draw_texture
from .scenespec import PHOTO_MAGNIFICATION, FamilySpec, Part, split

REFERENCE_DEPTH = 4.0
"""Depth (metres) at which photographs are seen at :data:`PHOTO_MAGNIFICATION`."""

GROUND_PHOTOS = ("gravel", "brick", "grass")
FACADE_PHOTOS = (
    "brick",
    "coffee",
    "chelsea",
    "astronaut",
    "motorcycle",
    "rocket",
    "camera",
    "immunohistochemistry",
    "moon",
    "coins",
    "page",
    "retina",
)


def _photo(rng: np.random.Generator, names) -> SurfaceTexture:
    return SurfaceTexture(
        "photo", photo=names[int(rng.integers(len(names)))], seed=int(rng.integers(2**31))
    )


def _facade_texture(rng: np.random.Generator) -> SurfaceTexture:
    """Mostly photographs; sometimes a bright wall or a fence (stripes)."""
    draw = rng.random()
    if draw < 0.15:
        return draw_texture(rng, "bright")
    if draw < 0.3:
        return draw_texture(rng, "stripes")
    return _photo(rng, FACADE_PHOTOS)


def _square(name, texture, center, half, orientation, texel) -> Part:
    solid = Solid(
        "square",
        texture.label(),
        tuple(float(c) for c in center),
        tuple(float(h) for h in half),
        orientation=tuple(float(a) for a in orientation),
        name=name,
    )
    return Part(solid, texture, texel)


def _layout(rng: np.random.Generator, fx: float) -> tuple[list[Part], dict]:
    """Ground, facades and the backdrop at the end of the street."""
    texel = REFERENCE_DEPTH * PHOTO_MAGNIFICATION / fx
    height = float(rng.uniform(1.2, 1.7))
    left, right = float(rng.uniform(3.0, 7.0)), float(rng.uniform(3.0, 7.0))
    end = float(rng.uniform(30.0, 45.0))
    start = -4.0
    length = end - start
    mid_z = (start + end) / 2
    ground = _square(
        "ground",
        _photo(rng, GROUND_PHOTOS),
        ((right - left) / 2, height, mid_z),
        ((left + right) / 2 + 0.5, length / 2),
        (-np.pi / 2, 0.0, 0.0),
        texel,
    )
    parts = [ground]
    for side, offset in (("left", -left), ("right", right)):
        top = float(rng.uniform(4.0, 12.0))
        parts.append(
            _square(
                f"{side} facade",
                _facade_texture(rng),
                (offset, height - top / 2, mid_z),
                (length / 2, top / 2),
                (0.0, np.pi / 2, 0.0),
                texel,
            )
        )
    half_w, half_h = 1.0 * end + 10.0, 0.8 * end + 10.0
    parts.append(
        _square(
            "end of street",
            _photo(rng, FACADE_PHOTOS),
            (0.0, 0.0, end),
            (half_w, half_h),
            (0.0, 0.0, 0.0),
            texel * end / REFERENCE_DEPTH / 2,
        )
    )
    return parts, {"height": height, "left": left, "right": right, "end": end}


def _cars(rng: np.random.Generator, street: dict, fx: float) -> list[Part]:
    """Parked cars along both kerbs; the last one may drive."""
    texel = REFERENCE_DEPTH * PHOTO_MAGNIFICATION / fx
    cars = []
    for i in range(int(rng.integers(1, 5))):
        half = np.array([0.9, 0.75, 2.2]) * rng.uniform(0.9, 1.1, 3)
        side = -1.0 if rng.random() < 0.5 else 1.0
        kerb = street["left"] if side < 0 else street["right"]
        x = side * (kerb - half[0] - rng.uniform(0.1, 0.5))
        z = float(rng.uniform(5.0, 0.7 * street["end"]))
        center = (float(x), street["height"] - half[1], z)
        texture = draw_texture(rng, "bright") if rng.random() < 0.3 else _photo(rng, FACADE_PHOTOS)
        velocity = (0.0, 0.0, 0.0)
        if i > 0 and rng.random() < 0.3:  # this one drives, along the street
            velocity = (0.0, 0.0, float(rng.uniform(-0.8, 0.8)))
        solid = Solid(
            "box",
            texture.label(),
            center,
            tuple(float(h) for h in half),
            velocity=velocity,
            orientation=(0.0, float(rng.uniform(-0.08, 0.08)), 0.0),
            name=f"car {i}",
        )
        cars.append(Part(solid, texture, texel))
    return cars


def _draft_street(seed: int, size, rng: np.random.Generator, common: dict) -> FamilySpec:
    fx = 0.8 * size[0]
    parts, street = _layout(rng, fx)
    parts += _cars(rng, street, fx)
    # The camera drives forward; a little yaw, roll, pitch and sideways drift.
    twist = np.array(
        [
            0.02 * rng.uniform(-1, 1),
            0.005 * rng.uniform(-1, 1),
            1.0,
            0.003 * rng.uniform(-1, 1),
            0.01 * rng.uniform(-1, 1),
            0.008 * rng.uniform(-1, 1),
        ]
    )
    cars = len(parts) - 4
    return FamilySpec(
        seed=seed,
        kind="street",
        split=split(seed),
        size=size,
        camera_twist=tuple(float(c) for c in twist),
        backdrop=None,
        parts=tuple(parts),
        blur_px=math.nan,
        num_samples=0,
        description=(
            f"street {street['left']:.1f} + {street['right']:.1f} m wide, camera "
            f"{street['height']:.2f} m high, {cars} cars; "
            + ", ".join(p.texture.label() for p in parts)
        ),
        **common,
    )


def street_scene(seed: int, *, size: tuple[int, int] = (320, 240)) -> FamilySpec:
    """The street scene of ``seed`` at ``size = (width, height)`` (module docstring)."""
    return draw_spec(seed, size, "street", _draft_street)
