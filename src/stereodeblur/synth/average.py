"""Real blur benchmarks from sharp high-frame-rate stereo footage, by frame averaging.

As for the paper's motorised-rail test set: ``window`` consecutive sharp frames
of a fast stereo clip are averaged (in linear intensity) into one blurred frame;
the sharp frame at the centre of the window is the ground truth.

Timing
------
With source frame rate ``f``, ``window = K`` (odd) and ``stride = S >= K``,
blurred frame ``j`` averages source frames ``j S .. j S + K - 1``; its centre is
source frame ``c_j = j S + (K - 1) / 2``. The new scene has frame rate ``f / S``
and exposure ``K / f``: the K source instants are exactly the midpoints of K equal
sub-intervals of that exposure, the samples of
:meth:`~stereodeblur.geometry.camera.Exposure.sample_fractions`. Source frames
count as instantaneous (their own exposure is ignored).

Ground truth
------------
``gt/sharp/VIEW/j`` is source frame ``c_j``; ``gt/disparity/VIEW/j`` is copied
from the source's ``c_j`` when it has one; ``gt/flow/left/j`` is the source's
left flows ``c_j -> c_j + 1 -> ... -> c_{j+1}`` composed (bilinear), when the
source has all of them; unknown where a chain leaves the view or meets an
unknown flow. ``gt/average.json`` records the source and the frames averaged.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy import ndimage

from ..errors import InputError
from ..geometry.camera import VIEWS, Exposure
from ..io.files import atomic_write
from ..io.scene import CameraInfo, SceneWriter


def compose_flows(flows) -> np.ndarray:
    """Flow from frame 0 to frame len(flows) of the chain ``flows[k]`` (frame k -> k + 1).

    Each flow is (H, W, 2) on its own frame's grid; NaN where unknown or where the
    chain leaves the image.
    """
    flows = [np.asarray(f, dtype=np.float64) for f in flows]
    if not flows:
        raise InputError("compose_flows needs at least one flow")
    total = flows[0].copy()
    H, W = total.shape[:2]
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    for flow in flows[1:]:
        coords = [y + total[..., 1], x + total[..., 0]]
        unknown = ~np.all(np.isfinite(total), axis=2)
        coords = [np.where(unknown, -1.0, c) for c in coords]
        step = np.stack(
            [
                ndimage.map_coordinates(flow[..., c], coords, order=1, mode="constant", cval=np.nan)
                for c in (0, 1)
            ],
            axis=-1,
        )
        total = total + step
    return total.astype(np.float32)


def average_clip(
    source,
    output: str | os.PathLike,
    *,
    window: int,
    stride: int | None = None,
    overwrite: bool = False,
    protect=(),
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Write a blurred scene made by averaging ``window`` frames of ``source``.

    Parameters
    ----------
    source : Scene or FrameSource
        A sharp stereo clip (see :func:`stereodeblur.io.sources.open_source`).
    output : path
        Output scene folder.
    window : int
        Frames averaged per blurred frame, odd (the centre frame is the ground truth).
    stride : int, optional
        Source frames between two blurred frames' starts, at least ``window``
        (default ``window``).
    overwrite : bool
        Write into a folder that holds another scene.
    protect : paths
        Input folders the output must not be written into.
    progress : callable, optional
        Called with a message per blurred frame.
    """
    if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 1:
        raise InputError(f"--window must be a positive integer, got {window!r}")
    if window % 2 == 0:
        raise InputError(
            f"--window must be odd so that a sharp frame sits at the window's centre, got {window}"
        )
    stride = window if stride is None else stride
    if isinstance(stride, bool) or not isinstance(stride, int | np.integer) or stride < window:
        raise InputError(f"--stride must be an integer >= --window ({window}), got {stride!r}")
    n = source.num_frames
    count = (n - window) // stride + 1 if n >= window else 0
    if count < 2:
        raise InputError(
            f"the source has {n} frames: --window {window} with stride {stride} gives "
            f"{max(count, 0)} blurred frame(s), at least 2 are needed"
        )
    rate = source.info.exposure.frame_rate
    info = CameraInfo(source.info.camera, Exposure(rate / stride, window / rate), source.info.color)
    writer = SceneWriter(output, info, overwrite=overwrite, protect=protect)
    say = progress or (lambda message: None)
    half = window // 2
    centres = [j * stride + half for j in range(count)]
    has_gt = hasattr(source, "read_gt_disparity")
    for j in range(count):
        first = j * stride
        for view in VIEWS:
            total = None
            for k in range(first, first + window):
                frame = source.read_frame(view, k).astype(np.float64)
                total = frame if total is None else total + frame
            writer.write_frame(view, j, (total / window).astype(np.float32))
            writer.write_gt_sharp(view, j, source.read_frame(view, centres[j]))
            if has_gt and source.has_gt("disparity", view, centres[j]):
                writer.write_gt_disparity(view, j, source.read_gt_disparity(view, centres[j]))
        if has_gt and j + 1 < count:
            chain = range(centres[j], centres[j + 1])
            if all(source.has_gt("flow", "left", k) for k in chain):
                writer.write_gt_flow(
                    "left", j, compose_flows([source.read_gt_flow("left", k) for k in chain])
                )
        say(f"blurred frame {j + 1}/{count}: source frames {first}..{first + window - 1}")
    record = {
        "source": str(getattr(source, "root", "")),
        "window": int(window),
        "stride": int(stride),
        "source_frame_rate": rate,
        "frames": [
            {"index": j, "source_frames": [j * stride, j * stride + window - 1], "centre": c}
            for j, c in enumerate(centres)
        ],
    }
    atomic_write(
        Path(output) / "gt" / "average.json", (json.dumps(record, indent=2) + "\n").encode()
    )
    return Path(output)
