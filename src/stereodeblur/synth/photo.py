"""Semi-real clips: a photographed stereo pair moved along its depth and motion, and blurred.

A stereo pair photographed at one instant, a dense disparity for each view and a rigid
motion per pixel (a label map into a list of twists, as the scene flow's) give the scene at
every instant ``s`` (in frames, 0 at the photograph): each pixel's 3D point moves by
``exp(s * twist)`` and is projected into its view. :func:`render_instant` splats the points
with a depth test (the nearest surface wins; surfaces within ``DEPTH_TOLERANCE`` of it are one
surface), and fills what no point reaches (disocclusions, content entering the view) from the
farther surface beside it; :func:`render_clip` averages the instants of each frame's
exposure, frame ``middle`` centred on the photograph, whose sharp images are then the
photographs themselves, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ..geometry.camera import Exposure, StereoCamera
from ..geometry.rigid import se3_exp

__all__ = [
    "PhotoScene",
    "SemiRealClip",
    "longest_blur",
    "moved_pixels",
    "points_of_view",
    "render_clip",
    "render_instant",
    "write_clip",
]

VIEWS = ("left", "right")
DEPTH_TOLERANCE = 0.03  # relative depth within which splats count as one surface
MIN_WEIGHT = 0.2  # splat weight below which a pixel is a hole (filled)
MIXED_DEPTH = 0.1  # relative change of the nearest surface over the exposure: mixed pixel


@dataclass(frozen=True)
class PhotoScene:
    """A photographed stereo pair with its depth and motion.

    Attributes
    ----------
    images : dict of str to ndarray, (H, W) or (H, W, C) float32
        Linear values of each view at the instant photographed.
    disparity : dict of str to ndarray, (H, W)
        Dense disparity of each view (> 0) in its own pixels.
    labels : dict of str to ndarray, (H, W) int
        Each pixel's motion, an index into ``twists``.
    twists : ndarray, (K, 6)
        Rigid motions per frame (``(v, omega)``, left-camera coordinates) of the points.
    camera : StereoCamera
    """

    images: dict
    disparity: dict
    labels: dict
    twists: np.ndarray
    camera: StereoCamera

    @property
    def shape(self) -> tuple[int, int]:
        return self.disparity["left"].shape


@dataclass(frozen=True)
class SemiRealClip:
    """Blurred frames of both views and their ground truth.

    ``frames[view][i]`` is frame ``i``; ``sharp[view][i]`` the instant at its centre (of frame
    ``middle``: the photograph); ``disparity[view][i]`` its disparity; ``flow[i]`` the left
    view's flow from the centre of frame ``i`` to that of ``i + 1``; ``mixed[view][i]`` True
    where the exposure of frame ``i`` mixes surfaces; ``longest_blur`` (px) of frame
    ``middle``'s left view, over the pixels not within ``border`` of the image's edge.
    """

    frames: dict
    sharp: dict
    disparity: dict
    flow: np.ndarray
    mixed: dict
    exposure: Exposure
    middle: int
    num_samples: int
    longest_blur: float


def points_of_view(scene: PhotoScene, view: str) -> np.ndarray:
    """The (H, W, 3) points seen by ``view``, in left-camera coordinates."""
    camera = scene.camera
    d = np.asarray(scene.disparity[view], dtype=np.float64)
    y, x = np.mgrid[0 : d.shape[0], 0 : d.shape[1]].astype(np.float64)
    return camera.backproject(x, y, camera.disparity_to_depth(d)) + camera.center(view)


def moved_pixels(scene: PhotoScene, view: str, points: np.ndarray, s: float):
    """Pixel positions ``(x, y)`` and depth in ``view`` of ``points`` moved to instant ``s``."""
    motions = se3_exp(float(s) * np.asarray(scene.twists, dtype=np.float64))
    labels = scene.labels[view]
    moved = np.empty_like(points)
    for k in np.unique(labels):
        mine = labels == k
        moved[mine] = points[mine] @ motions[k, :3, :3].T + motions[k, :3, 3]
    xy = scene.camera.project(moved, view)
    return xy[..., 0], xy[..., 1], moved[..., 2]


@numba.njit(cache=True, nogil=True)
def _splat(xs, ys, zs, values, height, width, tolerance):
    n, channels = values.shape
    zbuf = np.full((height, width), np.inf)
    for i in range(n):
        z = zs[i]
        if not z > 0:
            continue
        x0, y0 = int(np.floor(xs[i])), int(np.floor(ys[i]))
        for dy in range(2):
            for dx in range(2):
                xx, yy = x0 + dx, y0 + dy
                if 0 <= xx < width and 0 <= yy < height and z < zbuf[yy, xx]:
                    zbuf[yy, xx] = z
    acc = np.zeros((height, width, channels))
    weight = np.zeros((height, width))
    for i in range(n):
        z = zs[i]
        if not z > 0:
            continue
        x0, y0 = int(np.floor(xs[i])), int(np.floor(ys[i]))
        fx, fy = xs[i] - x0, ys[i] - y0
        for dy in range(2):
            for dx in range(2):
                xx, yy = x0 + dx, y0 + dy
                if not (0 <= xx < width and 0 <= yy < height):
                    continue
                if z > zbuf[yy, xx] * (1.0 + tolerance):
                    continue
                w = (fx if dx else 1.0 - fx) * (fy if dy else 1.0 - fy)
                weight[yy, xx] += w
                for c in range(channels):
                    acc[yy, xx, c] += w * values[i, c]
    return acc, weight, zbuf


@numba.njit(cache=True, nogil=True)
def _fill_holes(image, depth, holes):
    """``image`` with each hole taking the farther of the nearest surfaces left and right of
    it in its row (the background a disocclusion uncovers); a row without any, the nearest
    filled row's pixel in its column."""
    H, W, C = image.shape
    out = image.copy()
    filled = ~holes
    for y in range(H):
        left = -1
        for x in range(W):
            if not holes[y, x]:
                left = x
                continue
            right = x
            while right < W and holes[y, right]:
                right += 1
            src = -1
            if left >= 0 and right < W:
                src = left if depth[y, left] >= depth[y, right] else right
            elif left >= 0:
                src = left
            elif right < W:
                src = right
            if src >= 0:
                out[y, x] = image[y, src]
                filled[y, x] = True
    for x in range(W):
        for y in range(H):
            if filled[y, x]:
                continue
            for step in range(1, H):
                if y - step >= 0 and not holes[y - step, x]:
                    out[y, x] = image[y - step, x]
                    break
                if y + step < H and not holes[y + step, x]:
                    out[y, x] = image[y + step, x]
                    break
    return out


