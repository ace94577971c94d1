"""Coloured point clouds of deblurred frames, PLY files, and rendering from a new viewpoint.

Conventions
-----------
Points are in left-camera coordinates of the frame's centre instant (x right,
y down, z forward, scene units); every pixel of the frame's view with a finite
depth in front of the camera gives one point, from the scene flow's plane of its
segment (:meth:`~stereodeblur.sceneflow.model.SceneFlow.points`). Colours are
8-bit and encoded as the scene stores its frames (``linear`` or ``srgb``), so a
point's colour equals the pixel of the written frame. A cloud holds the
deblurred colours (``red``, ``green``, ``blue``) and, when given, the blurred
ones (``blurred_red``, ...), so both can be rendered side by side.

A viewpoint is a camera centre ``translation`` and an orientation ``rotation``
(rotation vector, radians; the columns of ``so3_exp(rotation)`` are the new
camera's axes in left-camera coordinates), so a point ``P`` is at
``so3_exp(rotation)^T (P - translation)`` in the new camera. Rendering projects
every point with the cloud's ``K`` to the nearest pixel, keeps the nearest point
per pixel (z-buffer), and fills one-pixel gaps (twice, so up to 2x magnification
leaves no holes) from the farther neighbour.

PLY files are binary little-endian with the intrinsics and image size as
comments (``comment K fx s cx 0 fy cy 0 0 1``, ``comment size W H``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .geometry.rigid import so3_exp
from .io.formats import linear_to_srgb
from .io.outputs import atomic_write

COLOR_SETS = ("deblurred", "blurred", "both")
# Largest rendered view: 2**26 pixels (8192 x 8192), 800 MB as float RGB.
MAX_PIXELS = 2**26
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_COLOR_NAMES = {"deblurred": ("red", "green", "blue")}
_COLOR_NAMES["blurred"] = tuple(f"blurred_{c}" for c in _COLOR_NAMES["deblurred"])


@dataclass(frozen=True)
class PointCloud:
    """Points with deblurred (and optionally blurred) colours.

    Attributes
    ----------
    points : ndarray, shape (N, 3), float32
    colors : ndarray, shape (N, 3), uint8
    blurred_colors : ndarray, shape (N, 3), uint8, or None
    K : ndarray, shape (3, 3), or None
        Intrinsics of the view the cloud was made from (the default for rendering).
    size : tuple of int or None
        ``(width, height)`` of that view.
    """

    points: np.ndarray
    colors: np.ndarray
    blurred_colors: np.ndarray | None = None
    K: np.ndarray | None = None
    size: tuple[int, int] | None = None

    def __post_init__(self):
        points = np.asarray(self.points, dtype=np.float32).reshape(-1, 3)
        if not np.all(np.isfinite(points)):
            raise InputError("point cloud points must be finite")
        object.__setattr__(self, "points", points)
        for name in ("colors", "blurred_colors"):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value)
            if value.shape != points.shape or value.dtype != np.uint8:
                raise InputError(
                    f"{name} must be uint8 of shape {points.shape}, got {value.dtype} {value.shape}"
                )
        if self.K is not None:
            object.__setattr__(self, "K", _check_intrinsics(self.K))
        if self.size is not None:
            object.__setattr__(self, "size", _check_size(self.size))

    def __len__(self) -> int:
        return self.points.shape[0]


def _check_intrinsics(K) -> np.ndarray:
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise InputError(f"K must be a finite 3 x 3 matrix, got {K.tolist()!r}")
    if not (K[0, 0] > 0 and K[1, 1] > 0) or not np.array_equal(K[2], [0.0, 0.0, 1.0]):
        raise InputError(f"K must have focal lengths > 0 and last row 0 0 1, got {K.tolist()!r}")
    return K


def _check_size(size) -> tuple[int, int]:
    width, height = (int(v) for v in size)
    if width < 1 or height < 1 or width * height > MAX_PIXELS:
        raise InputError(
            f"size must be at least 1 x 1 and at most {MAX_PIXELS} pixels, got {width} x {height}"
        )
    return width, height


def _to_u8(image: np.ndarray, color: str) -> np.ndarray:
    image = np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0)
    if color == "srgb":
        image = linear_to_srgb(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    return np.rint(image * 255).astype(np.uint8)


def frame_point_cloud(
    sceneflow, image: np.ndarray, *, blurred: np.ndarray | None = None, color: str = "linear"
) -> PointCloud:
    """The point cloud of a frame: scene-flow geometry with the frame's colours.

    Parameters
    ----------
    sceneflow : SceneFlow
        Its reference view is the frame's view.
    image, blurred : ndarray, shape (H, W) or (H, W, 3)
        Deblurred and blurred frame, linear float in [0, 1].
    color : {'linear', 'srgb'}
        Encoding of the stored colours (that of the scene).
    """
    points = sceneflow.points()
    if points.shape[:2] != np.shape(image)[:2]:
        raise InputError(f"image has shape {np.shape(image)}, the scene flow {points.shape[:2]}")
    keep = np.all(np.isfinite(points), axis=-1)
    depth = (points - sceneflow.camera.center(sceneflow.view))[..., 2]
    keep &= depth > 0
    H, W = points.shape[:2]
    K = sceneflow.camera.K
    return PointCloud(
        points[keep],
        _to_u8(image, color)[keep],
        None if blurred is None else _to_u8(blurred, color)[keep],
        K=K,
        size=(W, H),
    )


# --------------------------------------------------------------------------- PLY


def write_ply(path: str | os.PathLike, cloud: PointCloud, *, comments=()) -> Path:
    """Write ``cloud`` as a binary little-endian PLY (atomically)."""
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    fields += [(name, "u1") for name in _COLOR_NAMES["deblurred"]]
    if cloud.blurred_colors is not None:
        fields += [(name, "u1") for name in _COLOR_NAMES["blurred"]]
    vertices = np.empty(len(cloud), dtype=fields)
    for axis, name in enumerate("xyz"):
        vertices[name] = cloud.points[:, axis]
    for channel, name in enumerate(_COLOR_NAMES["deblurred"]):
        vertices[name] = cloud.colors[:, channel]
    if cloud.blurred_colors is not None:
        for channel, name in enumerate(_COLOR_NAMES["blurred"]):
            vertices[name] = cloud.blurred_colors[:, channel]
    lines = ["ply", "format binary_little_endian 1.0", "comment made by stereodeblur"]
    if cloud.K is not None:
        lines.append("comment K " + " ".join(f"{v:.17g}" for v in cloud.K.ravel()))
    if cloud.size is not None:
        lines.append(f"comment size {cloud.size[0]} {cloud.size[1]}")
    lines += [f"comment {' '.join(str(c).split())}" for c in comments]
    lines.append(f"element vertex {len(cloud)}")
    for name, kind in fields:
        lines.append(f"property {'float' if kind == '<f4' else 'uchar'} {name}")
    lines.append("end_header")
    header = ("\n".join(lines) + "\n").encode("ascii")
    return atomic_write(path, header + vertices.tobytes())


def _parse_header(data: bytes, path: Path):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"not a PLY file: {path} (expected 'ply' ... 'end_header')")
    newline = data.find(b"\n", end)
    if newline < 0:
        raise InputError(f"truncated PLY file {path}: nothing after end_header")
    lines = data[:end].decode("ascii", "replace").splitlines()[1:]
    fmt, elements, comments = None, [], []
    for line in lines:
        words = line.split()
        if not words:
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "comment":
            comments.append(words[1:])
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            if words[1] == "list":
                elements[-1][2].append((words[-1], None))
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
            else:
                raise InputError(f"{path}: unsupported PLY property line {line.strip()!r}")
        elif words[0] != "obj_info":
            raise InputError(f"{path}: unexpected PLY header line {line.strip()!r}")
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise InputError(f"{path}: unsupported PLY format {fmt!r}")
    if not elements or elements[0][0] != "vertex":
        raise InputError(f"{path}: the first PLY element must be 'vertex'")
    name, count, props = elements[0]
    if any(kind is None for _, kind in props):
        raise InputError(f"{path}: list properties on vertices are not supported")
    names = [n for n, _ in props]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: a vertex property is declared twice ({', '.join(names)})")
    return fmt, count, props, comments, newline + 1


def read_ply(path: str | os.PathLike) -> PointCloud:
    """Read the vertices of a PLY file (ours or any with float x, y, z and colours)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"point cloud not found: {path}")
    data = path.read_bytes()
    fmt, count, props, comments, start = _parse_header(data, path)
    names = [n for n, _ in props]
    for axis in "xyz":
        if axis not in names:
            raise InputError(f"{path}: vertices have no {axis!r} property")
    if fmt == "ascii":
        rows = data[start:].decode("ascii", "replace").split("\n")
        rows = [r for r in rows if r.strip()][:count]
        try:
            table = np.array([[float(v) for v in r.split()[: len(props)]] for r in rows])
        except ValueError:
            raise InputError(f"{path}: vertex values are not numbers") from None
        if table.shape != (count, len(props)):
            raise InputError(f"{path}: expected {count} vertices of {len(props)} values")
        columns = {n: table[:, k] for k, n in enumerate(names)}
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        dtype = np.dtype([(n, order + k.lstrip("<>")) for n, k in props])
        if len(data) - start < count * dtype.itemsize:
            raise InputError(
                f"truncated PLY file {path}: {count} vertices need {count * dtype.itemsize} "
                f"bytes, found {len(data) - start}"
            )
        table = np.frombuffer(data, dtype=dtype, count=count, offset=start)
        columns = {n: table[n] for n in names}
    points = np.stack([columns[a] for a in "xyz"], axis=1).astype(np.float32)
    if not np.all(np.isfinite(points)):
        raise InputError(f"{path}: vertex coordinates must be finite")

    def colors(kind):
        if not all(n in columns for n in _COLOR_NAMES[kind]):
            return None
        return np.stack([columns[n] for n in _COLOR_NAMES[kind]], axis=1).astype(np.uint8)

    deblurred = colors("deblurred")
    if deblurred is None:
        deblurred = np.full(points.shape, 255, np.uint8)
    try:
        K, size = None, None
        for words in comments:
            if words[:1] == ["K"] and len(words) == 10:
                K = np.array([float(v) for v in words[1:]]).reshape(3, 3)
            elif words[:1] == ["size"] and len(words) == 3:
                size = (int(words[1]), int(words[2]))
        return PointCloud(points, deblurred, colors("blurred"), K=K, size=size)
    except ValueError as err:  # InputError too: name the file
        raise InputError(f"{path}: {err}") from None


