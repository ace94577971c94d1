"""A scene read backwards in time, for the last frame of a clip with ground-truth motion.

Temporary: once :mod:`stereodeblur.pipeline` deblurs the last frame itself (towards the previous
frame), this module goes away.
"""

from __future__ import annotations

import numpy as np


class TimeReversed:
    """A scene read backwards in time: frame j is frame ``n - 1 - j``, flows inverted.

    Lets the last frame be deblurred from ground truth towards the previous frame.
    """

    def __init__(self, scene):
        self.scene = scene
        self.info = scene.info
        self.num_frames = scene.num_frames
        self.shape = scene.shape
        self.root = getattr(scene, "root", None)

    def _j(self, index: int) -> int:
        return self.num_frames - 1 - index

    def read_frame(self, view, index, *, linear=True):
        return self.scene.read_frame(view, self._j(index), linear=linear)

    def has_gt(self, kind, view, index):
        j = self._j(index) - (kind == "flow")
        return j >= 0 and self.scene.has_gt(kind, view, j)

    def gt_path(self, kind, view, index):
        return self.scene.gt_path(kind, view, max(self._j(index) - (kind == "flow"), 0))

    def read_gt_disparity(self, view, index):
        return self.scene.read_gt_disparity(view, self._j(index))

    def read_gt_mixed(self, view, index):
        return self.scene.read_gt_mixed(view, self._j(index))

    def read_gt_sharp(self, view, index, *, linear=True):
        return self.scene.read_gt_sharp(view, self._j(index), linear=linear)

    def read_gt_flow(self, view, index):
        from ..pipeline import invert_flow

        flow = self.scene.read_gt_flow(view, self._j(index) - 1)
        unknown = ~np.all(np.isfinite(flow), axis=2)
        inverse = invert_flow(np.where(unknown[..., None], 0.0, flow).astype(np.float32))
        if unknown.any():  # unknown where the inverse lands on an unknown pixel
            H, W = unknown.shape
            y, x = np.mgrid[0:H, 0:W]
            ys = np.clip(np.rint(y + inverse[..., 1]), 0, H - 1).astype(int)
            xs = np.clip(np.rint(x + inverse[..., 0]), 0, W - 1).astype(int)
            inverse[unknown[ys, xs]] = np.nan
        return inverse
