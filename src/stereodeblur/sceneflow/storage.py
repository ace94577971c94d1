"""Scene flow files: one ``.npz`` per frame, and dense outputs in a scene's gt/ layout.

The ``.npz`` file (``stereodeblur-sceneflow/1``)
-----------------------------------------------
A NumPy ``.npz`` archive (zip, compressed) with these arrays:

============  =================  =====================================================
key           dtype, shape       meaning
============  =================  =====================================================
format        str, ()            ``"stereodeblur-sceneflow/1"``
labels        int32, (H, W)      segment of every pixel of the reference view, 0..L-1
normals       float64, (L, 3)    scaled plane normals ``n`` (``P^T n = 1``), left-camera
                                 coordinates at frame t
twists        float64, (L, 6)    rigid motions t -> t + 1, twists ``(v, omega)``
                                 (metres, radians; see :mod:`stereodeblur.geometry.rigid`)
occlusion     uint8, (H, W)      1 where the pixel is occluded, leaves the view or lies
                                 on a motion boundary
view          str, ()            reference view, ``"left"`` or ``"right"``
K             float64, (3, 3)    intrinsics of both rectified views, pixels
baseline      float64, ()        distance between the camera centres, scene units
============  =================  =====================================================

Files are written atomically (a temporary file in the same folder, then renamed).
:func:`load_sceneflow` checks the format string, keys, shapes and values and
raises :class:`~stereodeblur.errors.InputError` naming the file otherwise.

Dense outputs
-------------
:func:`write_sceneflow_outputs` writes, for frame ``i`` (six digits ``NNNNNN``, or the
source's own frame name: KITTI's ``000005_10``)::

    OUT/disparity/left/NNNNNN.pfm    disparity of every pixel from its segment's plane
    OUT/flow/left/NNNNNN.flo         2D projection of the scene flow, t -> t + 1
    OUT/occlusion/left/NNNNNN.png    8-bit mask, 255 where occluded
    OUT/sceneflow/NNNNNN.npz         the file above

(the view folder is the scene flow's reference view).
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS, StereoCamera
from ..io.formats import _atomic_write
from .model import SceneFlow

FORMAT = "stereodeblur-sceneflow/1"
_KEYS = ("format", "labels", "normals", "twists", "occlusion", "view", "K", "baseline")


def _as_sceneflow(value) -> SceneFlow:
    sf = getattr(value, "sceneflow", value)
    if not isinstance(sf, SceneFlow):
        raise InputError(f"expected a SceneFlow or SceneFlowEstimate, got {type(value).__name__}")
    return sf


def save_sceneflow(path: str | os.PathLike, sceneflow) -> Path:
    """Write a scene flow (or an estimate holding one) to ``path`` as ``.npz``, atomically.

    Parameters
    ----------
    path : path
        Target file; its folder is created. A missing ``.npz`` suffix is not added.
    sceneflow : SceneFlow or SceneFlowEstimate

    Returns
    -------
    Path
    """
    sf = _as_sceneflow(sceneflow)
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer,
        format=np.array(FORMAT),
        labels=sf.labels.astype(np.int32),
        normals=sf.normals.astype(np.float64),
        twists=sf.twists.astype(np.float64),
        occlusion=sf.occlusion.astype(np.uint8),
        view=np.array(sf.view),
        K=sf.camera.K.astype(np.float64),
        baseline=np.array(sf.camera.baseline, dtype=np.float64),
    )
    return _atomic_write(path, buffer.getvalue())


def load_sceneflow(path: str | os.PathLike) -> SceneFlow:
    """Read a scene flow file written by :func:`save_sceneflow`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    InputError
        If the file is not a valid ``stereodeblur-sceneflow/1`` archive.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"scene flow file not found: {path}")
    expected = f"expected a {FORMAT} .npz archive"
    try:
        with open(path, "rb") as handle:  # ours, so closed whatever np.load raises
            if handle.read(4) != b"PK\x03\x04":  # every .npz is a zip archive
                raise InputError(f"not a scene flow file: {path} ({expected})")
            handle.seek(0)
            with np.load(handle, allow_pickle=False) as data:
                missing = [k for k in _KEYS if k not in data.files]
                if missing:
                    raise InputError(
                        f"not a scene flow file: {path} (missing {', '.join(missing)})"
                    )
                arrays = {k: data[k] for k in _KEYS}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, MemoryError) as err:
        if isinstance(err, InputError):
            raise
        # numpy's own text may suggest loading pickled objects unsafely: never shown.
        reason = "holds Python objects" if "pickle" in str(err) else type(err).__name__
        raise InputError(f"not a scene flow file: {path} ({reason}; {expected})") from None
    fmt = str(arrays["format"])
    if fmt != FORMAT:
        raise InputError(f"unsupported scene flow format {fmt!r} in {path}, expected {FORMAT!r}")
    view = str(arrays["view"])
    if view not in VIEWS:
        raise InputError(f"bad view {view!r} in {path}, expected 'left' or 'right'")
    try:
        camera = StereoCamera(arrays["K"], float(arrays["baseline"]))
        return SceneFlow(
            camera,
            arrays["labels"],
            arrays["normals"],
            arrays["twists"],
            arrays["occlusion"].astype(bool),
            view,
        )
    except (ValueError, TypeError) as err:
        raise InputError(f"invalid scene flow file {path}: {err}") from None


def write_sceneflow_outputs(
    out_dir: str | os.PathLike, sceneflow, frame_index: int, *, name: str | None = None
) -> dict:
    """Write dense disparity, flow, occlusion and the scene flow file for one frame.

    Parameters
    ----------
    out_dir : path
        Output root (the layout of a scene's gt/ folder, see the module docstring).
    sceneflow : SceneFlow or SceneFlowEstimate
    frame_index : int
        Frame number ``i`` (frame t); files are named ``{i:06d}`` unless ``name`` is given.
    name : str, optional
        The files' name without extension (a source's own frame name, e.g. ``'000005_10'``).

    Returns
    -------
    dict
        Paths written, by kind: ``disparity``, ``flow``, ``occlusion``, ``sceneflow``.
    """
    from ..io.formats import write_flo, write_mask, write_pfm

    sf = _as_sceneflow(sceneflow)
    if int(frame_index) != frame_index or frame_index < 0:
        raise InputError(f"frame_index must be a non-negative integer, got {frame_index!r}")
    if name is None:
        name = f"{int(frame_index):06d}"
    elif not name or "/" in name or name.startswith("."):
        raise InputError(f"name must be a file name without '/', got {name!r}")
    root = Path(out_dir)
    disparity = np.nan_to_num(sf.disparity(), nan=0.0, posinf=0.0, neginf=0.0)
    flow = np.nan_to_num(sf.flow(), nan=0.0, posinf=0.0, neginf=0.0)
    return {
        "disparity": write_pfm(
            root / "disparity" / sf.view / f"{name}.pfm", disparity.astype(np.float32)
        ),
        "flow": write_flo(root / "flow" / sf.view / f"{name}.flo", flow.astype(np.float32)),
        "occlusion": write_mask(root / "occlusion" / sf.view / f"{name}.png", sf.occlusion),
        "sceneflow": save_sceneflow(root / "sceneflow" / f"{name}.npz", sf),
    }
