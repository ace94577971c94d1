"""Segment boundaries moved to a dense flow's (sceneflow.relabel)."""

from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.geometry.camera import StereoCamera
from stereodeblur.pipeline.motion import to_right_view
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.sceneflow.relabel import flow_homographies, relabel_by_flow, segment_flow

CAMERA = StereoCamera(np.array([[50.0, 0, 20], [0, 50.0, 12], [0, 0, 1]]), 0.3)
HEIGHT, WIDTH = 24, 40
EDGE = 20  # the true boundary: segment 0 left of it, segment 1 from it on


def two_surfaces(edge: int) -> SceneFlow:
    """A far plane moving right (segment 0) and a near, tilted plane moving left and up
    (segment 1), split at column ``edge``."""
    labels = np.zeros((HEIGHT, WIDTH), dtype=np.int32)
    labels[:, edge:] = 1
    normals = np.array([[0.0, 0.0, 0.1], [0.02, 0.01, 0.2]])
    twists = np.array([[0.1, 0, 0, 0, 0, 0], [-0.2, 0.05, 0.1, 0, 0.01, 0]])
    return SceneFlow(CAMERA, labels, normals, twists, np.zeros((HEIGHT, WIDTH), bool))


@pytest.mark.parametrize("view", ["left", "right"])
def test_segment_flow_is_the_scene_flows_own(view):
    sf = two_surfaces(EDGE)
    sf = to_right_view(sf) if view == "right" else sf
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH]
    flow = segment_flow(flow_homographies(sf), x.ravel(), y.ravel(), sf.labels.ravel())
    np.testing.assert_allclose(flow.reshape(HEIGHT, WIDTH, 2), sf.flow(), atol=1e-9)
    back = segment_flow(flow_homographies(sf.reversed()), x.ravel(), y.ravel(), sf.labels.ravel())
    np.testing.assert_allclose(back.reshape(HEIGHT, WIDTH, 2), sf.reversed().flow(), atol=1e-9)


def test_the_boundary_moves_to_the_flows_within_the_radius():
    truth = two_surfaces(EDGE)
    estimate = two_surfaces(EDGE + 4)  # the estimate's boundary 4 px right of the truth's
    moved = relabel_by_flow(estimate, truth.flow(), truth.reversed().flow(), radius=6)
    np.testing.assert_array_equal(moved.labels, truth.labels)
    part = relabel_by_flow(estimate, truth.flow(), radius=2)  # only 2 px of the 4
    np.testing.assert_array_equal(part.labels, two_surfaces(EDGE + 2).labels)
    for out in (moved, part):
        np.testing.assert_array_equal(out.normals, estimate.normals)
        np.testing.assert_array_equal(out.twists, estimate.twists)
        assert out.occlusion is estimate.occlusion and out.view == estimate.view


def test_its_own_flow_keeps_every_label():
    sf = two_surfaces(EDGE)
    assert np.array_equal(relabel_by_flow(sf, sf.flow(), radius=5).labels, sf.labels)


def test_the_backward_flow_decides_where_the_forward_flow_misleads():
    truth, estimate = two_surfaces(EDGE), two_surfaces(EDGE - 3)
    # In the disputed columns the forward flow leans to the estimate's surface (as a dense
    # flow does where that surface comes to cover the pixel); the backward flow does not.
    forward = truth.flow().copy()
    lean = 0.6 * estimate.flow() + 0.4 * truth.flow()
    forward[:, EDGE - 3 : EDGE] = lean[:, EDGE - 3 : EDGE]
    assert np.array_equal(relabel_by_flow(estimate, forward, radius=4).labels, estimate.labels)
    both = relabel_by_flow(estimate, forward, truth.reversed().flow(), radius=4)
    np.testing.assert_array_equal(both.labels, truth.labels)


def test_segments_of_one_surface_are_not_swapped():
    def one_surface(edge):  # two segments, the second's motion 1 % faster towards the camera
        sf = two_surfaces(edge)
        twists = sf.twists[[0, 0]] + [[0, 0, 0, 0, 0, 0], [0, 0, 0.01, 0, 0, 0]]
        return SceneFlow(CAMERA, sf.labels, sf.normals[[0, 0]], twists, sf.occlusion)

    estimate, truth = one_surface(EDGE), one_surface(EDGE + 3)
    difference = np.abs(estimate.flow() - truth.flow()).max()
    assert 0.01 < difference < 0.5  # the two segments' flows differ, by less than the jump
    swapped = relabel_by_flow(estimate, truth.flow(), radius=4)  # without a jump they swap
    np.testing.assert_array_equal(swapped.labels, truth.labels)
    kept = relabel_by_flow(estimate, truth.flow(), radius=4, jump=0.5, relative=0.02)
    np.testing.assert_array_equal(kept.labels, estimate.labels)
    estimate, truth = two_surfaces(EDGE + 4), two_surfaces(EDGE)  # two surfaces: moved
    moved = relabel_by_flow(estimate, truth.flow(), radius=6, jump=0.5, relative=0.02)
    np.testing.assert_array_equal(moved.labels, truth.labels)