def render_instant(scene: PhotoScene, view: str, s: float, points=None, *, truth=False):
    """``view`` at instant ``s``: the image (H, W, C) float32 and the nearest depth (H, W),
    infinite in holes (which the image fills from the background beside them). With
    ``truth``, also the disparity (H, W) and, of the left view, the flow (H, W, 2) from ``s``
    to ``s + 1`` of the points seen, holes filled alike."""
    image = np.asarray(scene.images[view], dtype=np.float64)
    channels = 1 if image.ndim == 2 else image.shape[2]
    values = [image.reshape(-1, channels)]
    points = points_of_view(scene, view) if points is None else points
    x, y, z = moved_pixels(scene, view, points, s)
    if truth:
        values.append(scene.camera.depth_to_disparity(z).reshape(-1, 1))
        if view == "left":
            x1, y1, _ = moved_pixels(scene, view, points, s + 1.0)
            values.append(np.stack([x1 - x, y1 - y], axis=-1).reshape(-1, 2))
    H, W = scene.shape
    acc, weight, zbuf = _splat(
        x.ravel(), y.ravel(), z.ravel(), np.ascontiguousarray(np.concatenate(values, axis=1)),
        H, W, DEPTH_TOLERANCE,
    )  # fmt: skip
    holes = weight < MIN_WEIGHT
    out = acc / np.maximum(weight, 1e-12)[..., None]
    out = _fill_holes(out, np.where(holes, 0.0, zbuf), holes).astype(np.float32)
    zbuf[holes] = np.inf
    if not truth:
        return out, zbuf
    flow = out[..., channels + 1 : channels + 3] if view == "left" else None
    return out[..., :channels], zbuf, out[..., channels], flow


