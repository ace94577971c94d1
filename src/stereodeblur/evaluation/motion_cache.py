"""Frame 1's motion (left view) for the benchmarks, computed once and stored.

:func:`cached_motion` stores the estimated scene flow and the initial optical flow of a scene
in a cache folder and reads them back on later runs (``bench paper``,
``benchmarks/calibrate_defaults.py``), so that every column of a scene, in every run, uses
one motion. Each stored motion has its :func:`motion_signature` beside it; a motion stored
without one, or with other estimator settings, is estimated again. A result cached from a
motion names it by :func:`motion_digest`.
"""

from __future__ import annotations

import functools
import hashlib
import io
import time
import warnings
from pathlib import Path

import numpy as np

from .paper_columns import FRAME


def quiet(function, *args, **kwargs):
    """Call ``function``, returning ``(result, warning messages)`` instead of warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = function(*args, **kwargs)
    return result, tuple(dict.fromkeys(str(w.message) for w in caught))


MOTION_CACHE_VERSION = 2
"""Version of the stored motions, part of their :func:`motion_signature`: raise it whenever
what is stored or signed changes."""
ESTIMATOR_SOURCES = ("sceneflow", "geometry", "pipeline/motion.py", "deconv/trust.py")
"""The package's modules a stored motion is computed by (folders: every ``.py`` in them)."""
ESTIMATOR_LIBRARIES = ("numpy", "scipy", "cv2", "skimage", "numba", "maxflow")
"""The libraries whose versions a stored motion depends on."""
STORED_SOURCES = ("sceneflow", "initial-flow")
"""The motion sources :func:`cached_motion` stores (the true motion is cheap to recompute)."""


@functools.cache
def estimator_fingerprint() -> str:
    """Hash of the source of :data:`ESTIMATOR_SOURCES` and the versions of
    :data:`ESTIMATOR_LIBRARIES`: a motion stored by other code or libraries is estimated again
    (other library versions can give another scene flow from the same frames and settings)."""
    import importlib

    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for name in ESTIMATOR_SOURCES:
        path = package / name
        for file in sorted(path.rglob("*.py")) if path.is_dir() else [path]:
            digest.update(file.relative_to(package).as_posix().encode())
            digest.update(file.read_bytes())
    for name in ESTIMATOR_LIBRARIES:
        digest.update(f"{name} {importlib.import_module(name).__version__}".encode())
    return digest.hexdigest()[:16]


def motion_signature(source: str, settings) -> str:
    """What a stored motion of ``source`` depends on: the estimator's code and libraries
    (:func:`estimator_fingerprint`) and, for the scene flow, its settings and seed (the
    initial optical flow has no settings)."""
    signature = f"{source} v{MOTION_CACHE_VERSION} {estimator_fingerprint()}"
    if source == "sceneflow":
        signature += f" {settings.estimator!r} seed={settings.seed}"
    return signature


def cached_motion(scene, source: str, settings, cache: Path):
    """The :class:`~stereodeblur.pipeline.FrameMotion` of frame 1 (left) from ``source``,
    a scene flow with its dense flows but its boundaries as estimated (``relabel_radius``
    0: :func:`~stereodeblur.evaluation.paper_bench.deblur_with_motion` moves them).

    Scene flow and initial flow are stored under ``cache`` and read back on later runs if
    they were made with the same :func:`motion_signature`; gt motion is recomputed (it is
    cheap). Returns ``(motion, seconds, warnings)``.
    """
    from dataclasses import replace

    from ..io.outputs import atomic_write, atomic_write_text
    from ..pipeline import FrameMotion, dense_flow, frame_motion, neighbour_of
    from ..sceneflow.storage import load_sceneflow, save_sceneflow

    kernels = "displacement" if source == "initial-flow" else settings.kernels
    # The estimate as it is, its boundaries not moved (the deblurring moves them).
    settings = replace(settings, motion_source=source, kernels=kernels, relabel_radius=0)
    neighbour = neighbour_of(FRAME, scene.num_frames)
    path = cache / f"{source}.npz"
    stored = is_stored(cache, source, settings)
    if source == "sceneflow" and stored:
        sf = load_sceneflow(path)
        dense = dense_flow(scene, FRAME, "left", scene.read_frame("left", FRAME))
        motion = FrameMotion(FRAME, neighbour, "left", sf, sf.flow(), sf.reversed().flow(), dense)
        return motion, 0.0, ()
    if source == "initial-flow" and stored:
        with np.load(path) as data:
            backward = data["backward"] if data["backward"].size else None
            motion = FrameMotion(FRAME, neighbour, "left", None, data["forward"], backward)
        return motion, 0.0, ()
    start = time.perf_counter()
    blurred = scene.read_frame("left", FRAME)
    motion, messages = quiet(frame_motion, scene, FRAME, "left", settings, blurred)
    seconds = time.perf_counter() - start
    cache.mkdir(parents=True, exist_ok=True)
    if source == "sceneflow":
        save_sceneflow(path, motion.sceneflow)
    elif source == "initial-flow":
        backward = np.zeros(0) if motion.flow_backward is None else motion.flow_backward
        buffer = io.BytesIO()
        np.savez_compressed(buffer, forward=motion.flow_forward, backward=backward)
        atomic_write(path, buffer.getvalue())
    if source in STORED_SOURCES:
        atomic_write_text(cache / f"{source}.signature", motion_signature(source, settings))
    return motion, seconds, messages


def motion_digest(motion) -> str:
    """Hash of what a deblurring takes from ``motion`` (a
    :class:`~stereodeblur.pipeline.FrameMotion`): its scene flow's segments, planes, motions and
    occlusion (not the dense flows beside it, which the frames determine), else its flows. A
    result cached with one motion is not reused with another (a motion estimated again by other
    code must not meet the results of the old one)."""
    digest = hashlib.sha256()
    sf = motion.sceneflow
    if sf is not None:
        arrays = (
            sf.labels.astype(np.int32),
            sf.normals.astype(np.float64),
            sf.twists.astype(np.float64),
            sf.occlusion.astype(np.uint8),
        )
    else:
        flows = (motion.flow_forward, motion.flow_backward)
        arrays = tuple(np.asarray(f, np.float32) for f in flows if f is not None)
    for array in arrays:
        digest.update(str(array.shape).encode())
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()[:16]


def is_stored(cache: Path, source: str, settings) -> bool:
    """Whether ``cache`` holds a motion of ``source`` made with ``settings``
    (:func:`motion_signature`), which :func:`cached_motion` reads back."""
    return (
        source in STORED_SOURCES
        and (cache / f"{source}.npz").is_file()
        and _has_text(cache / f"{source}.signature", motion_signature(source, settings))
    )


def _has_text(path: Path, text: str) -> bool:
    """Whether the file ``path`` holds exactly ``text`` (False if it cannot be read)."""
    try:
        return path.read_text(encoding="utf-8") == text
    except OSError:
        return False
