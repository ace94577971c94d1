"""Study for issue 13: deblur the left view at t from several blurred observations.

Not the method (nothing in the package uses it): a measurement of what the other view and the
neighbouring frames add to the deconvolution, with the pipeline's own operators and weights.

Every observation is an operator that composes a warp and a blur: the reference sharp image
(left view, frame t) is warped to the observation's sharp image at its centre instant by the
scene flow's per-segment homographies (bilinear), then blurred by the observation's own
occlusion-aware homography operator (:func:`stereodeblur.pipeline.operator.view_operator`).
Observations: the left view at t (the reference, the pipeline's operator and data terms), the
right view at t (through the disparity), the left view at t - 1 and t + 1 (the scene flow's
motion taken as constant over three frames). A blurred pixel whose exposure touches pixels that
are not seen in the reference frame (occluded, outside, another segment) gets weight 0.
``--scale`` multiplies the extra observations' squared weights; ``--robust c`` reweights them
each IRLS round by ``1 / (1 + (r / c)^2)`` of their residual ``r``. The solver is a plain IRLS
of Eq. 6 (10 x 25, the pipeline's alpha and anchor) summing the data terms.

    python benchmarks/study_multi_observation.py SCENE [SCENE ...] [--motion-source gt]
        [--scale 0.3] [--robust 0.01]

Prints PSNR (2.5 % border) and the mean squared error in gt/mixed per set of observations.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
from scipy import ndimage

from stereodeblur.blur.trajectories import bilinear_taps, homography_positions
from stereodeblur.deconv.trust import OUTSIDE_WEIGHT, leaves_view
from stereodeblur.deconv.weights import hidden_weights
from stereodeblur.evaluation.metrics import psnr
from stereodeblur.geometry.plane import move_plane
from stereodeblur.geometry.rigid import se3_exp
from stereodeblur.io import open_scene
from stereodeblur.pipeline.motion import FrameMotion, stereo_motion
from stereodeblur.pipeline.operator import view_operator
from stereodeblur.pipeline.weights import data_terms
from stereodeblur.pipeline.window import read_window
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.settings import DeblurSettings

SETS = {
    "reference only": [],
    "+ right view": ["right"],
    "+ frames t-1, t+1": ["t-1", "t+1"],
    "all": ["right", "t-1", "t+1"],
}


def warp_matrix(positions: np.ndarray, shape) -> sp.csr_matrix:
    """Row y samples the source image bilinearly at ``positions[y]`` (clamped)."""
    H, W = shape
    index, weight, valid = bilinear_taps(positions.reshape(-1, 1, 2), shape, border="clamp")
    rows = np.broadcast_to(np.arange(H * W)[:, None, None], index.shape)
    matrix = sp.coo_matrix((weight[valid], (rows[valid], index[valid])), shape=(H * W, H * W))
    return matrix.tocsr()


def splat_labels(sf: SceneFlow, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Labels of the left view seeing ``points`` (nearest first); holes filled, and marked."""
    H, W = sf.shape
    q = sf.camera.project(points, "left")
    xr, yr = np.round(q[..., 0]).astype(int), np.round(q[..., 1]).astype(int)
    z = points[..., 2]
    ok = (xr >= 0) & (xr < W) & (yr >= 0) & (yr < H) & (z > 0)
    order = np.argsort(np.where(ok, -z, -np.inf).ravel(), kind="stable")  # far first
    order = order[ok.ravel()[order]]
    labels = np.full((H, W), -1, np.int32)
    labels[yr.ravel()[order], xr.ravel()[order]] = sf.labels.ravel()[order]
    holes = labels < 0
    if holes.any() and not holes.all():
        _, (iy, ix) = ndimage.distance_transform_edt(holes, return_indices=True)
        labels[holes] = labels[iy[holes], ix[holes]]
    return labels, holes


def temporal_observation(sf: SceneFlow, k: int, exposure, settings):
    """Composite operator and weights of the left view at t + k."""
    M = se3_exp(float(k) * sf.twists)
    moved = zip(sf.normals, M, strict=True)
    normals = np.stack([move_plane(n, m[:3, :3], m[:3, 3]) for n, m in moved])
    labels, holes = splat_labels(sf, sf.points_at(float(k)))
    sfk = SceneFlow(sf.camera, labels, normals, sf.twists, np.zeros_like(holes))
    motion = FrameMotion(0, 1, "left", sfk, sfk.flow(), sfk.reversed().flow())
    blur = view_operator(motion, exposure, settings)
    positions = homography_positions(sf.homographies(np.array([float(k)])), labels)[:, :, 0]
    H, W = sf.shape
    inside = (positions[..., 0] >= 0) & (positions[..., 0] <= W - 1)
    inside &= (positions[..., 1] >= 0) & (positions[..., 1] <= H - 1)
    xi = np.clip(np.round(positions[..., 0]).astype(int), 0, W - 1)
    yi = np.clip(np.round(positions[..., 1]).astype(int), 0, H - 1)
    seen = inside & ~holes & (sf.labels[yi, xi] == labels)
    unseen = blur.operator.matrix @ (~seen).ravel().astype(np.float32)
    duty = exposure.duty_cycle
    w = np.where(leaves_view(motion.flow_forward, motion.flow_backward, duty), OUTSIDE_WEIGHT, 1.0)
    if blur.hidden is not None:
        w = w * hidden_weights(blur.hidden)
    w = np.where(unseen.reshape(H, W) > 0.02, 0.0, w)
    return (blur.operator.matrix @ warp_matrix(positions, (H, W))).tocsr(), w


