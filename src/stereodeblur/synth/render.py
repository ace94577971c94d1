"""Ray casting of rigidly moving textured planes: instantaneous and motion-blurred images.

This renderer is the physical ground truth of the synthetic benchmark. It never
uses the blur operators of :mod:`stereodeblur.blur`: a blurred frame is the mean of
instantaneous images, each obtained by casting one ray per pixel.

Conventions
-----------
Time
    An instant is a fraction ``s`` of the frame interval measured from the centre
    of frame 0's exposure. Frame ``i`` is centred at ``s = i`` and exposed over
    ``[i - tau/2, i + tau/2]``, ``tau = exposure * frame_rate``.
Motion
    Every object has a reference pose at ``s = 0`` and a twist ``xi`` per frame
    interval (see :mod:`stereodeblur.geometry.rigid`). At instant ``s`` a point of
    the object that is at ``P`` in the reference pose is at ``R P + T`` with
    ``[R, T] = exp(s xi)``, in left-camera coordinates (the motion acts about the
    left camera's origin).
Rays
    Pixel centres sit at integer coordinates, ``(0, 0)`` the top-left pixel; sizes
    are ``(width, height)`` and images ``(height, width, 3)``. The ray of pixel
    ``(x, y)`` in a view is ``C + lambda K^-1 (x, y, 1)`` with ``C`` the view's camera
    centre (the right one at ``(baseline, 0, 0)``); since the direction has unit
    ``z``, the hit's depth is ``Z = lambda``. The nearest hit in front of the camera
    wins.
Texture
    An object's texture is fixed to the object: the reference-pose point ``P``
    has texture coordinates ``u = (P - origin) . axes[0] / texel_size + (w - 1) / 2``
    and ``v = (P - origin) . axes[1] / texel_size + (h - 1) / 2`` (texel centres at
    integer ``(u, v) = (col, row)``), looked up with bilinear interpolation. An
    unbounded object is an infinite plane whose texture repeats its edge texels; a
    bounded one is only the rectangle its texture covers.
Solids
    :class:`SphereObject`, :class:`CylinderObject` and :class:`BoxObject` are given
    in a local frame: the reference-pose point is ``P = center + frame @ q`` for local
    coordinates ``q`` (``frame``'s columns are the local axes, a rotation). Their
    rays are intersected exactly (ray-quadric, ray-slab) in local coordinates;
    textures wrap by spherical, cylindrical or per-face planar coordinates (see each
    class). Sphere and cylinder textures should be periodic along ``u`` (first column
    equal to the last, :func:`periodic_texture`) for a seamless wrap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.camera import VIEWS, Exposure, StereoCamera
from ..geometry.plane import move_plane
from ..geometry.rigid import se3_exp


@dataclass(frozen=True)
class PlanarObject:
    """A textured plane moving rigidly with a constant twist.

    Parameters
    ----------
    normal : array_like, shape (3,)
        Scaled normal ``n`` (``P^T n = 1``) of the plane in the reference pose, left
        camera coordinates.
    twist : array_like, shape (6,)
        Motion per frame interval, ``(v, omega)``.
    texture : ndarray, shape (h, w, 3)
        Linear RGB values in [0, 1], stored as float32.
    origin : array_like, shape (3,)
        Point of the plane (reference pose) at the texture's centre.
    axes : array_like, shape (2, 3)
        Orthonormal in-plane directions of increasing texture column and row.
    texel_size : float
        Side of one texel in scene units.
    name : str
        Label for reports and ``objects.json``.
    texture_name : str
        Where the texture came from.
    bounded : bool
        If True the object is only the rectangle covered by its texture; otherwise
        the plane is infinite and the texture's edge texels repeat.
    """

    normal: np.ndarray
    twist: np.ndarray
    texture: np.ndarray
    origin: np.ndarray
    axes: np.ndarray
    texel_size: float
    name: str = "plane"
    texture_name: str = ""
    bounded: bool = False

    def __post_init__(self):
        n = np.asarray(self.normal, dtype=np.float64).reshape(-1)
        xi = np.asarray(self.twist, dtype=np.float64).reshape(-1)
        origin = np.asarray(self.origin, dtype=np.float64).reshape(-1)
        axes = np.asarray(self.axes, dtype=np.float64)
        texture = np.asarray(self.texture, dtype=np.float32)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or not np.any(n):
            raise ValueError(f"normal must be 3 finite numbers, not all 0, got {self.normal!r}")
        if xi.shape != (6,) or not np.all(np.isfinite(xi)):
            raise ValueError(f"twist must be 6 finite numbers, got {self.twist!r}")
        if texture.ndim != 3 or texture.shape[2] != 3 or min(texture.shape[:2]) < 2:
            raise ValueError(
                f"texture must have shape (h, w, 3) with h, w >= 2, got {texture.shape}"
            )
        if origin.shape != (3,) or abs(origin @ n - 1.0) > 1e-9:
            raise ValueError(
                f"origin must be a point of the plane (origin . normal = 1), got {origin}"
            )
        if axes.shape != (2, 3) or not np.allclose(axes @ axes.T, np.eye(2), atol=1e-9):
            raise ValueError(f"axes must be 2 orthonormal 3-vectors, got {axes.tolist()}")
        if np.max(np.abs(axes @ n)) > 1e-9 * np.linalg.norm(n):
            raise ValueError("axes must lie in the plane (perpendicular to the normal)")
        if not np.isfinite(self.texel_size) or self.texel_size <= 0:
            raise ValueError(f"texel_size must be a positive number, got {self.texel_size!r}")
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "twist", xi)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "texture", texture)
        object.__setattr__(self, "texel_size", float(self.texel_size))
        # Channel-first copy for fast bilinear lookups (not a field).
        planes = np.ascontiguousarray(np.moveaxis(texture, -1, 0).reshape(3, -1))
        object.__setattr__(self, "_planes", planes)

    def pose(self, fraction: float) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and translation ``exp(fraction * twist)`` from the reference pose."""
        M = se3_exp(float(fraction) * self.twist)
        return M[:3, :3], M[:3, 3]

    def texture_coordinates(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Texture coordinates ``(u, v)`` of reference-pose points ``(..., 3)`` on the plane."""
        A, b = self._texture_map()
        points = np.asarray(points, dtype=np.float64)
        return points @ A[0] + b[0], points @ A[1] + b[1]

    def _texture_map(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A, b)`` with ``(u, v) = A P + b`` for reference-pose points ``P``."""
        h, w = self.texture.shape[:2]
        A = self.axes / self.texel_size
        b = np.array([(w - 1) / 2, (h - 1) / 2]) - A @ self.origin
        return A, b

    def describe(self) -> dict:
        """The object for ``gt/objects.json``: name, texture, plane and twist."""
        return {
            "name": self.name,
            "normal": [float(c) for c in self.normal],
            "twist": [float(c) for c in self.twist],
            "texture": self.texture_name,
        }


def periodic_texture(texture: np.ndarray) -> np.ndarray:
    """``texture`` followed by its mirror image and its first column again, along ``u``.

    The result, of width ``2 w + 1``, is continuous when wrapped around (its first and
    last columns are equal), for spheres and cylinders.
    """
    texture = np.asarray(texture, dtype=np.float32)
    if texture.ndim != 3 or min(texture.shape[:2]) < 2:
        raise ValueError(f"texture must have shape (h, w, C) with h, w >= 2, got {texture.shape}")
    return np.concatenate([texture, texture[:, ::-1], texture[:, :1]], axis=1)


def _check_frame(frame) -> np.ndarray:
    frame = np.asarray(frame, dtype=np.float64)
    if frame.shape != (3, 3) or not np.allclose(frame.T @ frame, np.eye(3), atol=1e-9):
        raise ValueError(f"frame must be a 3 x 3 rotation matrix, got {frame.tolist()}")
    if np.linalg.det(frame) < 0:
        raise ValueError("frame must be a rotation (determinant +1), not a reflection")
    return frame


def _positive(value, name: str) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return value


class _Solid:
    """Ray casting shared by the solids (fields ``center``, ``frame``, ``twist``, ``texture``,
    ``name``, ``texture_name`` are the subclasses'); see the module conventions."""

    def _check_common(self):
        center = np.asarray(self.center, dtype=np.float64).reshape(-1)
        xi = np.asarray(self.twist, dtype=np.float64).reshape(-1)
        texture = np.asarray(self.texture, dtype=np.float32)
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise ValueError(f"center must be 3 finite numbers, got {self.center!r}")
        if xi.shape != (6,) or not np.all(np.isfinite(xi)):
            raise ValueError(f"twist must be 6 finite numbers, got {self.twist!r}")
        if texture.ndim != 3 or texture.shape[2] != 3 or min(texture.shape[:2]) < 2:
            raise ValueError(
                f"texture must have shape (h, w, 3) with h, w >= 2, got {texture.shape}"
            )
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "frame", _check_frame(self.frame))
        object.__setattr__(self, "twist", xi)
        object.__setattr__(self, "texture", texture)
        planes = np.ascontiguousarray(np.moveaxis(texture, -1, 0).reshape(3, -1))
        object.__setattr__(self, "_planes", planes)

    def pose(self, fraction: float) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and translation ``exp(fraction * twist)`` from the reference pose."""
        M = se3_exp(float(fraction) * self.twist)
        return M[:3, :3], M[:3, 3]

    @property
    def bounding_radius(self) -> float:  # pragma: no cover - overridden
        raise NotImplementedError

    def describe(self) -> dict:
        """The object for ``gt/objects.json``: kind, name, texture, shape and twist."""
        out = {"name": self.name, "kind": self.kind, "twist": [float(c) for c in self.twist]}
        out["center"] = [float(c) for c in self.center]
        out["frame"] = [[float(c) for c in row] for row in self.frame]
        out.update(self._shape())
        out["texture"] = self.texture_name
        return out

    def _screen_box(self, camera: StereoCamera, view: str, R, T, width: int, height: int):
        """Pixel rectangle ``(x0, x1, y0, y1)`` (end exclusive) that holds the object's image.

        The cube around the bounding sphere, moved to the instant, projects into the
        convex hull of its projected corners when all of them lie in front of the
        camera; otherwise the whole image is returned.
        """
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        points = (R @ self.center + T - camera.center(view)) + self.bounding_radius * corners
        if np.any(points[:, 2] <= 1e-9):
            return 0, width, 0, height
        h = points @ camera.K.T
        x, y = h[:, 0] / h[:, 2], h[:, 1] / h[:, 2]
        x0 = int(np.clip(np.floor(x.min()) - 1, 0, width))
        x1 = int(np.clip(np.ceil(x.max()) + 2, 0, width))
        y0 = int(np.clip(np.floor(y.min()) - 1, 0, height))
        y1 = int(np.clip(np.ceil(y.max()) + 2, 0, height))
        return x0, x1, y0, y1

    def cast(
        self, camera: StereoCamera, view: str, size, fraction: float, *, points: bool, offset=(0, 0)
    ):
        """Depth and texture coordinates (and reference-pose points) of every pixel's ray.

        Returns ``(depth, fields)``: ``depth`` (H, W) with ``inf`` where the object is
        missed; ``fields`` the list ``[u, v]`` (plus ``[X, Y, Z]`` with ``points``) of
        (H, W) arrays, NaN where missed.
        """
        width, height = size
        R, T = self.pose(fraction)
        # Ray C + lam K^-1 (x, y, 1) in local coordinates: q + lam B (x, y, 1).
        q = self.frame.T @ (R.T @ (camera.center(view) - T) - self.center)
        B = self.frame.T @ R.T @ camera.K_inv
        depth = np.full((height, width), np.inf)
        fields = [np.full((height, width), np.nan) for _ in range(5 if points else 2)]
        x0, x1, y0, y1 = self._screen_box(camera, view, R, T, width, height)
        if x0 >= x1 or y0 >= y1:
            return depth, fields
        y, x = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        x, y = x + offset[0], y + offset[1]
        rays = np.stack([x, y, np.ones_like(x)], -1) @ B.T  # (h, w, 3) local directions
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            lam, local, u, v = self._local_hits(q, rays)
        hit = np.isfinite(lam) & (lam > 0)
        window = (slice(y0, y1), slice(x0, x1))
        depth[window] = np.where(hit, lam, np.inf)
        values = [u, v]
        if points:
            P = local @ self.frame.T + self.center
            values += [P[..., 0], P[..., 1], P[..., 2]]
        for field_, value in zip(fields, values, strict=True):
            field_[window] = np.where(hit, value, np.nan)
        return depth, fields

    def _local_hits(self, q, rays):  # pragma: no cover - overridden
        """``(lam, local point, u, v)`` of rays ``q + lam * rays``; ``lam`` NaN or inf on a miss."""
        raise NotImplementedError


def _nearest_quadric_root(a, b, c):
    """Smallest positive root of ``a lam^2 + 2 b lam + c = 0`` (``inf`` if none)."""
    disc = b * b - a * c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    near = (-b - root) / a
    far = (-b + root) / a
    lam = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    return np.where(np.isfinite(lam), lam, np.inf), near, far


@dataclass(frozen=True)
class SphereObject(_Solid):
    """A textured sphere moving rigidly with a constant twist.

    Parameters
    ----------
    center : array_like, shape (3,)
        Centre in the reference pose, left-camera coordinates.
    radius : float
    frame : array_like, shape (3, 3)
        Rotation whose columns are the local axes; the third is the pole axis.
    twist : array_like, shape (6,)
        Motion per frame interval, ``(v, omega)``.
    texture : ndarray, shape (h, w, 3)
        Linear RGB in [0, 1], periodic along ``u`` (see :func:`periodic_texture`).
        A local point ``q`` at longitude ``phi = atan2(q_y, q_x)`` and polar angle
        ``theta = arccos(q_z / r)`` has ``u = (phi + pi) / (2 pi) * (w - 1)`` and
        ``v = theta / pi * (h - 1)``.
    name, texture_name : str
    """

    center: np.ndarray
    radius: float
    frame: np.ndarray
    twist: np.ndarray
    texture: np.ndarray
    name: str = "sphere"
    texture_name: str = ""
    kind = "sphere"

    def __post_init__(self):
        self._check_common()
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    @property
    def bounding_radius(self) -> float:
        return self.radius

    def _shape(self) -> dict:
        return {"radius": self.radius}

    def _local_hits(self, q, rays):
        a = np.einsum("...k,...k->...", rays, rays)
        lam, _, _ = _nearest_quadric_root(a, rays @ q, q @ q - self.radius**2)
        local = q + np.where(np.isfinite(lam), lam, np.nan)[..., None] * rays
        h, w = self.texture.shape[:2]
        phi = np.arctan2(local[..., 1], local[..., 0])
        theta = np.arccos(np.clip(local[..., 2] / self.radius, -1.0, 1.0))
        return lam, local, (phi + np.pi) / (2 * np.pi) * (w - 1), theta / np.pi * (h - 1)


@dataclass(frozen=True)
class CylinderObject(_Solid):
    """A closed textured cylinder (side and two caps) moving rigidly with a constant twist.

    Parameters
    ----------
    center : array_like, shape (3,)
        Midpoint of the axis in the reference pose.
    radius, half_height : float
    frame : array_like, shape (3, 3)
        Rotation whose columns are the local axes; the third is the cylinder's axis.
    twist : array_like, shape (6,)
    texture : ndarray, shape (h, w, 3)
        Periodic along ``u``. The side point at angle ``phi = atan2(q_y, q_x)`` and
        height ``q_z`` has ``u = (phi + pi) / (2 pi) * (w - 1)`` and
        ``v = (q_z + half_height) / t``, with the texel size ``t = 2 pi r / (w - 1)``;
        cap points have ``u = q_x / t + (w - 1) / 4``, ``v = q_y / t + (h - 1) / 2``.
    name, texture_name : str
    """

    center: np.ndarray
    radius: float
    half_height: float
    frame: np.ndarray
    twist: np.ndarray
    texture: np.ndarray
    name: str = "cylinder"
    texture_name: str = ""
    kind = "cylinder"

    def __post_init__(self):
        self._check_common()
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        object.__setattr__(self, "half_height", _positive(self.half_height, "half_height"))

    @property
    def bounding_radius(self) -> float:
        return float(np.hypot(self.radius, self.half_height))

    def _shape(self) -> dict:
        return {"radius": self.radius, "half_height": self.half_height}

    def _local_hits(self, q, rays):
        r, hh = self.radius, self.half_height
        bx, by, bz = rays[..., 0], rays[..., 1], rays[..., 2]
        _, near, far = _nearest_quadric_root(
            bx * bx + by * by, q[0] * bx + q[1] * by, q[0] ** 2 + q[1] ** 2 - r * r
        )
        candidates = []
        for lam in (near, far):  # the side, within the height
            ok = (lam > 0) & (np.abs(q[2] + lam * bz) <= hh)
            candidates.append(np.where(ok, lam, np.inf))
        for z in (-hh, hh):  # the caps, within the radius
            lam = (z - q[2]) / bz
            ok = (lam > 0) & (np.hypot(q[0] + lam * bx, q[1] + lam * by) <= r)
            candidates.append(np.where(ok, lam, np.inf))
        candidates = np.stack(candidates)
        which = np.argmin(candidates, axis=0)
        lam = np.take_along_axis(candidates, which[None], 0)[0]
        local = q + np.where(np.isfinite(lam), lam, np.nan)[..., None] * rays
        h, w = self.texture.shape[:2]
        texel = 2 * np.pi * r / (w - 1)
        phi = np.arctan2(local[..., 1], local[..., 0])
        side = which < 2
        u = np.where(
            side, (phi + np.pi) / (2 * np.pi) * (w - 1), local[..., 0] / texel + (w - 1) / 4
        )
        v = np.where(side, (local[..., 2] + hh) / texel, local[..., 1] / texel + (h - 1) / 2)
        return lam, local, u, v


# Where each face of a box takes its texture window, as fractions of the slack.
_FACE_OFFSETS = ((0.0, 0.0), (1.0, 1.0), (0.5, 0.0), (0.0, 1.0), (1.0, 0.5), (0.5, 0.5))


@dataclass(frozen=True)
class BoxObject(_Solid):
    """A textured box (rectangular cuboid) moving rigidly with a constant twist.

    Parameters
    ----------
    center : array_like, shape (3,)
        Centre in the reference pose.
    half_sizes : array_like, shape (3,)
        Half its extent along each local axis.
    frame : array_like, shape (3, 3)
        Rotation whose columns are the box's axes.
    twist : array_like, shape (6,)
    texture : ndarray, shape (h, w, 3)
    texel_size : float
        Side of one texel in scene units. A point of the face normal to local axis
        ``i`` has ``u = (q_j + s_j) / texel_size + a`` and ``v = (q_k + s_k) / texel_size
        + b`` (``j, k`` the next axes cyclically, ``s`` the half sizes); the offsets
        ``(a, b)`` differ per face, so that faces show different parts of the texture.
    name, texture_name : str
    """

    center: np.ndarray
    half_sizes: np.ndarray
    frame: np.ndarray
    twist: np.ndarray
    texture: np.ndarray
    texel_size: float
    name: str = "box"
    texture_name: str = ""
    kind = "box"

    def __post_init__(self):
        self._check_common()
        half = np.asarray(self.half_sizes, dtype=np.float64).reshape(-1)
        if half.shape != (3,) or not np.all(np.isfinite(half)) or np.any(half <= 0):
            raise ValueError(f"half_sizes must be 3 positive numbers, got {self.half_sizes!r}")
        object.__setattr__(self, "half_sizes", half)
        object.__setattr__(self, "texel_size", _positive(self.texel_size, "texel_size"))

    @property
    def bounding_radius(self) -> float:
        return float(np.linalg.norm(self.half_sizes))

    def _shape(self) -> dict:
        return {
            "half_sizes": [float(c) for c in self.half_sizes],
            "texel_size": self.texel_size,
        }

    def _local_hits(self, q, rays):
        s = self.half_sizes
        t1 = (-s - q) / rays
        t2 = (s - q) / rays
        entry = np.minimum(t1, t2)
        exit_ = np.maximum(t1, t2).min(-1)
        axis = np.argmax(np.nan_to_num(entry, nan=-np.inf), -1)
        lam = np.take_along_axis(entry, axis[..., None], -1)[..., 0]
        lam = np.where((lam <= exit_) & (lam > 0), lam, np.inf)
        local = q + np.where(np.isfinite(lam), lam, np.nan)[..., None] * rays
        h, w = self.texture.shape[:2]
        face = 2 * axis + (np.take_along_axis(local, axis[..., None], -1)[..., 0] > 0)
        u = np.full(lam.shape, np.nan)
        v = np.full(lam.shape, np.nan)
        for f, (fu, fv) in enumerate(_FACE_OFFSETS):
            i = f // 2
            j, k = (i + 1) % 3, (i + 2) % 3
            on = face == f
            slack_u = max(w - 1 - 2 * s[j] / self.texel_size, 0.0)
            slack_v = max(h - 1 - 2 * s[k] / self.texel_size, 0.0)
            u[on] = (local[on, j] + s[j]) / self.texel_size + fu * slack_u
            v[on] = (local[on, k] + s[k]) / self.texel_size + fv * slack_v
        return lam, local, u, v


def describe_object(index: int, obj) -> dict:
    """``{"id": index, ...}`` and the object's own :meth:`describe` for ``gt/objects.json``."""
    return {"id": int(index), **obj.describe()}


