"""The order of the gallery's examples: from what the tool does to the pieces it is made of.

Sphinx-gallery imports the sort key by name (``within_subsection_order`` in ``conf.py``), so it
lives in a module of its own, and its configuration value stays a string that pickles.
"""

from __future__ import annotations

import os

ORDER = (
    "plot_deblur_scene.py",
    "plot_scene_flow.py",
    "plot_blur_kernels.py",
    "plot_point_cloud.py",
)


class GalleryOrder:
    """Sort key of the examples of one gallery folder: their place in :data:`ORDER`."""

    def __init__(self, src_dir: str) -> None:
        self.src_dir = src_dir

    def __repr__(self) -> str:
        return f"GalleryOrder({ORDER})"

    def __call__(self, filename: str) -> tuple[int, str]:
        name = os.path.basename(filename)
        return (ORDER.index(name) if name in ORDER else len(ORDER), name)
