"""Scene input and output: the stereo video scene format and its file formats."""

from .formats import (
    PngInfo,
    linear_to_srgb,
    read_flo,
    read_mask,
    read_pfm,
    read_png,
    read_png_header,
    srgb_to_linear,
    write_flo,
    write_mask,
    write_pfm,
    write_png,
)
from .protocol import StereoScene
from .readable import check_files, check_readable
from .scene import (
    CameraInfo,
    Scene,
    SceneWriter,
    open_scene,
    read_camera,
    scene_path,
    write_camera,
)

__all__ = [
    "CameraInfo",
    "PngInfo",
    "Scene",
    "SceneWriter",
    "StereoScene",
    "check_files",
    "check_readable",
    "linear_to_srgb",
    "open_scene",
    "read_camera",
    "read_flo",
    "read_mask",
    "read_pfm",
    "read_png",
    "read_png_header",
    "scene_path",
    "srgb_to_linear",
    "write_camera",
    "write_flo",
    "write_mask",
    "write_pfm",
    "write_png",
]