@dataclass(frozen=True)
class RayHits:
    """What the ray of every pixel of a view hits at one instant.

    Attributes
    ----------
    depth : ndarray, shape (H, W), float64
        Depth ``Z`` of the hit in left-camera coordinates; ``inf`` where nothing is hit.
    object_id : ndarray, shape (H, W), int32
        Index of the object hit, -1 where nothing is hit.
    texture_u, texture_v : ndarray, shape (H, W), float64
        Texture coordinates of the hit in its object's texture; NaN where nothing is hit.
    points : ndarray, shape (H, W, 3), float64, or None
        The hit point in its object's reference pose (NaN where nothing is hit), if
        asked for.
    """

    depth: np.ndarray
    object_id: np.ndarray
    texture_u: np.ndarray
    texture_v: np.ndarray
    points: np.ndarray | None = None


@dataclass(frozen=True)
class InstantRender:
    """An instantaneous image of one view and its exact geometry.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float32
        Linear RGB, 0 where nothing is hit.
    depth : ndarray, shape (H, W), float64
        Left-camera depth of the point seen, ``inf`` where nothing is hit.
    object_id : ndarray, shape (H, W), int32
        Object seen, -1 for none.
    tracked : ndarray, shape (K, H, W, 2), float64
        Position in the same view of the point seen, at each instant asked for; NaN
        where nothing is hit.
    """

    image: np.ndarray
    depth: np.ndarray
    object_id: np.ndarray
    tracked: np.ndarray