def test_a_flow_of_another_size_is_refused():
    sf = two_surfaces(EDGE)
    with pytest.raises(ValueError, match="shape"):
        relabel_by_flow(sf, np.zeros((HEIGHT, WIDTH - 1, 2)), radius=3)


def test_a_margin_keeps_the_labels_where_the_flow_is_wrong_everywhere():
    truth, estimate = two_surfaces(EDGE), two_surfaces(EDGE + 4)
    # Clean flows: the segments fit them (median distance 0), so the margin changes nothing.
    clean = relabel_by_flow(estimate, truth.flow(), truth.reversed().flow(), radius=6, margin=1)
    np.testing.assert_array_equal(clean.labels, truth.labels)
    # Flows off by a few px everywhere (as DIS on noisy fine stripes): without a margin, the
    # noise moves pixels along the boundary's band; with it, hardly any.
    rng = np.random.default_rng(0)
    step = np.abs(truth.flow()[:, EDGE] - truth.flow()[:, EDGE - 1]).max()
    forward, backward = (
        flow + rng.normal(0, 0.5 * step, flow.shape)
        for flow in (estimate.flow(), estimate.reversed().flow())
    )
    noisy = (relabel_by_flow(estimate, forward, backward, radius=6).labels != estimate.labels).sum()
    kept = relabel_by_flow(estimate, forward, backward, radius=6, margin=1)
    assert noisy > 20 and (kept.labels != estimate.labels).sum() <= 0.1 * noisy


def _relabelled_by_definition(sf, forward, backward, radius, jump, relative, margin):
    """The rule of ``relabel_by_flow`` written out pixel by pixel: the window's segments in
    row order, each other surface's summed end-point distances plus the margin; the least
    below the own segment's wins, a tie keeps the earlier."""
    targets = [(flow_homographies(sf), forward), (flow_homographies(sf.reversed()), backward)]
    labels, (height, width) = sf.labels, sf.labels.shape

    def distances(segment, x, y):
        flows = [segment_flow(h, [x], [y], [segment])[0] for h, _ in targets]
        errors = [f - target[y, x] for f, (_, target) in zip(flows, targets, strict=True)]
        return sum(np.hypot(*e) for e in errors), flows[0]

    own_totals = [distances(labels[y, x], x, y)[0] for y in range(height) for x in range(width)]
    threshold = margin * np.median(own_totals)
    out = labels.copy()
    for y in range(height):
        for x in range(width):
            own = labels[y, x]
            best, own_forward = distances(own, x, y)
            seen = {own}
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    s = labels[min(max(y + dy, 0), height - 1), min(max(x + dx, 0), width - 1)]
                    if s in seen:
                        continue
                    seen.add(s)
                    total, f = distances(s, x, y)
                    longer = max(np.hypot(*f), np.hypot(*own_forward))
                    if np.hypot(*(f - own_forward)) <= max(jump, relative * longer):
                        continue  # the same surface
                    if total + threshold < best:
                        best, out[y, x] = total + threshold, s
    return out


def test_every_pixel_takes_the_segment_the_rule_defines():
    rng = np.random.default_rng(3)
    blocks = rng.integers(0, 6, size=(4, 5))
    labels = np.kron(blocks, np.ones((6, 8), dtype=np.int64)).astype(np.int32)
    normals = np.column_stack([rng.normal(0, 0.01, (6, 2)), rng.uniform(0.1, 0.3, 6)])
    twists = rng.normal(0, 0.05, (6, 6))
    sf = SceneFlow(CAMERA, labels, normals, twists, np.zeros((HEIGHT, WIDTH), bool))
    # The dense flows follow the surfaces 2 px lower and to the right of the estimate's.
    truth = replace(sf, labels=np.pad(labels, ((2, 0), (2, 0)), mode="edge")[:HEIGHT, :WIDTH])
    forward = truth.flow() + rng.normal(0, 0.3, (HEIGHT, WIDTH, 2))
    backward = truth.reversed().flow() + rng.normal(0, 0.3, (HEIGHT, WIDTH, 2))
    options = dict(radius=3, jump=0.5, relative=0.1, margin=0.2)
    moved = relabel_by_flow(sf, forward, backward, **options)
    expected = _relabelled_by_definition(sf, forward, backward, **options)
    assert (moved.labels != labels).mean() > 0.02  # the rule moves some boundaries here
    np.testing.assert_array_equal(moved.labels, expected)
