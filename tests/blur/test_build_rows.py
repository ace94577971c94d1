"""Operators built for some rows only: equal to the full operators' rows, exactly."""

import numpy as np
import pytest

from stereodeblur.blur import _kernels
from stereodeblur.blur.displacement import displacement_blur
from stereodeblur.blur.homography import homography_blur
from stereodeblur.blur.operator import merge_rows
from stereodeblur.blur.visibility import sceneflow_visibility
from stereodeblur.errors import InputError

from .scenes import EXPOSURE, random_sceneflow, smooth_flow

SHAPE = (40, 56)


def _mask(seed: int) -> np.ndarray:
    """A band of rows and a scatter of single pixels."""
    rng = np.random.default_rng(seed)
    mask = rng.random(SHAPE) < 0.1
    mask[12:20, 5:40] = True
    return mask


def _flows(seed: int = 2):
    forward = smooth_flow(SHAPE, seed, amplitude=8.0)
    return forward, smooth_flow(SHAPE, seed + 100, amplitude=8.0)


def _assert_same(a, b):
    np.testing.assert_array_equal(a.indptr, b.indptr)
    np.testing.assert_array_equal(a.indices, b.indices)
    np.testing.assert_array_equal(a.data, b.data)
    assert a.indices.dtype == b.indices.dtype and a.data.dtype == b.data.dtype


@pytest.mark.parametrize("chunked", [False, True])
def test_displacement_rows_equal_the_full_operators(chunked, monkeypatch):
    if chunked:
        monkeypatch.setattr(_kernels, "_MIN_CHUNK", 16)
    mask = _mask(0)
    full = displacement_blur(*_flows(), EXPOSURE).matrix.tocsr()
    part = displacement_blur(*_flows(), EXPOSURE, rows=mask).matrix
    counts = np.diff(part.indptr)
    assert np.all(counts[~mask.ravel()] == 0)
    _assert_same(part[np.flatnonzero(mask)], full[np.flatnonzero(mask)])


def test_displacement_rows_skip_far_sources():
    """A mask in one corner: the splats of sources that cannot reach it are not built."""
    forward, backward = _flows()
    mask = np.zeros(SHAPE, bool)
    mask[:3, :3] = True
    full = displacement_blur(forward, backward, EXPOSURE).matrix
    part = displacement_blur(forward, backward, EXPOSURE, rows=mask).matrix
    _assert_same(part[np.flatnonzero(mask)], full[np.flatnonzero(mask)])
    assert part.nnz == full[np.flatnonzero(mask)].nnz


@pytest.mark.parametrize("layered", [False, True])
@pytest.mark.parametrize("view", ["left", "right"])
def test_homography_substitute_equals_merge_rows(view, layered):
    scene = random_sceneflow(SHAPE, 1, view=view)
    visible = sceneflow_visibility(scene, EXPOSURE, 70) if layered else None
    mask = _mask(1)
    other = displacement_blur(*_flows(), EXPOSURE, rows=mask)
    merged = merge_rows(homography_blur(scene, EXPOSURE, visible=visible), other, mask)
    built = homography_blur(scene, EXPOSURE, visible=visible, substitute=(other, mask))
    _assert_same(built.matrix, merged.matrix)


def test_homography_substitute_with_long_rows(monkeypatch):
    """Substituted rows longer than the room kept for computed ones make the output grow."""
    monkeypatch.setattr(_kernels, "_MIN_CHUNK", 16)
    scene = random_sceneflow(SHAPE, 3)
    other = displacement_blur(*(3.0 * f for f in _flows(4)), EXPOSURE)
    mask = np.ones(SHAPE, bool)
    mask[0, :4] = False
    counts = np.diff(other.matrix.indptr)
    # More entries than the room first kept for a chunk's output (16 per row).
    assert max(counts[a:b].sum() - 16 * (b - a) for a, b in _kernels._chunks(counts.size)) > 0
    merged = merge_rows(homography_blur(scene, EXPOSURE), other, mask)
    _assert_same(homography_blur(scene, EXPOSURE, substitute=(other, mask)).matrix, merged.matrix)


def test_bad_rows_and_substitutes_are_refused():
    forward, backward = _flows()
    with pytest.raises(InputError, match="rows"):
        displacement_blur(forward, backward, EXPOSURE, rows=np.ones((3, 3), bool))
    scene = random_sceneflow(SHAPE, 1)
    other = displacement_blur(forward, backward, EXPOSURE)
    with pytest.raises(ValueError, match="mask"):
        homography_blur(scene, EXPOSURE, substitute=(other, np.ones(SHAPE, np.uint8)))
    with pytest.raises(ValueError, match="SparseBlur"):
        homography_blur(scene, EXPOSURE, substitute=(other.matrix, np.ones(SHAPE, bool)))