@dataclass(frozen=True)
class BlurredRender:
    """A motion-blurred frame of one view.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float32
        Mean of the instantaneous images over the exposure.
    mixed : ndarray, shape (H, W), bool
        True where the object seen changes during the exposure.
    """

    image: np.ndarray
    mixed: np.ndarray


def _check_size(size) -> tuple[int, int]:
    try:
        width, height = (int(s) for s in size)
    except (TypeError, ValueError):
        raise ValueError(f"size must be (width, height), got {size!r}") from None
    if width < 2 or height < 2:
        raise ValueError(f"size must be at least (2, 2), got {size!r}")
    return width, height


def _check_view(view: str) -> str:
    if view not in VIEWS:
        raise ValueError(f"view must be 'left' or 'right', got {view!r}")
    return view


def _ray_geometry(normal, twist, camera: StereoCamera, view: str, fraction: float):
    """Closed forms of the rays of ``view`` against a plane moved to ``fraction``.

    The ray ``C + lam d``, ``d = K^-1 (x, y, 1)``, meets the moved plane
    ``P^T n_t = 1`` at ``lam = numerator / (g . (x, y, 1))`` with
    ``numerator = 1 - C . n_t`` and ``g = K^-T n_t``. The hit, moved back to the
    reference pose, is ``R^T (C + lam d - T) = o + lam A (x, y, 1)`` with
    ``o = R^T (C - T)`` and ``A = R^T K^-1``.
    """
    M = se3_exp(float(fraction) * np.asarray(twist, dtype=np.float64))
    R, T = M[:3, :3], M[:3, 3]
    n_t = move_plane(normal, R, T)
    C = camera.center(_check_view(view))
    K_inv = camera.K_inv
    return 1.0 - C @ n_t, K_inv.T @ n_t, R.T @ (C - T), R.T @ K_inv


