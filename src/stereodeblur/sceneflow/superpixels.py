"""Superpixel over-segmentation of the reference view and its adjacency graph.

Segments are SLIC superpixels (Achanta et al. 2012) with consecutive int32
labels from 0. Two segments are adjacent when they share a 4-connected pixel
boundary; an edge ``(s, t)`` is stored once with ``s < t``, with the length of
the shared boundary in pixel pairs and three sample points on it (its two ends
along the boundary's main direction and its centroid), in pixel coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .from_gt import default_num_segments

__all__ = [
    "SegmentGraph",
    "default_num_segments",
    "grid_segments",
    "segment_graph",
    "slic_segments",
]

NUM_BOUNDARY_POINTS = 3


def slic_segments(
    image: np.ndarray, num_segments: int, *, compactness: float = 10.0, sigma: float = 1.0
) -> np.ndarray:
    """SLIC superpixels of a float image in [0, 1] as consecutive int32 labels from 0.

    Clustering runs in CIELAB (grey images as grey RGB), so ``compactness`` has
    its usual meaning (10: colour and distance weigh alike over a segment), on
    the image smoothed by a Gaussian of ``sigma`` pixels. If SLIC returns fewer
    than a quarter of the segments asked for (pure noise can collapse into one
    segment), a regular grid of rectangles is used instead.
    """
    from skimage.segmentation import slic

    image = np.asarray(image, dtype=np.float64)
    if not (image.ndim == 3 and image.shape[2] == 3):
        image = np.repeat(image.reshape(image.shape[:2])[..., None], 3, axis=2)
    num_segments = max(1, int(num_segments))
    labels = slic(
        image,
        n_segments=num_segments,
        compactness=compactness,
        sigma=sigma,
        start_label=0,
        channel_axis=-1,
        convert2lab=True,
        enforce_connectivity=True,
        max_num_iter=5,
    )
    if labels.max() + 1 < num_segments / 4:
        labels = grid_segments(image.shape[:2], num_segments)
    _, labels = np.unique(labels, return_inverse=True)
    return labels.reshape(image.shape[:2]).astype(np.int32)


def grid_segments(shape: tuple[int, int], num_segments: int) -> np.ndarray:
    """About ``num_segments`` near-square rectangles covering an image of ``shape``."""
    height, width = shape
    side = max(1.0, np.sqrt(height * width / max(1, num_segments)))
    rows = max(1, int(round(height / side)))
    cols = max(1, int(round(width / side)))
    r = np.minimum(np.arange(height) * rows // height, rows - 1)
    c = np.minimum(np.arange(width) * cols // width, cols - 1)
    return (r[:, None] * cols + c[None, :]).astype(np.int32)


@dataclass(frozen=True)
class SegmentGraph:
    """Segments of the reference view and their adjacency.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
    edges : ndarray of int64, shape (E, 2)
        Adjacent segment pairs ``(s, t)``, ``s < t``.
    boundary_length : ndarray, shape (E,)
        Shared boundary length in 4-connected pixel pairs.
    boundary_points : ndarray, shape (E, NUM_BOUNDARY_POINTS, 2)
        Sample points ``(x, y)`` on each shared boundary.
    order : ndarray of int64, shape (H*W,)
        Flat pixel indices sorted by segment; pixels of segment ``s`` are
        ``order[bounds[s]:bounds[s + 1]]``.
    bounds : ndarray of int64, shape (L + 1,)
    centroids : ndarray, shape (L, 2)
        Mean ``(x, y)`` of each segment.
    """

    labels: np.ndarray
    edges: np.ndarray
    boundary_length: np.ndarray
    boundary_points: np.ndarray
    order: np.ndarray
    bounds: np.ndarray
    centroids: np.ndarray

    @property
    def num_segments(self) -> int:
        return len(self.bounds) - 1

    @property
    def sizes(self) -> np.ndarray:
        return np.diff(self.bounds)

    def neighbours(self) -> list[np.ndarray]:
        """Sorted neighbour segments of every segment."""
        num = self.num_segments
        both = np.concatenate([self.edges, self.edges[:, ::-1]])
        both = both[np.lexsort((both[:, 1], both[:, 0]))]
        starts = np.searchsorted(both[:, 0], np.arange(num + 1))
        return [both[starts[s] : starts[s + 1], 1] for s in range(num)]

    def adjacency(self):
        """Symmetric boolean CSR adjacency matrix (L, L)."""
        import scipy.sparse as sp

        num = self.num_segments
        s, t = self.edges[:, 0], self.edges[:, 1]
        data = np.ones(2 * len(s), dtype=bool)
        return sp.csr_matrix(
            (data, (np.concatenate([s, t]), np.concatenate([t, s]))), shape=(num, num)
        )


def segment_graph(labels: np.ndarray) -> SegmentGraph:
    """Adjacency graph, boundaries and pixel lists of a label map with labels 0..L-1."""
    labels = np.asarray(labels, dtype=np.int32)
    height, width = labels.shape
    num = int(labels.max()) + 1 if labels.size else 0
    flat = labels.ravel()
    order = np.argsort(flat, kind="stable").astype(np.int64)
    bounds = np.searchsorted(flat[order], np.arange(num + 1)).astype(np.int64)
    y, x = np.divmod(np.arange(flat.size), width)
    sizes = np.maximum(np.diff(bounds), 1)
    centroids = np.stack(
        [np.bincount(flat, x, num) / sizes, np.bincount(flat, y, num) / sizes], axis=1
    )

    # 4-connected pixel pairs across segment borders, with their midpoints.
    a_h, b_h = labels[:, :-1], labels[:, 1:]
    yy, xx = np.mgrid[0:height, 0 : width - 1]
    mh = a_h != b_h
    a_v, b_v = labels[:-1, :], labels[1:, :]
    yv, xv = np.mgrid[0 : height - 1, 0:width]
    mv = a_v != b_v
    s = np.concatenate([a_h[mh], a_v[mv]]).astype(np.int64)
    t = np.concatenate([b_h[mh], b_v[mv]]).astype(np.int64)
    px = np.concatenate([xx[mh] + 0.5, xv[mv].astype(np.float64)])
    py = np.concatenate([yy[mh].astype(np.float64), yv[mv] + 0.5])
    lo, hi = np.minimum(s, t), np.maximum(s, t)
    key = lo * max(num, 1) + hi
    keys, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    edges = np.stack([keys // max(num, 1), keys % max(num, 1)], axis=1).astype(np.int64)
    num_edges = len(keys)
    points = np.zeros((num_edges, NUM_BOUNDARY_POINTS, 2))
    if num_edges:
        mx = np.bincount(inverse, px, num_edges) / counts
        my = np.bincount(inverse, py, num_edges) / counts
        # Main direction of each boundary from its 2x2 scatter matrix.
        dx, dy = px - mx[inverse], py - my[inverse]
        sxx = np.bincount(inverse, dx * dx, num_edges)
        sxy = np.bincount(inverse, dx * dy, num_edges)
        syy = np.bincount(inverse, dy * dy, num_edges)
        angle = 0.5 * np.arctan2(2 * sxy, sxx - syy)
        proj = dx * np.cos(angle[inverse]) + dy * np.sin(angle[inverse])
        by_edge = np.lexsort((proj, inverse))
        first = np.searchsorted(inverse[by_edge], np.arange(num_edges))
        last = np.append(first[1:], len(by_edge)) - 1
        points[:, 0] = np.stack([px[by_edge[first]], py[by_edge[first]]], axis=1)
        points[:, 1] = np.stack([mx, my], axis=1)
        points[:, 2] = np.stack([px[by_edge[last]], py[by_edge[last]]], axis=1)
    return SegmentGraph(
        labels=labels,
        edges=edges,
        boundary_length=counts.astype(np.float64),
        boundary_points=points,
        order=order,
        bounds=bounds,
        centroids=centroids,
    )
