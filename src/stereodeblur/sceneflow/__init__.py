"""Piecewise-rigid scene flow: the model, and its estimation from stereo frames."""

from .model import SceneFlow

__all__ = ["SceneFlow"]