def _depth(numerator: float, g: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ray parameter (= depth) of the hits, ``inf`` where the plane is not hit in front."""
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = numerator / (g[0] * x + g[1] * y + g[2])
    return np.where(np.isfinite(lam) & (lam > 0), lam, np.inf)


def _affine_along_ray(o, A, lam, x, y):
    """``o + lam * (A @ (x, y, 1))`` for vectors ``o`` (k,) and rows ``A`` (k, 3), stacked last."""
    with np.errstate(invalid="ignore"):
        return [o[j] + lam * (A[j, 0] * x + A[j, 1] * y + A[j, 2]) for j in range(len(o))]


def intersect_plane(
    normal: np.ndarray,
    twist: np.ndarray,
    camera: StereoCamera,
    view: str,
    x: np.ndarray,
    y: np.ndarray,
    fraction: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Cast the rays of pixels ``(x, y)`` of ``view`` at a plane moved to instant ``fraction``.

    Parameters
    ----------
    normal : ndarray, shape (3,)
        Scaled normal of the plane in its reference pose.
    twist : ndarray, shape (6,)
        The plane's motion per frame interval.
    camera : StereoCamera
    view : {'left', 'right'}
    x, y : ndarray
        Pixel coordinates (broadcast together).
    fraction : float

    Returns
    -------
    depth : ndarray
        Ray parameter ``lambda`` = depth ``Z`` of the hit; ``inf`` where the ray does
        not meet the plane in front of the camera.
    points : ndarray, shape (..., 3)
        The hit points moved back to the reference pose (non-finite where no hit).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    numerator, g, o, A = _ray_geometry(normal, twist, camera, view, fraction)
    lam = _depth(numerator, g, x, y)
    return lam, np.stack(_affine_along_ray(o, A, lam, x, y), -1)


def cast_rays(
    objects,
    camera: StereoCamera,
    view: str,
    size: tuple[int, int],
    fraction: float,
    *,
    points: bool = True,
    offset: tuple[float, float] = (0.0, 0.0),
) -> RayHits:
    """Intersect the ray of every pixel of ``view`` with the objects at instant ``fraction``.

    Parameters
    ----------
    objects : sequence of PlanarObject, SphereObject, CylinderObject or BoxObject
    camera : StereoCamera
    view : {'left', 'right'}
    size : tuple of int
        ``(width, height)`` in pixels.
    fraction : float
        The instant (see the module conventions).
    points : bool
        Also return the reference-pose points hit (needed by :func:`track`).
    offset : tuple of float
        ``(dx, dy)``: cast the ray through ``(x + dx, y + dy)`` instead of each pixel
        centre (supersampling, :func:`pixel_offsets`).

    Returns
    -------
    RayHits
    """
    width, height = _check_size(size)
    _check_view(view)
    x = np.arange(width, dtype=np.float64)[None, :] + offset[0]
    y = np.arange(height, dtype=np.float64)[:, None] + offset[1]
    shape = (height, width)
    best = np.full(shape, np.inf)
    object_id = np.full(shape, -1, dtype=np.int32)
    fields = [np.full(shape, np.nan) for _ in range(5 if points else 2)]  # u, v (, X, Y, Z)
    for k, obj in enumerate(objects):
        if isinstance(obj, _Solid):
            lam, values = obj.cast(
                camera, view, (width, height), fraction, points=points, offset=offset
            )
        else:
            numerator, g, o, A = _ray_geometry(obj.normal, obj.twist, camera, view, fraction)
            lam = _depth(numerator, g, x, y)
            # Texture coordinates are affine in the reference-pose point: (u, v) = B P + c.
            B, c = obj._texture_map()
            values = _affine_along_ray(B @ o + c, B @ A, lam, x, y)
            if obj.bounded:
                h, w = obj.texture.shape[:2]
                u, v = values
                inside = (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
                lam = np.where(inside, lam, np.inf)
            if points:
                values += _affine_along_ray(o, A, lam, x, y)
        nearer = lam < best
        if nearer.all():
            best, fields = lam, values  # full (H, W) arrays
            object_id[...] = k
        elif nearer.any():
            best = np.where(nearer, lam, best)
            object_id[nearer] = k
            for field_, value in zip(fields, values, strict=True):
                field_[nearer] = value[nearer]
    return RayHits(
        depth=best,
        object_id=object_id,
        texture_u=fields[0],
        texture_v=fields[1],
        points=np.stack(fields[2:], -1) if points else None,
    )


def _bilinear(planes: np.ndarray, height: int, width: int, u, v) -> np.ndarray:
    """Bilinear lookup in channel-first ``planes`` (C, height * width) at ``(u, v)``."""
    u = np.clip(u, 0.0, width - 1.0)
    v = np.clip(v, 0.0, height - 1.0)
    u0 = np.minimum(u.astype(np.intp), width - 2)
    v0 = np.minimum(v.astype(np.intp), height - 2)
    fu = (u - u0).astype(np.float32)
    fv = (v - v0).astype(np.float32)
    w11 = fu * fv
    w10 = fv - w11
    w01 = fu - w11
    w00 = 1.0 - fu - w10
    i00 = v0 * width + u0
    taps = ((i00, w00), (i00 + 1, w01), (i00 + width, w10), (i00 + width + 1, w11))
    out = np.empty(u.shape + (planes.shape[0],), dtype=np.float32)
    for ch, plane in enumerate(planes):
        total = np.take(plane, taps[0][0]) * taps[0][1]
        for index, weight in taps[1:]:
            total += np.take(plane, index) * weight
        out[..., ch] = total
    return out


def sample_texture(texture: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear lookup of ``texture`` (h, w, C) at ``(u, v)``; coordinates clamp to the edge.

    Texel ``(row, col)`` has its centre at ``(u, v) = (col, row)``.
    """
    texture = np.asarray(texture, dtype=np.float32)
    h, w = texture.shape[:2]
    planes = np.moveaxis(texture.reshape(h, w, -1), -1, 0).reshape(-1, h * w)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    return _bilinear(planes, h, w, u, v)


def shade(objects, hits: RayHits) -> np.ndarray:
    """Texture colour of every hit, shape (H, W, 3) float32; 0 where nothing is hit."""
    image = np.zeros(hits.object_id.shape + (3,), dtype=np.float32)
    for k, obj in enumerate(objects):
        mask = hits.object_id == k
        h, w = obj.texture.shape[:2]
        if mask.all():
            image[...] = _bilinear(obj._planes, h, w, hits.texture_u, hits.texture_v)
        elif mask.any():
            u, v = hits.texture_u[mask], hits.texture_v[mask]
            image[mask] = _bilinear(obj._planes, h, w, u, v)
    return image


def track(objects, camera: StereoCamera, view: str, hits: RayHits, fractions) -> np.ndarray:
    """Where the points of ``hits`` project in ``view`` at each instant of ``fractions``.

    ``hits`` must hold points (``cast_rays(..., points=True)``).

    Returns
    -------
    ndarray, shape (K, H, W, 2)
        Pixel positions ``(x, y)``; NaN where nothing was hit or the point is then
        behind the camera. Occlusion is not considered.
    """
    C = camera.center(_check_view(view))
    if hits.points is None:
        raise ValueError("hits hold no points: cast the rays with points=True")
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1)
    out = np.full((fractions.size,) + hits.object_id.shape + (2,), np.nan)
    for k, obj in enumerate(objects):
        mask = hits.object_id == k
        if not mask.any():
            continue
        P = hits.points if mask.all() else hits.points[mask]
        for j, s in enumerate(fractions):
            # Projection K (R P + T - C) of the moved point, as one affine map of P.
            R, T = obj.pose(s)
            h = P @ (camera.K @ R).T + camera.K @ (T - C)
            with np.errstate(divide="ignore", invalid="ignore"):
                q = np.where(h[..., 2:] > 0, h[..., :2] / h[..., 2:], np.nan)
            if mask.all():
                out[j] = q
            else:
                out[j][mask] = q
    return out