# --------------------------------------------------------------------------- rendering


@dataclass(frozen=True)
class RenderedView:
    """A point cloud rendered from a viewpoint.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float32
        Colours in [0, 1], encoded as the cloud's; black where nothing is seen.
        With ``colors='both'`` deblurred on the left, blurred on the right (W doubled).
    mask : ndarray of bool, shape (H, W)
        Pixels that show a point.
    depth : ndarray, shape (H, W), float32
        Depth along the new camera's z, inf where nothing is seen.
    """

    image: np.ndarray
    mask: np.ndarray
    depth: np.ndarray


def render_view(
    cloud: PointCloud,
    *,
    rotation=(0.0, 0.0, 0.0),
    translation=(0.0, 0.0, 0.0),
    K: np.ndarray | None = None,
    size: tuple[int, int] | None = None,
    colors: str = "deblurred",
) -> RenderedView:
    """Render ``cloud`` from the camera at ``translation`` turned by ``rotation``.

    Parameters
    ----------
    cloud : PointCloud
    rotation : 3-vector
        Rotation vector of the new camera (radians); see the module docstring.
    translation : 3-vector
        New camera centre in the cloud's coordinates.
    K : ndarray, shape (3, 3), optional
        Intrinsics; default the cloud's.
    size : tuple of int, optional
        ``(width, height)``; default the cloud's.
    colors : {'deblurred', 'blurred', 'both'}
        Which colours; ``'both'`` puts deblurred and blurred side by side.
    """
    if colors not in COLOR_SETS:
        raise InputError(f"colors must be one of {', '.join(COLOR_SETS)}, got {colors!r}")
    if colors != "deblurred" and cloud.blurred_colors is None:
        raise InputError("the point cloud has no blurred colours (blurred_red, ...)")
    K = cloud.K if K is None else _check_intrinsics(K)
    size = cloud.size if size is None else _check_size(size)
    if K is None or size is None:
        raise InputError("the point cloud states no intrinsics or image size: give K and size")
    width, height = size
    R = so3_exp(np.asarray(rotation, dtype=np.float64).reshape(3))
    camera = (cloud.points.astype(np.float64) - np.asarray(translation, dtype=np.float64)) @ R
    z = camera[:, 2]
    front = z > 1e-9
    zf = np.where(front, z, 1.0)
    x = (K[0, 0] * camera[:, 0] + K[0, 1] * camera[:, 1]) / zf + K[0, 2]
    y = K[1, 1] * camera[:, 1] / zf + K[1, 2]
    xi, yi = np.rint(x), np.rint(y)
    inside = front & (xi >= 0) & (xi < width) & (yi >= 0) & (yi < height)
    pixel = (yi[inside] * width + xi[inside]).astype(np.int64)
    order = np.lexsort((z[inside], pixel))  # by pixel, nearest first
    pixel, first = np.unique(pixel[order], return_index=True)
    chosen = np.flatnonzero(inside)[order[first]]
    depth = np.full(height * width, np.inf)
    depth[pixel] = z[chosen]
    index = np.full(height * width, -1, np.int64)
    index[pixel] = chosen
    depth, index = depth.reshape(height, width), index.reshape(height, width)
    for _ in range(2):  # the second pass fills what lies between gaps (up to 2x magnification)
        _fill_gaps(depth, index)
    mask = index >= 0
    sets = ["deblurred", "blurred"] if colors == "both" else [colors]
    images = []
    for name in sets:
        table = cloud.colors if name == "deblurred" else cloud.blurred_colors
        image = np.zeros((height, width, 3), np.float32)
        image[mask] = table[index[mask]].astype(np.float32) / 255.0
        images.append(image)
    return RenderedView(np.concatenate(images, axis=1), mask, depth.astype(np.float32))


