"""Piecewise-rigid scene flow: the model, and its estimation from stereo frames.

The estimator and the file functions are imported on first use, so that
``from stereodeblur.sceneflow import SceneFlow`` stays light.
"""

from .._lazy import lazy_exports
from .model import SceneFlow

_LAZY = {
    "SceneFlowEstimate": ".estimate",
    "SceneFlowSettings": ".settings",
    "SceneFlowWarning": ".estimate",
    "estimate_scene_flow": ".estimate",
    "initial_optical_flow": ".initial",
    "initial_disparity": ".initial",
    "save_sceneflow": ".storage",
    "load_sceneflow": ".storage",
    "write_sceneflow_outputs": ".storage",
}

__all__ = ["SceneFlow", *_LAZY]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