def render_instant(
    objects,
    camera: StereoCamera,
    view: str,
    size: tuple[int, int],
    fraction: float,
    *,
    track_to=(),
    supersampling: int = 1,
) -> InstantRender:
    """The instantaneous image of ``view`` at ``fraction``, with depth, object ids and tracks.

    Parameters
    ----------
    objects : sequence of objects (see :func:`cast_rays`)
    camera : StereoCamera
    view : {'left', 'right'}
    size : tuple of int
        ``(width, height)``.
    fraction : float
        The instant (see the module conventions).
    track_to : sequence of float
        Instants at which to project the point seen at every pixel (for flow).
    supersampling : int
        The image is the mean over ``supersampling**2`` rays per pixel
        (:func:`pixel_offsets`: the pixel's area); depth, ids and tracks are those of the
        ray through the pixel centre.
    """
    hits = cast_rays(objects, camera, view, size, fraction)
    if supersampling == 1:
        image = shade(objects, hits)
    else:
        offsets = pixel_offsets(supersampling)
        image = sum(
            shade(objects, cast_rays(objects, camera, view, size, fraction, offset=o))
            for o in offsets
        ) / len(offsets)
    return InstantRender(
        image=np.asarray(image, dtype=np.float32),
        depth=np.array(hits.depth),
        object_id=hits.object_id,
        tracked=track(objects, camera, view, hits, track_to),
    )