def right_observation(scene, window, motions, settings):
    """Composite operator and weights of the right view at t."""
    blur = view_operator(motions["right"], window.exposure, settings)
    terms = data_terms(scene, window, "right", blur, settings)
    disparity = motions["right"].sceneflow.disparity()
    H, W = disparity.shape
    y, x = np.mgrid[0:H, 0:W]
    positions = np.stack([x + disparity, y.astype(np.float64)], -1)
    left_disparity = motions["left"].sceneflow.disparity()
    xi = np.clip(np.round(x + disparity).astype(int), 0, W - 1)
    seen = (x + disparity <= W - 1) & (np.abs(left_disparity[y, xi] - disparity) < 1.0)
    unseen = blur.operator.matrix @ (~seen).ravel().astype(np.float32)
    w = np.where(unseen.reshape(H, W) > 0.02, 0.0, terms.weights)
    return (blur.operator.matrix @ warp_matrix(positions, (H, W))).tocsr(), w


def _gradient(image):
    dx, dy = np.zeros_like(image), np.zeros_like(image)
    dx[:, :-1] = image[:, 1:] - image[:, :-1]
    dy[:-1] = image[1:] - image[:-1]
    return dx, dy


def _gradient_adjoint(dx, dy):
    out = np.zeros_like(dx)
    out[:, :-1] -= dx[:, :-1]
    out[:, 1:] += dx[:, :-1]
    out[:-1] -= dy[:-1]
    out[1:] += dy[:-1]
    return out


def solve(observations, shape, alpha, start, anchor, *, robust=0.0, num_irls=10, num_cg=25):
    """Eq. 6 with a sum of data terms ``(A, B, w^2)`` and the anchor to ``start``."""
    H, W = shape
    C = start.shape[2]
    x = start.reshape(H * W, C).astype(np.float64)
    beta = None if anchor is None else anchor.reshape(-1, 1).astype(np.float64)
    weights = [w2 for _, _, w2 in observations]
    transposed = [A.T.tocsr() for A, _, _ in observations]
    for round_ in range(num_irls):
        if robust > 0 and round_ > 0:
            for j, (A, B, w2) in enumerate(observations[1:], start=1):
                r = np.sqrt(np.mean((B - A @ x) ** 2, axis=1))
                weights[j] = w2 / (1 + (r / robust) ** 2)
        terms = list(zip(transposed, observations, weights, strict=True))
        b = sum(At @ (w[:, None] * B) for At, (_, B, _), w in terms)
        if beta is not None:
            b = b + beta * start.reshape(-1, C)
        dx, dy = _gradient(x.reshape(H, W, C))
        rx = np.maximum(np.abs(dx), 0.01) ** (0.8 - 2)
        ry = np.maximum(np.abs(dy), 0.01) ** (0.8 - 2)

        def normal(v, terms=terms, rx=rx, ry=ry):
            out = sum(At @ (w[:, None] * (A @ v)) for At, (A, _, _), w in terms)
            gx, gy = _gradient(v.reshape(H, W, C))
            out = out + alpha * _gradient_adjoint(rx * gx, ry * gy).reshape(H * W, C)
            return out if beta is None else out + beta * v

        r = b - normal(x)
        p = r.copy()
        rs = np.sum(r * r, axis=0)
        for _ in range(num_cg):
            q = normal(p)
            step = rs / np.maximum(np.sum(p * q, axis=0), 1e-30)
            x += step * p
            r -= step * q
            rs_new = np.sum(r * r, axis=0)
            p = r + (rs_new / np.maximum(rs, 1e-30)) * p
            rs = rs_new
    return x.reshape(H, W, C)


def study(root: str, motion_source: str, scale: float, robust: float) -> None:
    scene = open_scene(root)
    settings = DeblurSettings(motion_source=motion_source)
    index = 1
    window = read_window(scene, index, ("left", "right"), settings)
    motions = stereo_motion(scene, window, ("left", "right"), settings).views
    blur = view_operator(motions["left"], window.exposure, settings)
    terms = data_terms(scene, window, "left", blur, settings)
    left = window.blurred("left")
    H, W, C = left.shape
    sharp = scene.read_gt_sharp("left", index)
    mixed = scene.read_gt_mixed("left", index) > 0
    b = int(round(0.025 * W))

    def score(image):
        a, s = np.clip(image, 0, 1)[b:-b, b:-b], sharp[b:-b, b:-b]
        return psnr(a, s), float(np.mean((a - s)[mixed[b:-b, b:-b]] ** 2))

    def flat(image):
        return image.reshape(-1, C).astype(np.float64)

    reference = (blur.operator.matrix, flat(left), (terms.weights**2).ravel())
    A, w = right_observation(scene, window, motions, settings)
    extra = {"right": (A, flat(window.blurred("right")), scale * (w**2).ravel())}
    for k in (-1, 1):
        A, w = temporal_observation(motions["left"].sceneflow, k, window.exposure, settings)
        extra[f"t{k:+d}"] = (A, flat(scene.read_frame("left", index + k)), scale * (w**2).ravel())
    print(f"{root} ({motion_source}): blurred {score(left)[0]:.2f} dB", flush=True)
    for name, keys in SETS.items():
        start = time.perf_counter()
        observations = [reference] + [extra[k] for k in keys]
        image = solve(observations, (H, W), terms.alpha, left, terms.anchor, robust=robust)
        value, mse = score(image)
        took = time.perf_counter() - start
        print(f"  {name:20s} {value:6.2f} dB  mixed MSE {mse:.5f}  {took:.0f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--motion-source", default="gt", choices=("gt", "sceneflow"))
    parser.add_argument("--scale", type=float, default=1.0)
    parser.add_argument("--robust", type=float, default=0.0)
    args = parser.parse_args()
    for root in args.scenes:
        study(root, args.motion_source, args.scale, args.robust)


if __name__ == "__main__":
    main()
