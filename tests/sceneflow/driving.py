"""A driving scene for the scene-flow tests: a road and roadside under forward motion.

The camera drives forward along z over a flat, weakly textured road (asphalt grain with
hard tree shadows), between a hedge on the left and a wall on the right, under a far,
nearly flat sky. The scene is static: one rigid motion, the camera's, explains every
pixel. The flow at the bottom of the image is large (``bottom_flow`` pixels per frame),
the frames are motion blurred (``duty_cycle`` of the frame interval), and frame t + 1 is
brighter than frame t by ``gain`` (auto exposure). Rendered by ray casting
(:mod:`stereodeblur.synth.render`), with its exact flow and disparity.

Scene units are metres; the camera is ``CAMERA_HEIGHT`` above the road (y down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from stereodeblur.geometry import Exposure, StereoCamera
from stereodeblur.io.srgb import linear_to_srgb, srgb_to_linear
from stereodeblur.synth.render import PlanarObject, SceneSetup, render_scene

CAMERA_HEIGHT = 1.5
BASELINE = 0.54  # KITTI's
FRAME_RATE = 10.0


@dataclass(frozen=True)
class DrivingPair:
    """Four frames (left t, right t, left t + 1, right t + 1), grey float32 in [0, 1], with
    the camera, exposure, the true left-view flow t -> t + 1 and where the road is seen."""

    frames: tuple[np.ndarray, ...]
    camera: StereoCamera
    exposure: Exposure
    flow: np.ndarray
    disparity: np.ndarray
    road: np.ndarray


def _noise(rng, shape, scales):
    out = np.zeros(shape)
    for sigma, amplitude in scales:
        layer = ndimage.gaussian_filter(rng.standard_normal(shape), sigma, mode="wrap")
        out += amplitude * layer / layer.std()
    return out


def road_texture(rng, size=1024, *, contrast=0.03, shadow=0.45, num_shadows=60):
    """Asphalt: fine grain of std ``contrast`` around 0.35, times hard-edged shadows
    (blobs at ``shadow`` of the light) and two lane markings."""
    grain = 0.35 + contrast * _noise(rng, (size, size), ((0.7, 1.0), (2.0, 0.6), (8.0, 0.4)))
    light = np.ones((size, size))
    yy, xx = np.mgrid[0:size, 0:size]
    for _ in range(num_shadows):
        cx, cy = rng.uniform(0, size, 2)
        rx, ry = rng.uniform(8, 60, 2)
        light[((xx - cx) / rx) ** 2 + ((yy - cy) / ry) ** 2 < 1] = shadow
    # Lane markings along z (texture rows run along z): dashed lines at x = -1.8 and 1.8 m.
    image = grain * light
    for column in (size // 2 - 36, size // 2 + 36):
        dashes = (yy // 40) % 2 == 0
        image[(np.abs(xx - column) < 2) & dashes] = 0.8 * light[(np.abs(xx - column) < 2) & dashes]
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def roadside_texture(rng, shape=(512, 512), *, mean=0.3, contrast=0.12):
    """Hedge or wall: texture at several scales."""
    image = mean + contrast * _noise(rng, shape, ((1.0, 1.0), (3.0, 1.0), (10.0, 0.7)))
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def _grey(image):
    return np.repeat(image[..., None], 3, axis=2)


def driving_setup(
    size=(320, 240), *, bottom_flow=60.0, duty_cycle=0.3, road_contrast=0.03, seed=0, texel=0.05
) -> SceneSetup:
    """The road scene; the camera's forward speed gives ``bottom_flow`` px per frame at
    the centre of the bottom image row."""
    width, height = size
    f = 0.8 * width
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    camera = StereoCamera(K, BASELINE)
    rng = np.random.default_rng(seed)
    # Road point seen at the bottom row now, and where it must be seen at t + 1.
    rows = (height - 1) / 2
    z_now = f * CAMERA_HEIGHT / rows
    z_next = f * CAMERA_HEIGHT / (rows + bottom_flow)
    speed = z_now - z_next
    twist = np.array([0.0, 0.0, -speed, 0.0, 0.0, 0.0])  # the world moves towards the camera
    road = road_texture(rng, contrast=road_contrast)
    objects = (
        PlanarObject(
            normal=[0.0, 1.0 / CAMERA_HEIGHT, 0.0],
            twist=twist,
            texture=_grey(road),
            origin=[0.0, CAMERA_HEIGHT, 0.5 * road.shape[0] * texel],
            axes=[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            texel_size=texel,
            name="road",
        ),
        # Roadside: a 3 m hedge on the left, a 2 m wall on the right, 51 m long.
        PlanarObject(
            normal=[-1.0 / 4.0, 0.0, 0.0],
            twist=twist,
            texture=_grey(roadside_texture(rng, (30, 512), mean=0.25)),
            origin=[-4.0, CAMERA_HEIGHT - 1.5, 25.0],
            axes=[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
            texel_size=2 * texel,
            name="hedge",
            bounded=True,
        ),
        PlanarObject(
            normal=[1.0 / 6.0, 0.0, 0.0],
            twist=twist,
            texture=_grey(roadside_texture(rng, (20, 512), mean=0.5, contrast=0.08)),
            origin=[6.0, CAMERA_HEIGHT - 1.0, 25.0],
            axes=[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
            texel_size=2 * texel,
            name="wall",
            bounded=True,
        ),
        PlanarObject(
            normal=[0.0, 0.0, 1.0 / 500.0],
            twist=twist,
            texture=_grey(roadside_texture(rng, mean=0.85, contrast=0.02)),
            origin=[0.0, 0.0, 500.0],
            axes=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            texel_size=2.0,
            name="sky",
        ),
    )
    exposure = Exposure(FRAME_RATE, duty_cycle / FRAME_RATE)
    return SceneSetup("driving", camera, exposure, size, 2, objects)


def driving_pair(
    size=(320, 240),
    *,
    bottom_flow=60.0,
    duty_cycle=0.3,
    gain=1.2,
    road_contrast=0.03,
    seed=0,
    num_samples=16,
) -> DrivingPair:
    """Render the scene and return the blurred grey frames, frame t + 1 times ``gain``."""
    setup = driving_setup(
        size, bottom_flow=bottom_flow, duty_cycle=duty_cycle, road_contrast=road_contrast, seed=seed
    )
    scene = render_scene(setup, num_samples=num_samples)
    grey = {v: [f.mean(axis=2) for f in scene.frames[v]] for v in ("left", "right")}
    frames = (
        grey["left"][0],
        grey["right"][0],
        np.clip(gain * grey["left"][1], 0.0, 1.0),
        np.clip(gain * grey["right"][1], 0.0, 1.0),
    )
    return DrivingPair(
        frames=tuple(f.astype(np.float32) for f in frames),
        camera=setup.camera,
        exposure=setup.exposure,
        flow=scene.flow[0],
        disparity=scene.disparity["left"][0],
        road=scene.object_ids["left"][0] == 0,
    )


def _srgb_8bit(linear: np.ndarray) -> np.ndarray:
    """Linear light through a camera's 8-bit sRGB encoding and back, as a PNG is read."""
    return srgb_to_linear(np.round(linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0) / 255.0)