def render_blurred(
    objects,
    camera: StereoCamera,
    exposure: Exposure,
    view: str,
    size: tuple[int, int],
    frame: int,
    *,
    num_samples: int = 48,
    supersampling: int = 1,
) -> BlurredRender:
    """Frame ``frame`` of ``view``: the mean of ``num_samples`` instantaneous images.

    The instants are ``frame + exposure.sample_fractions(num_samples)``, the midpoints
    of equal sub-intervals of the exposure. Use at least 32 for a smooth blur. With
    ``supersampling`` S, instant ``j`` casts its rays through the pixel offset
    ``pixel_offsets(S)[j % S**2]`` (one ray per pixel and instant; the mean covers the
    pixel's area as well as the exposure); ``mixed`` compares instants of equal offset.
    """
    if int(num_samples) != num_samples or num_samples < 1:
        raise ValueError(f"num_samples must be a positive integer, got {num_samples!r}")
    width, height = _check_size(size)
    offsets = pixel_offsets(supersampling)
    total = np.zeros((height, width, 3))
    first_id = {}
    mixed = np.zeros((height, width), dtype=bool)
    for j, s in enumerate(frame + exposure.sample_fractions(int(num_samples))):
        which = j % len(offsets)
        hits = cast_rays(objects, camera, view, size, s, points=False, offset=offsets[which])
        total += shade(objects, hits)
        if which not in first_id:
            first_id[which] = hits.object_id
        else:
            mixed |= hits.object_id != first_id[which]
    return BlurredRender(image=(total / num_samples).astype(np.float32), mixed=mixed)