def longest_blur(scene: PhotoScene, duty_cycle: float, *, border: int = 0) -> float:
    """Longest displacement (px) over the exposure of the photographed instant, left view,
    over the pixels not within ``border`` of the image's edge."""
    points = points_of_view(scene, "left")
    a = moved_pixels(scene, "left", points, -duty_cycle / 2)
    b = moved_pixels(scene, "left", points, duty_cycle / 2)
    length = np.hypot(b[0] - a[0], b[1] - a[1])
    if border:
        length = length[border:-border, border:-border]
    return float(length.max())


def render_clip(
    scene: PhotoScene,
    exposure: Exposure,
    *,
    num_frames: int = 3,
    middle: int = 1,
    num_samples: int | None = None,
    border: int = 0,
) -> SemiRealClip:
    """Blurred frames ``0 .. num_frames - 1`` of both views, frame ``middle`` centred on the
    photograph; ``num_samples`` instants per frame (default: twice the longest blur in px,
    at least 8)."""
    longest = longest_blur(scene, exposure.duty_cycle, border=border)
    if num_samples is None:
        num_samples = max(8, int(np.ceil(2 * longest)))
    frames, sharp, disparity, mixed, flow = {}, {}, {}, {}, []
    grey = {v: np.ndim(scene.images[v]) == 2 for v in VIEWS}
    for view in VIEWS:
        points = points_of_view(scene, view)
        frames[view], sharp[view], disparity[view], mixed[view] = [], [], [], []
        for i in range(num_frames):
            total, near, far = 0.0, np.inf, 0.0
            for s in (i - middle) + exposure.sample_fractions(num_samples):
                image, zbuf = render_instant(scene, view, s, points)
                total = total + image.astype(np.float64)
                near, far = np.minimum(near, zbuf), np.maximum(far, zbuf)
            frame = (total / num_samples).astype(np.float32)
            frames[view].append(frame[..., 0] if grey[view] else frame)
            with np.errstate(invalid="ignore"):
                mixed[view].append(~(far <= near * (1.0 + MIXED_DEPTH)))
            image, _, d, f = render_instant(scene, view, i - middle, points, truth=True)
            if i == middle:  # the photograph itself, not its resampled copy
                image, d = scene.images[view], scene.disparity[view]
            sharp[view].append(
                np.asarray(image[..., 0] if grey[view] and image.ndim == 3 else image, np.float32)
            )
            disparity[view].append(np.asarray(d, np.float32))
            if view == "left" and i < num_frames - 1:
                flow.append(f)
    return SemiRealClip(
        frames={v: tuple(f) for v, f in frames.items()},
        sharp={v: tuple(f) for v, f in sharp.items()},
        disparity={v: tuple(f) for v, f in disparity.items()},
        flow=tuple(flow),
        mixed={v: tuple(f) for v, f in mixed.items()},
        exposure=exposure,
        middle=middle,
        num_samples=num_samples,
        longest_blur=longest,
    )


def write_clip(clip: SemiRealClip, camera: StereoCamera, root, *, overwrite: bool = False):
    """Write ``clip`` as a scene folder (``SCENE_FORMAT.md``): 16-bit linear frames and
    every frame's ground truth (both views' sharp images, disparity and mixed masks, the
    left view's flow)."""
    from ..io.scene import CameraInfo, SceneWriter

    writer = SceneWriter(root, CameraInfo(camera, clip.exposure, "linear"), overwrite=overwrite)
    for view in VIEWS:
        for i, frame in enumerate(clip.frames[view]):
            writer.write_frame(view, i, frame, bit_depth=16)
            writer.write_gt_sharp(view, i, clip.sharp[view][i])
            writer.write_gt_disparity(view, i, clip.disparity[view][i])
            writer.write_gt_mixed(view, i, clip.mixed[view][i])
    for i, flow in enumerate(clip.flow):
        writer.write_gt_flow("left", i, flow)
    return root
