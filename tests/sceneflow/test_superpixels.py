import numpy as np

from stereodeblur.sceneflow.superpixels import segment_graph, slic_segments


def test_graph_of_a_hand_made_label_map():
    labels = np.array(
        [
            [0, 0, 1, 1],
            [0, 0, 1, 1],
            [2, 2, 2, 1],
        ],
        dtype=np.int32,
    )
    g = segment_graph(labels)
    assert g.num_segments == 3
    edges = {tuple(e) for e in g.edges.tolist()}
    assert edges == {(0, 1), (0, 2), (1, 2)}
    length = dict(zip(map(tuple, g.edges.tolist()), g.boundary_length, strict=True))
    assert length[(0, 1)] == 2  # two horizontal pixel pairs
    assert length[(0, 2)] == 2
    assert length[(1, 2)] == 2  # (1,2)-(2,2) vertically and (2,2)-(2,3) horizontally
    np.testing.assert_array_equal(g.sizes, [4, 5, 3])
    for s in range(3):
        pixels = g.order[g.bounds[s] : g.bounds[s + 1]]
        assert np.all(labels.ravel()[pixels] == s)
    np.testing.assert_allclose(g.centroids[0], [0.5, 0.5])
    # Boundary points of (0, 1) lie on the line x = 1.5 between rows 0 and 1.
    pts = g.boundary_points[list(map(tuple, g.edges.tolist())).index((0, 1))]
    np.testing.assert_allclose(pts[:, 0], 1.5)
    assert set(pts[[0, 2], 1]) == {0.0, 1.0}
    assert [n.tolist() for n in g.neighbours()] == [[1, 2], [0, 2], [0, 1]]


def test_slic_gives_consecutive_connected_labels_near_the_requested_count():
    rng = np.random.default_rng(0)
    image = rng.random((60, 80)).astype(np.float32)
    labels = slic_segments(image, 48)
    assert labels.dtype == np.int32
    assert labels.min() == 0
    num = labels.max() + 1
    np.testing.assert_array_equal(np.unique(labels), np.arange(num))
    assert 24 <= num <= 96


def test_grid_segments_cover_the_image_with_about_the_requested_count():
    from stereodeblur.sceneflow.superpixels import grid_segments

    labels = grid_segments((30, 40), 12)
    assert labels.shape == (30, 40)
    assert labels.max() + 1 == 12
    sizes = np.bincount(labels.ravel())
    assert sizes.min() == sizes.max() == 100