@dataclass(frozen=True)
class ShadedHedge:
    """Four sharp camera frames (left t, right t, left t + 1, right t + 1; grey float32,
    linear), the camera, the true left-view disparity at t and where the hedge and the bush
    are seen."""

    frames: tuple[np.ndarray, ...]
    camera: StereoCamera
    disparity: np.ndarray
    hedge: np.ndarray
    bush: np.ndarray


def shaded_hedge(size=(320, 240), *, shade=0.003, shot=1e-3, seed=0) -> ShadedHedge:
    """A hedge in deep shade (mean ``shade`` of full scale) 7 m away behind a sunlit bush 5 m
    away, over a road under a bright sky, the camera driving forward 0.4 m per frame; shot
    noise of variance ``shot`` times the brightness, then 8-bit sRGB (KITTI 2015's 000007
    has such a hedge)."""
    width, height = size
    f = 0.8 * width
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    camera = StereoCamera(K, BASELINE)
    rng = np.random.default_rng(seed)
    twist = np.array([0.0, 0.0, -0.4, 0.0, 0.0, 0.0])
    road = road_texture(rng)
    bush = roadside_texture(rng, (40, 300), mean=0.45)
    hedge = shade * roadside_texture(rng, (120, 300), mean=0.5, contrast=0.1) / 0.5

    def wall(name, texture, centre, z):
        return PlanarObject(
            normal=[0.0, 0.0, 1.0 / z],
            twist=twist,
            texture=_grey(texture),
            origin=[centre[0], centre[1], z],
            axes=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            texel_size=0.02 if z < 100 else 2.0,
            name=name,
            bounded=z < 100,
        )

    objects = (
        PlanarObject(
            normal=[0.0, 1.0 / CAMERA_HEIGHT, 0.0],
            twist=twist,
            texture=_grey(road),
            origin=[0.0, CAMERA_HEIGHT, 0.5 * road.shape[0] * 0.05],
            axes=[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            texel_size=0.05,
            name="road",
        ),
        wall("bush", bush, (1.0, CAMERA_HEIGHT - 0.4), 5.0),
        wall("hedge", hedge, (1.0, CAMERA_HEIGHT - 1.2), 7.0),
        wall("sky", roadside_texture(rng, mean=0.85, contrast=0.02), (0.0, 0.0), 500.0),
    )
    setup = SceneSetup("shaded_hedge", camera, Exposure(FRAME_RATE, 0.0), size, 2, objects)
    scene = render_scene(setup, num_samples=1)
    noise = np.random.default_rng(seed + 1)
    frames = []
    for index in (0, 1):
        for view in ("left", "right"):
            grey = scene.frames[view][index].mean(axis=2)
            grey = grey + np.sqrt(shot * grey) * noise.standard_normal(grey.shape)
            frames.append(_srgb_8bit(grey).astype(np.float32))
    return ShadedHedge(
        frames=tuple(frames),
        camera=camera,
        disparity=scene.disparity["left"][0],
        hedge=scene.object_ids["left"][0] == 2,
        bush=scene.object_ids["left"][0] == 1,
    )