def _fill_gaps(depth: np.ndarray, index: np.ndarray) -> None:
    """Fill empty pixels with a seen pixel on both sides (row or column) from the farther one."""
    empty = index < 0
    best_depth = np.full(depth.shape, -np.inf)
    best_index = np.full(index.shape, -1)
    for axis in (0, 1):
        before = np.roll(index, 1, axis=axis)
        after = np.roll(index, -1, axis=axis)
        d_before = np.roll(depth, 1, axis=axis)
        d_after = np.roll(depth, -1, axis=axis)
        edge = np.zeros(index.shape, bool)
        if axis == 0:
            edge[0, :] = edge[-1, :] = True
        else:
            edge[:, 0] = edge[:, -1] = True
        gap = empty & ~edge & (before >= 0) & (after >= 0)
        for d, i in ((d_before, before), (d_after, after)):
            better = gap & (d > best_depth)
            best_depth[better] = d[better]
            best_index[better] = i[better]
    filled = best_index >= 0
    index[filled] = best_index[filled]
    depth[filled] = best_depth[filled]


def point_cloud_path(
    root: str | os.PathLike, view: str, index: int, *, name: str | None = None
) -> Path:
    """Where a clip run with point clouds puts the cloud of frame ``index`` of ``view``
    (``NNNNNN.ply``, or ``name``.ply: the source's own frame name)."""
    return Path(root) / "pointcloud" / view / f"{name or f'{int(index):06d}'}.ply"
