"""Piecewise-rigid scene flow: the model, and its estimation from stereo frames.

The estimator and the file functions are imported on first use, so that
``from stereodeblur.sceneflow import SceneFlow`` stays light.
"""

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


def __getattr__(name):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