@dataclass(frozen=True)
class SceneSetup:
    """Everything that defines a synthetic clip, before rendering.

    Attributes
    ----------
    name : str
    camera : StereoCamera
    exposure : Exposure
    size : tuple of int
        ``(width, height)``.
    num_frames : int
    objects : tuple of objects (see :func:`cast_rays`)
    """

    name: str
    camera: StereoCamera
    exposure: Exposure
    size: tuple[int, int]
    num_frames: int
    objects: tuple

    def __post_init__(self):
        object.__setattr__(self, "size", _check_size(self.size))
        if int(self.num_frames) != self.num_frames or self.num_frames < 2:
            raise ValueError(f"num_frames must be an integer >= 2, got {self.num_frames!r}")
        object.__setattr__(self, "objects", tuple(self.objects))


@dataclass(frozen=True)
class RenderedScene:
    """A rendered stereo clip and its ground truth (views 'left' and 'right').

    Attributes
    ----------
    name : str
    camera : StereoCamera
    exposure : Exposure
    size : tuple of int
        ``(width, height)``.
    objects : tuple of objects (see :func:`cast_rays`)
        The true objects: reference pose at the centre of frame 0 and twists.
    num_samples : int
        Instants averaged per blurred frame.
    frames : dict of str to tuple of ndarray
        Blurred frames per view, (H, W, 3) float32.
    sharp : dict of str to tuple of ndarray
        Instantaneous images at the frame centres.
    disparity : dict of str to tuple of ndarray
        Disparity ``fx * baseline / Z`` (H, W) float32 at the frame centres; NaN where
        nothing is hit.
    flow : tuple of ndarray
        Left-view flow (H, W, 2) float32 from the centre of frame i to that of i + 1,
        for i = 0 .. num_frames - 2.
    mixed : dict of str to tuple of ndarray
        True where the blurred pixel mixes objects.
    object_ids : dict of str to tuple of ndarray
        Object seen (H, W) int32 at the frame centres, -1 for none.
    """

    name: str
    camera: StereoCamera
    exposure: Exposure
    size: tuple[int, int]
    objects: tuple
    num_samples: int
    frames: dict = field(repr=False)
    sharp: dict = field(repr=False)
    disparity: dict = field(repr=False)
    flow: tuple = field(repr=False)
    mixed: dict = field(repr=False)
    object_ids: dict = field(repr=False)

    @property
    def num_frames(self) -> int:
        return len(self.frames["left"])


