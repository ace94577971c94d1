"""Conjugate gradients on images, every colour channel an independent system.

Conventions
-----------
The operator is a callable mapping an array of image shape, ``(H, W)`` or ``(H, W, C)``,
to an array of the same shape; it must be symmetric positive (semi)definite on each
channel and must treat the channels independently (the same matrix on every channel),
as the normal operators of :mod:`stereodeblur.deconv.irls` do. Each channel gets its own
step sizes, so solving ``C`` channels at once equals ``C`` separate solves. Vectors are
float32 (float64 if the right-hand side is float64); inner products are accumulated in
float64, row by row and then summed in a fixed order, so results do not depend on the
number of threads.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numba
import numpy as np
from numba import uint64 as U

from stereodeblur._threads import run_ranges
from stereodeblur.errors import InputError


@dataclass(frozen=True, eq=False)
class CGResult:
    """Outcome of :func:`conjugate_gradient`.

    Attributes
    ----------
    solution : ndarray
        The last iterate, shape and dtype of the working arrays (the right-hand side's shape).
    residual_norms : ndarray, shape (num_iterations + 1, C)
        Euclidean norm of the (recursively updated) residual ``b - M x`` per channel, before
        the first step and after every step; ``C = 1`` for ``(H, W)`` images.
    num_iterations : int
        Steps taken (fewer than requested when every channel met ``rtol``).
    """

    solution: np.ndarray
    residual_norms: np.ndarray
    num_iterations: int


# The kernels index with unsigned integers (``U``) and ``error_model="numpy"`` so that LLVM can
# drop negative-index wraparound checks and vectorise their inner loops. Keep index arithmetic
# unsigned throughout: numba types ``uint64 + int64`` as float64.
_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# Partial sums per channel for an inner product: entry ``k`` of a flat row goes to lane
# ``k % (LANES * C)``, which belongs to channel ``k % C``; the lanes are then added in order.
LANES = 16


@numba.njit(**_JIT)
def lane_dots(a, b, acc):  # pragma: no cover - compiled
    """``acc[k % L] += a[k] b[k]`` in float64 over flat rows ``a``, ``b`` (``L = acc.size``).

    A fixed order of additions, independent of the thread count, that vectorises.
    """
    lanes = U(acc.size)
    size = U(a.size)
    blocks = size // lanes
    for block in range(blocks):
        base = block * lanes
        for lane in range(lanes):
            acc[lane] += np.float64(a[base + lane]) * np.float64(b[base + lane])
    base = blocks * lanes
    for lane in range(size - base):
        acc[lane] += np.float64(a[base + lane]) * np.float64(b[base + lane])


@numba.njit(**_JIT)
def fold_lanes(acc, channels, partial, row):  # pragma: no cover - compiled
    """``partial[row, c]`` = the sum of the lanes of channel ``c``, in order; clears ``acc``."""
    for c in range(channels):
        total = 0.0
        for lane in range(c, acc.size, channels):
            total += acc[lane]
        partial[row, c] = total
    acc[:] = 0.0


@numba.njit(**_JIT)
def lane_sum(values):  # pragma: no cover - compiled
    """Sum of a float64 vector in :data:`LANES` partial sums, a fixed order that vectorises."""
    acc = np.zeros(LANES)
    lanes = U(LANES)
    blocks = U(values.size) // lanes
    for block in range(blocks):
        base = block * lanes
        for lane in range(lanes):
            acc[lane] += values[base + lane]
    for k in range(blocks * lanes, U(values.size)):
        acc[k - blocks * lanes] += values[k]
    total = 0.0
    for lane in range(LANES):
        total += acc[lane]
    return total


@numba.njit(**_JIT)
def row_channel_dots(a, b, channels, partial, row):  # pragma: no cover - compiled
    """``partial[row, c] = sum_k a[k] b[k]`` over the entries of channel ``c`` of a flat row."""
    acc = np.zeros(LANES * channels)
    lane_dots(a, b, acc)
    fold_lanes(acc, channels, partial, row)


@numba.njit(**_JIT)
def _channel_dots_rows(first, last, a, b, partial):  # pragma: no cover - compiled
    """``partial[i, c] = sum_j a[i, j, c] * b[i, j, c]`` for rows ``first .. last - 1``."""
    rows, cols, channels = a.shape
    a2 = a.reshape(rows, cols * channels)
    b2 = b.reshape(rows, cols * channels)
    acc = np.zeros(LANES * channels)
    for i in range(first, last):
        lane_dots(a2[i], b2[i], acc)
        fold_lanes(acc, channels, partial, i)


@numba.njit(**_JIT)
def _residual_rows(first, last, r, q, step, partial):  # pragma: no cover - compiled
    """``r -= step q`` (``step`` repeated along a row); the row sums of ``r . r`` per channel.

    The squares go straight into the lanes of :func:`lane_dots` (same order of additions).
    """
    rows = r.shape[0]
    channels = r.shape[2]
    size = U(step.size)
    r2 = r.reshape(rows, step.size)
    q2 = q.reshape(rows, step.size)
    lanes = U(LANES * channels)
    blocks = size // lanes
    acc = np.zeros(LANES * channels)
    for i in range(first, last):
        r_row = r2[i]
        q_row = q2[i]
        for block in range(blocks):
            base = block * lanes
            for lane in range(lanes):
                k = base + lane
                value = r_row[k] - step[k] * q_row[k]
                r_row[k] = value
                acc[lane] += np.float64(value) * np.float64(value)
        base = blocks * lanes
        for lane in range(size - base):
            k = base + lane
            value = r_row[k] - step[k] * q_row[k]
            r_row[k] = value
            acc[lane] += np.float64(value) * np.float64(value)
        fold_lanes(acc, channels, partial, i)


@numba.njit(**_JIT)
def _direction_rows(first, last, x, p, r, step, beta):  # pragma: no cover - compiled
    """``x += step p``, then ``p = r + beta p`` (``step``, ``beta`` repeated along a row)."""
    rows = p.shape[0]
    size = U(step.size)
    x2 = x.reshape(rows, step.size)
    p2 = p.reshape(rows, step.size)
    r2 = r.reshape(rows, step.size)
    for i in range(first, last):
        x_row = x2[i]
        p_row = p2[i]
        r_row = r2[i]
        for k in range(size):
            old = p_row[k]
            x_row[k] += step[k] * old
            p_row[k] = r_row[k] + beta[k] * old


def by_rows(kernel, array: np.ndarray, *args) -> None:
    """``kernel(first, last, *args)`` over ranges of the rows of ``array``, in parallel.

    The kernels release the GIL and run on the package's worker threads (several ranges
    per thread), whose idle threads block instead of spinning: unlike an OpenMP
    ``prange`` this keeps its speed on a machine busy with other work. Ranges never
    change what a row computes, so results do not depend on the number of threads.
    """
    parts = 2 * numba.get_num_threads() if array.size >= PARALLEL_MIN_SIZE else 1
    ranges = _row_ranges(array.shape[0], parts)
    run_ranges(kernel, ranges, *args)


@functools.lru_cache(maxsize=64)
def _row_ranges(rows: int, parts: int) -> tuple[tuple[int, int], ...]:
    """At most ``parts`` non-empty contiguous ranges of about equal length covering ``rows``."""
    bounds = np.linspace(0, rows, min(parts, rows) + 1).astype(np.int64)
    return tuple((int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a)


def _channel_dots(a, b, partial) -> None:
    by_rows(_channel_dots_rows, a, a, b, partial)


def _update_residual(r, q, step, partial) -> None:
    by_rows(_residual_rows, r, r, q, step, partial)


def _update_iterate(x, p, r, step, beta) -> None:
    by_rows(_direction_rows, p, x, p, r, step, beta)


# Below this many values per vector the kernels run on the calling thread only: waking the
# other threads costs more than it saves on small images.
PARALLEL_MIN_SIZE = 1 << 16


@contextmanager
def threads_for(size: int) -> Iterator[None]:
    """Run numba parallel regions in the block on one thread when ``size`` is small."""
    if size >= PARALLEL_MIN_SIZE:
        yield
        return
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def _as_3d(array: np.ndarray) -> np.ndarray:
    """View an ``(H, W)`` array as ``(H, W, 1)``; ``(H, W, C)`` unchanged."""
    return array[..., None] if array.ndim == 2 else array


def conjugate_gradient(
    operator: Callable[[np.ndarray], np.ndarray],
    rhs: np.ndarray,
    *,
    initial: np.ndarray | None = None,
    num_iterations: int = 25,
    rtol: float | None = None,
) -> CGResult:
    """Solve ``M x = b`` per channel by conjugate gradients.

    Parameters
    ----------
    operator : callable
        ``M``: maps an array shaped like ``rhs`` to one of the same shape; symmetric positive
        (semi)definite and the same on every channel. Its result may be modified in place
        unless it shares memory with the argument.
    rhs : ndarray, shape (H, W) or (H, W, C)
        ``b``.
    initial : ndarray, optional
        Starting point ``x0`` (zeros by default); not modified.
    num_iterations : int
        Number of steps (the paper uses 25 per IRLS iteration).
    rtol : float, optional
        A channel stops once its residual norm is ``<= rtol * ||b||``; iteration ends early
        when all channels have stopped. Without it exactly ``num_iterations`` steps are taken
        (a channel whose curvature ``p^T M p`` is not positive stops regardless).

    Returns
    -------
    CGResult
    """
    rhs = np.asarray(rhs)
    if rhs.ndim not in (2, 3) or rhs.size == 0:
        raise InputError(f"rhs must have shape (H, W) or (H, W, C), got {rhs.shape}")
    if int(num_iterations) != num_iterations or num_iterations < 0:
        raise InputError(f"num_iterations must be a non-negative integer, got {num_iterations!r}")
    if rtol is not None and not (np.isfinite(rtol) and rtol >= 0):
        raise InputError(f"rtol must be a non-negative number or None, got {rtol!r}")
    dtype = np.float64 if rhs.dtype == np.float64 else np.float32
    shape = rhs.shape
    b = _as_3d(np.ascontiguousarray(rhs, dtype=dtype))

    def apply(vector3d: np.ndarray, partial: np.ndarray) -> np.ndarray:
        result = np.asarray(operator(vector3d.reshape(shape)))
        if result.shape != shape:
            raise InputError(f"operator returned shape {result.shape}, expected {shape}")
        if result.dtype != dtype or not result.flags.c_contiguous:
            result = np.ascontiguousarray(result, dtype=dtype)
        result = _as_3d(result)
        _channel_dots(vector3d, result, partial)
        return result

    if initial is None:
        x = None
    else:
        initial = np.asarray(initial)
        if initial.shape != shape:
            raise InputError(f"initial has shape {initial.shape}, expected {shape}")
        x = _as_3d(np.array(initial, dtype=dtype, order="C"))
    with threads_for(b.size):
        x, norms, taken = solve(apply, b, x, num_iterations=int(num_iterations), rtol=rtol)
    return CGResult(solution=x.reshape(shape), residual_norms=norms, num_iterations=taken)


def solve(apply, b, x, *, num_iterations: int, rtol: float | None, residual=None):
    """The CG iteration on validated ``(H, W, C)`` C-contiguous arrays.

    ``apply(p, partial)`` returns ``M p`` (an array it owns, ``(H, W, C)``, C-contiguous, of
    ``b``'s dtype) and writes the row sums of ``p * (M p)`` per channel into ``partial``
    (``(H, C)`` float64), so that callers can fuse that product into the operator. ``x`` is
    the starting point, updated in place (zeros if None). ``residual``, if given, is
    ``b - M x`` computed by the caller (then owned and overwritten by the solver). Returns
    ``(x, residual_norms, steps)``.
    """
    rows, channels = b.shape[0], b.shape[2]
    partial = np.empty((rows, channels), dtype=np.float64)
    if x is None:
        x = np.zeros_like(b)
        r = b.copy()
    elif residual is not None:
        r = residual
    else:
        r = b - apply(x, partial)
    target = None
    if rtol is not None:
        _channel_dots(b, b, partial)
        target = rtol * np.sqrt(partial.sum(axis=0))
    _channel_dots(r, r, partial)
    rr = partial.sum(axis=0)
    norms = [np.sqrt(rr)]
    active = np.ones(channels, dtype=bool) if target is None else norms[0] > target
    p = r.copy()
    # Per-channel scalars repeated along a row, for contiguous inner loops.
    step = np.zeros(b.shape[1] * channels, dtype=b.dtype)
    beta = np.zeros_like(step)
    step_rows = step.reshape(b.shape[1], channels)
    beta_rows = beta.reshape(b.shape[1], channels)
    taken = 0
    for _ in range(num_iterations):
        active &= rr > 0
        if not active.any():
            break
        q = apply(p, partial)
        curvature = partial.sum(axis=0)
        active &= curvature > 0
        step_rows[:] = np.where(active, rr / np.where(active, curvature, 1.0), 0.0)
        _update_residual(r, q, step, partial)
        rr_new = np.where(active, partial.sum(axis=0), rr)
        taken += 1
        norms.append(np.sqrt(rr_new))
        beta_rows[:] = np.where(active, rr_new / np.where(rr > 0, rr, 1.0), 0.0)
        rr = rr_new
        if target is not None:
            active &= np.sqrt(rr) > target
        _update_iterate(x, p, r, step, beta)  # x += step p and the next direction, one pass
    return x, np.array(norms), taken
