import numpy as np

from stereodeblur.geometry import se3_exp
from stereodeblur.geometry.plane import disparity_coefficients
from stereodeblur.sceneflow.fusion import ProposalSet
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.sceneflow.proposals import predict
from stereodeblur.sceneflow.refine import refine_proposals

from .scenes import CAMERA, SIZE, frames, render_views

NORMAL = np.array([0.1, -0.06, 0.5])
TWIST = np.array([0.05, -0.03, -0.08, 0.01, 0.015, -0.01])


def _endpoint_and_disparity_errors(props):
    truth = SceneFlow(
        CAMERA, np.zeros(SIZE, np.int32), NORMAL[None], TWIST[None], np.zeros(SIZE, bool)
    )
    y, x = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    d0, x1, y1, _ = predict(CAMERA, props.abc[0], props.R[0], props.T[0], x, y)
    flow = truth.flow()
    epe = np.hypot(x1 - x - flow[..., 0], y1 - y - flow[..., 1]).mean()
    return epe, np.abs(d0 - truth.disparity()).mean()


def test_refinement_pulls_a_perturbed_proposal_towards_the_truth():
    views = render_views(NORMAL, TWIST, num_instants=9)
    images = list(frames(views))
    M = se3_exp(TWIST)
    abc = disparity_coefficients(CAMERA, NORMAL)
    start = ProposalSet(
        (abc + [0.004, -0.003, 0.4])[None],
        (se3_exp(np.array([0, 0, 0, 0.002, -0.002, 0.001]))[:3, :3] @ M[:3, :3])[None],
        (M[:3, 3] + [0.004, -0.003, 0.005])[None],
    )
    before = _endpoint_and_disparity_errors(start)
    refined = refine_proposals(CAMERA, images, np.zeros(SIZE, np.int64), start)
    after = _endpoint_and_disparity_errors(refined)
    assert before[0] > 0.4 and before[1] > 0.3
    assert after[0] < 0.4 * before[0]  # the motion prior holds back part of the step
    assert after[1] < 0.25 * before[1]


def test_no_iterations_returns_the_input():
    props = ProposalSet(np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, 3)))
    out = refine_proposals(
        CAMERA, [np.zeros(SIZE)] * 4, np.zeros(SIZE, np.int64), props, num_iterations=0
    )
    assert out is props
