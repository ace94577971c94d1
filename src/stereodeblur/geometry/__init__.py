"""Twists and rotations, the stereo camera, planes and homographies."""

from .camera import Exposure, StereoCamera
from .homography import homography, motion_in_view, trajectory_homographies
from .plane import (
    disparity_coefficients,
    move_plane,
    plane_disparity,
    plane_from_disparity_coefficients,
    plane_in_view,
)
from .rigid import RigidMotion, se3_exp, se3_log, so3_exp, so3_log

__all__ = [
    "Exposure",
    "RigidMotion",
    "StereoCamera",
    "disparity_coefficients",
    "homography",
    "motion_in_view",
    "move_plane",
    "plane_disparity",
    "plane_from_disparity_coefficients",
    "plane_in_view",
    "se3_exp",
    "se3_log",
    "so3_exp",
    "so3_log",
    "trajectory_homographies",
]