def pixel_offsets(supersampling: int) -> list[tuple[float, float]]:
    """``(dx, dy)`` of ``supersampling**2`` rays on a regular grid over a pixel's area.

    ``[(0, 0)]`` for 1 (the pixel centre), e.g. the four ``(+-1/4, +-1/4)`` for 2.
    """
    if int(supersampling) != supersampling or supersampling < 1:
        raise ValueError(f"supersampling must be a positive integer, got {supersampling!r}")
    steps = (np.arange(int(supersampling)) + 0.5) / supersampling - 0.5
    return [(float(dx), float(dy)) for dy in steps for dx in steps]


def render_scene(
    setup: SceneSetup, *, num_samples: int = 48, supersampling: int = 1
) -> RenderedScene:
    """Render the blurred frames of both views and the ground truth of ``setup``.

    ``supersampling`` (see :func:`render_blurred` and :func:`render_instant`) makes blurred
    and sharp images means over each pixel's area; disparity, flow and ids stay those of
    the pixel centres.
    """
    width, height = setup.size
    grid = np.stack(np.meshgrid(np.arange(width), np.arange(height)), -1).astype(np.float64)
    frames, sharp, disparity, mixed, object_ids = ({v: [] for v in VIEWS} for _ in range(5))
    flow = []
    for view in VIEWS:
        for i in range(setup.num_frames):
            blurred = render_blurred(
                setup.objects,
                setup.camera,
                setup.exposure,
                view,
                setup.size,
                i,
                num_samples=num_samples,
                supersampling=supersampling,
            )
            frames[view].append(blurred.image)
            mixed[view].append(blurred.mixed)
            last = i == setup.num_frames - 1
            track_to = (i + 1,) if view == "left" and not last else ()
            instant = render_instant(
                setup.objects,
                setup.camera,
                view,
                setup.size,
                i,
                track_to=track_to,
                supersampling=supersampling,
            )
            sharp[view].append(instant.image)
            object_ids[view].append(instant.object_id)
            with np.errstate(divide="ignore"):
                d = setup.camera.depth_to_disparity(instant.depth)
            disparity[view].append(np.where(instant.object_id >= 0, d, np.nan).astype(np.float32))
            if track_to:
                flow.append((instant.tracked[0] - grid).astype(np.float32))
    return RenderedScene(
        name=setup.name,
        camera=setup.camera,
        exposure=setup.exposure,
        size=setup.size,
        objects=setup.objects,
        num_samples=int(num_samples),
        frames={v: tuple(a) for v, a in frames.items()},
        sharp={v: tuple(a) for v, a in sharp.items()},
        disparity={v: tuple(a) for v, a in disparity.items()},
        flow=tuple(flow),
        mixed={v: tuple(a) for v, a in mixed.items()},
        object_ids={v: tuple(a) for v, a in object_ids.items()},
    )
