"""Check up front that every frame a run will read can be read.

:func:`check_readable` is called before the first frame is processed, so a bad
file stops a run before any work is done (and before anything is written), with
a one-line :class:`~stereodeblur.errors.InputError` naming the first bad file and
what was expected. Nothing is decoded: a PNG's signature, IHDR and chunk layout
are read (:func:`~stereodeblur.io.formats.check_png_file`); a video is opened and
its frame count compared with the frames needed.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from ..errors import InputError
from ..geometry.camera import VIEWS
from .formats import read_flo_header, read_pfm_header
from .kitti import KittiSource
from .png import check_png_file
from .protocol import StereoScene
from .scene import Scene
from .video import VideoSource, video_frame_count


def _png_frames(scene: StereoScene, files: Iterable[Path]) -> None:
    """Every PNG in ``files`` has the scene's size and channels and is complete."""
    height, width = scene.shape
    for path in files:
        header = check_png_file(path)
        if (header.height, header.width, header.channels) != (height, width, scene.channels):
            kind = "grey" if header.channels == 1 else "RGB"
            expected = "grey" if scene.channels == 1 else "RGB"
            raise InputError(
                f"{path} is {header.width}x{header.height} {kind}, expected {width}x{height} "
                f"{expected} like the other frames of {scene.name}"
            )


def _video_frames(scene: VideoSource, views, last: int) -> None:
    for view in views:
        path = scene.files[view]
        count = video_frame_count(path)
        if count <= last:
            raise InputError(
                f"{path} has {count} frames now, expected at least {last + 1} "
                f"(it had {scene.num_frames} when opened)"
            )


def check_readable(
    scene: StereoScene, views: Iterable[str] = VIEWS, indices: Iterable[int] | None = None
) -> None:
    """Check that frames ``indices`` of ``views`` can be read, without decoding them.

    Parameters
    ----------
    scene : StereoScene
        A :class:`~stereodeblur.io.scene.Scene`, KITTI source or video pair.
    views : iterable of str
        ``'left'`` and/or ``'right'``.
    indices : iterable of int, optional
        Frame numbers; all frames when omitted.

    Raises
    ------
    InputError
        Naming the first file that cannot be read and what was expected.
    FileNotFoundError
        When a frame file has disappeared since the scene was opened.
    """
    views = tuple(views)
    for view in views:
        if view not in VIEWS:
            raise InputError(f"view must be 'left' or 'right', got {view!r}")
    indices = sorted(set(range(scene.num_frames) if indices is None else indices))
    for index in indices:
        if isinstance(index, bool) or not 0 <= index < scene.num_frames:
            raise InputError(f"frame index {index!r} is out of range 0..{scene.num_frames - 1}")
    if not indices:
        return
    if isinstance(scene, Scene | KittiSource):
        _png_frames(scene, (scene.frame_path(v, i) for i in indices for v in views))
    elif isinstance(scene, VideoSource):
        _video_frames(scene, views, indices[-1])
    else:
        raise TypeError(f"check_readable: unsupported source {type(scene).__name__}")


def check_files(paths: Iterable, *, size: tuple[int, int] | None = None) -> None:
    """Check ground-truth or other single files up front, by their headers only.

    ``.png`` (:func:`~stereodeblur.io.png.check_png_file`), ``.pfm`` and ``.flo``
    (header and file size) are understood; with ``size = (width, height)`` each
    must also have that size, like the frames it belongs to.

    Raises
    ------
    InputError
        Naming the first bad file and what was expected.
    FileNotFoundError
        When a file is missing.
    """
    for path in map(Path, paths):
        suffix = path.suffix.lower()
        if suffix == ".png":
            header = check_png_file(path)
            found = (header.width, header.height)
        elif suffix == ".pfm":
            found = read_pfm_header(path)[:2]
        elif suffix == ".flo":
            found = read_flo_header(path)
        else:
            raise InputError(f"cannot check {path}: expected a .png, .pfm or .flo file")
        if size is not None and tuple(found) != tuple(size):
            raise InputError(
                f"{path} is {found[0]}x{found[1]}, expected {size[0]}x{size[1]} like the frames"
            )
