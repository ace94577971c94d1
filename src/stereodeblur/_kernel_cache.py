"""Whether numba's on-disk cache already holds the package's compiled kernels.

The kernels are compiled with ``cache=True``: the first run compiles them (about a minute)
and writes them to numba's cache, an index file ``MODULE.FUNCTION-LINE.pyXY.nbi`` per kernel in
the module's ``__pycache__`` or under ``NUMBA_CACHE_DIR``; later runs load them. A module's
kernels count as cached when its cache folder holds an index file of that module (a cheap
look at one folder, no compilation).
"""

from __future__ import annotations

import importlib
from pathlib import Path

# Modules whose kernels every run of a command compiles, by what the command does.
DEBLUR_MODULES = ("stereodeblur.blur.trajectories", "stereodeblur.deconv.prior")
SCENEFLOW_MODULES = ("stereodeblur.sceneflow.census",)


def _cache_folder(module) -> Path | None:
    """Where numba caches the kernels of ``module`` (None if it has no cached kernel)."""
    for value in vars(module).values():
        cache = getattr(value, "_cache", None)  # a numba dispatcher with cache=True
        folder = getattr(cache, "_cache_path", None)
        if folder is not None:
            return Path(folder)
    return None


def kernels_cached(modules=DEBLUR_MODULES) -> bool:
    """Whether numba's cache holds compiled kernels of every module in ``modules``.

    True when that cannot be told (numba's cache layout changed): say nothing then.
    """
    for name in modules:
        module = importlib.import_module(name)
        folder = _cache_folder(module)
        if folder is None:
            continue
        stem = Path(module.__file__).stem
        try:
            if not any(folder.glob(f"{stem}.*.nbi")):
                return False
        except OSError:
            return False
    return True
