"""Properties every blur operator must have, over one registry of all operators."""

import numpy as np
import pytest
import scipy.sparse as sp

from stereodeblur.blur.displacement import displacement_blur
from stereodeblur.blur.homography import homography_blur
from stereodeblur.blur.operator import dot_test
from stereodeblur.blur.visibility import sceneflow_visibility
from stereodeblur.geometry import Exposure

from .scenes import EXPOSURE, random_sceneflow, smooth_flow

SHAPE = (40, 56)


def _homography(view, exposure=EXPOSURE, speed=1.0, seed=1, layered=False):
    scene = random_sceneflow(SHAPE, seed, view=view, speed=speed)
    visible = sceneflow_visibility(scene, exposure, 70) if layered else None
    return homography_blur(scene, exposure, visible=visible, interpolation="bilinear")


def _displacement(backward, exposure=EXPOSURE, speed=1.0, seed=2):
    forward = speed * smooth_flow(SHAPE, seed, amplitude=8.0)
    back = (
        -forward
        if backward == "mirrored"
        else speed * smooth_flow(SHAPE, seed + 100, amplitude=8.0)
    )
    return displacement_blur(forward, back, exposure, interpolation="bilinear")


REGISTRY = {
    "homography-left": lambda **kw: _homography("left", **kw),
    "homography-right": lambda **kw: _homography("right", **kw),
    "homography-layered": lambda **kw: _homography("left", layered=True, **kw),
    "displacement-mirrored": lambda **kw: _displacement("mirrored", **kw),
    "displacement-independent": lambda **kw: _displacement("independent", **kw),
}


@pytest.fixture(scope="module", params=sorted(REGISTRY))
def registered(request):
    return request.param, REGISTRY[request.param]()


@pytest.mark.parametrize("channels", [None, 3])
def test_dot_test(registered, channels):
    _, op = registered
    shape = SHAPE if channels is None else SHAPE + (channels,)
    for seed in range(3):
        assert dot_test(op, shape, seed=seed) < 1e-5


def test_rows_sum_to_one(registered):
    _, op = registered
    np.testing.assert_allclose(np.asarray(op.matrix.sum(axis=1)).ravel(), 1.0, atol=1e-5)
    assert op.matrix.data.min() > 0


def test_operator_really_blurs(registered):
    """Guards the other tests against a registry of near-identities."""
    _, op = registered
    off_diagonal = op.matrix - sp.diags(op.matrix.diagonal())
    assert np.median(np.asarray(off_diagonal.sum(axis=1)).ravel()) > 0.4


def test_matrix_layout(registered):
    _, op = registered
    m = op.matrix
    assert m.shape == (SHAPE[0] * SHAPE[1],) * 2
    assert m.indices.dtype == np.int32 and m.data.dtype == np.float32
    assert m.has_canonical_format
    copy = m.copy()
    copy.sort_indices()
    copy.sum_duplicates()
    np.testing.assert_array_equal(copy.indices, m.indices)


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_zero_motion_is_exactly_identity(name):
    op = REGISTRY[name](speed=0.0)
    n = SHAPE[0] * SHAPE[1]
    np.testing.assert_array_equal(op.matrix.indptr, np.arange(n + 1))
    np.testing.assert_array_equal(op.matrix.indices, np.arange(n))
    np.testing.assert_array_equal(op.matrix.data, np.ones(n, np.float32))


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_zero_exposure_is_exactly_identity(name):
    op = REGISTRY[name](exposure=Exposure(frame_rate=25.0, exposure=0.0))
    n = SHAPE[0] * SHAPE[1]
    np.testing.assert_array_equal(op.matrix.indices, np.arange(n))
    np.testing.assert_array_equal(op.matrix.data, np.ones(n, np.float32))


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_threaded_chunks_give_the_same_operator(name, monkeypatch):
    """Small images run in one chunk; force many chunks and compare."""
    from stereodeblur.blur import _kernels

    serial = REGISTRY[name]()
    monkeypatch.setattr(_kernels, "_MIN_CHUNK", 16)
    assert len(_kernels._chunks(SHAPE[0] * SHAPE[1])) > 1
    chunked = REGISTRY[name]()
    for a, b in [(serial.matrix, chunked.matrix), (serial._transposed(), chunked._transposed())]:
        np.testing.assert_array_equal(a.indptr, b.indptr)
        np.testing.assert_array_equal(a.indices, b.indices)
        np.testing.assert_array_equal(a.data, b.data)
    image = np.random.default_rng(0).random(SHAPE + (3,), dtype=np.float32)
    np.testing.assert_allclose(chunked.forward(image), serial.forward(image), rtol=1e-6)
    np.testing.assert_allclose(chunked.adjoint(image), serial.adjoint(image), rtol=1e-6)
    monkeypatch.undo()
    np.testing.assert_allclose(chunked.forward(image), serial.forward(image), rtol=1e-6)


@pytest.mark.parametrize("channels", [None, 3])
def test_gram_is_adjoint_of_weighted_forward(registered, channels):
    """``gram(x, w^2) = A^T (w^2 A x)`` (float32 tiles) and in float64 (CSR); symmetric."""
    _, op = registered
    rng = np.random.default_rng(7)
    shape = SHAPE if channels is None else SHAPE + (channels,)
    image = rng.standard_normal(shape).astype(np.float32)
    squared = rng.uniform(0, 1, SHAPE).astype(np.float32)
    weighted = op.forward(image) * (squared if channels is None else squared[..., None])
    expected = op.adjoint(weighted)
    gram = op.gram(image, squared)
    assert gram.dtype == np.float32
    np.testing.assert_allclose(gram, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())
    np.testing.assert_allclose(op.gram(image), op.adjoint(op.forward(image)), rtol=1e-5, atol=1e-5)
    exact = op.gram(image.astype(np.float64), squared)
    assert exact.dtype == np.float64
    np.testing.assert_allclose(gram, exact, rtol=1e-5, atol=1e-5 * np.abs(exact).max())
    other = rng.standard_normal(shape).astype(np.float32)  # symmetric: a dot test of its own
    lhs = float(np.vdot(op.gram(image, squared).astype(np.float64), other))
    rhs = float(np.vdot(image.astype(np.float64), op.gram(other, squared)))
    assert abs(lhs - rhs) <= 1e-5 * max(abs(lhs), abs(rhs))
