"""One pass over a stereo frame: each frame read, scene flow and dense flow computed once."""

import threading
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.deconv.trust import motion_trust, near_motion_boundaries
from stereodeblur.errors import InputError
from stereodeblur.io.scene import open_scene
from stereodeblur.io.sources import open_source
from stereodeblur.pipeline import (
    DeblurSettings,
    deblur_frame,
    deblur_stereo_frame,
    frame_motion,
    invert_flow,
    to_right_view,
)
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene

FAST = {"num_irls": 2, "num_cg": 3, "num_samples": 8}
ESTIMATED = DeblurSettings(**FAST)  # the defaults: scene flow, adaptive, homographies
TRUE = DeblurSettings(**FAST, motion_source="gt")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    rendered = make_object_scene("squares", size=(64, 48), num_samples=8)
    return open_scene(write_rendered_scene(rendered, tmp_path_factory.mktemp("s") / "squares"))


def _count(monkeypatch, scene, trusts=None):
    """Spy on frame reads, scene-flow estimates and the pipeline's dense flows (and, into
    ``trusts``, the motion-trust maps and noise estimates)."""
    from stereodeblur.deconv import noise, trust
    from stereodeblur.sceneflow import estimate, initial

    reads, estimates, flows = Counter(), [], []
    inside = []  # dense flows inside the estimator are its own business (by thread: the
    # pipeline computes the views' dense flows meanwhile in another)
    read_frame, estimate_scene_flow = scene.read_frame, estimate.estimate_scene_flow
    optical_flow = initial.initial_optical_flow
    motion_trusts, noise_sigma = trust.motion_trusts, noise.estimate_noise_sigma
    trusts = [] if trusts is None else trusts

    def spy_trust(blurred, following, flows, **kwargs):
        for flow in flows:
            trusts.append(("trust", blurred.tobytes(), following.tobytes(), flow.tobytes()))
        return motion_trusts(blurred, following, flows, **kwargs)

    def spy_noise(image):
        if threading.get_ident() not in inside:
            trusts.append(("noise", image.tobytes()))
        return noise_sigma(image)

    monkeypatch.setattr(trust, "motion_trusts", spy_trust)
    monkeypatch.setattr(noise, "estimate_noise_sigma", spy_noise)

    def spy_read(view, index, **kwargs):
        reads[view, index] += 1
        return read_frame(view, index, **kwargs)

    def spy_estimate(*args, **kwargs):
        estimates.append(1)
        inside.append(threading.get_ident())
        try:
            return estimate_scene_flow(*args, **kwargs)
        finally:
            inside.pop()

    def spy_flow(a, b, **kwargs):
        # Not the estimator's own (of its 8-bit grey frames), wherever they run.
        if threading.get_ident() not in inside and a.dtype != np.uint8:
            flows.append((a.tobytes(), b.tobytes()))
        return optical_flow(a, b, **kwargs)

    monkeypatch.setattr(scene, "read_frame", spy_read)
    monkeypatch.setattr(estimate, "estimate_scene_flow", spy_estimate)
    monkeypatch.setattr(initial, "initial_optical_flow", spy_flow)
    return reads, estimates, flows


@pytest.mark.parametrize("index", [1, 2])
def test_a_stereo_frame_reads_and_estimates_everything_once(scene, monkeypatch, index):
    trusts = []
    reads, estimates, flows = _count(monkeypatch, scene, trusts)
    result = deblur_stereo_frame(scene, index, settings=ESTIMATED)
    assert set(result.frames) == {"left", "right"}
    window = {1: (0, 1, 2), 2: (1, 2)}[index]
    assert reads == Counter({(v, i): 1 for v in ("left", "right") for i in window})
    assert len(estimates) == 1
    # Dense flows: each view to the neighbour and to the other side where there is one.
    assert len(flows) == len(set(flows)) == {1: 4, 2: 2}[index]
    # Per view one noise estimate; the trust of the motion used (the dense flow near motion
    # boundaries) and of the scene flow's own (for alpha), per neighbouring frame: no repeats.
    assert [kind for kind, *_ in trusts].count("noise") == 2
    assert len(trusts) == len(set(trusts)) == 2 + 2 * 2 * {1: 2, 2: 1}[index]


def test_true_motion_reads_each_frame_once(scene, monkeypatch):
    reads, estimates, flows = _count(monkeypatch, scene)
    deblur_stereo_frame(scene, 1, settings=TRUE)
    assert reads == Counter({(v, i): 1 for v in ("left", "right") for i in (0, 1, 2)})
    assert estimates == []
    assert len(flows) == len(set(flows)) == 4  # the exposure check's, each view both ways


@pytest.mark.parametrize(
    ("settings", "index"),
    [
        (ESTIMATED, 1),
        (ESTIMATED, 2),
        (TRUE, 1),
        (TRUE, 2),
        (DeblurSettings(**FAST, kernels="displacement", motion_source="initial-flow"), 0),
        (DeblurSettings(**FAST, boundary_weights="paper", motion_source="gt"), 1),
    ],
)
def test_the_stereo_frame_equals_one_frame_per_view(scene, settings, index):
    stereo = deblur_stereo_frame(scene, index, settings=settings)
    for view in ("left", "right"):
        alone = deblur_frame(scene, index, view=view, settings=settings)
        both = stereo.frames[view]
        np.testing.assert_array_equal(both.image, alone.image)
        assert both.alpha == alone.alpha and both.view == view
        assert (both.trust is None) == (alone.trust is None)
        if both.trust is not None:
            np.testing.assert_array_equal(both.trust, alone.trust)


def test_one_view_only(scene, monkeypatch):
    reads, _, _ = _count(monkeypatch, scene)
    settings = DeblurSettings(**FAST, motion_source="initial-flow", kernels="displacement")
    result = deblur_stereo_frame(scene, 1, views=("right",), settings=settings)
    assert set(result.frames) == {"right"}
    assert set(reads) == {("right", 0), ("right", 1), ("right", 2)}


def test_the_last_frame_with_true_motion_leads_to_the_previous_frame(scene):
    last = scene.num_frames - 1
    motion = frame_motion(scene, last, "left", TRUE)
    assert (motion.index, motion.neighbour, motion.flow_backward) == (last, last - 1, None)
    # The flow to the previous frame is the inverse of the gt flow into the last frame.
    into = scene.read_gt_flow("left", last - 1)
    known = np.all(np.isfinite(into), axis=2)
    expected = invert_flow(np.where(known[..., None], into, 0).astype(np.float32))
    inside = np.isfinite(motion.flow_forward).all(axis=2)
    assert inside.mean() > 0.5
    np.testing.assert_array_equal(motion.flow_forward[inside], expected[inside])
    result = deblur_frame(scene, last, settings=TRUE)
    assert result.motion.neighbour == last - 1 and np.isfinite(result.image).all()


def test_the_last_frames_trust_compares_the_previous_frame_along_the_flow_to_it(scene):
    last = scene.num_frames - 1
    settings = DeblurSettings(**FAST, kernels="displacement")  # scene flow, no dense rows
    result = deblur_frame(scene, last, settings=settings)
    motion, blurred = result.motion, scene.read_frame("left", last)
    previous = scene.read_frame("left", last - 1)
    expected = motion_trust(blurred, previous, motion.flow_forward)
    band = near_motion_boundaries(motion.flow_forward, scene.info.exposure.duty_cycle)
    assert band.any()
    np.testing.assert_array_equal(result.trust[band], expected[band])
    wrong = motion_trust(blurred, previous, -motion.flow_forward)  # the flow pointing away
    assert result.trust[band].mean() > wrong[band].mean()


@pytest.mark.parametrize("observations", ["single", "other-view"])
def test_timings_name_the_stages(scene, observations):
    settings = replace(TRUE, observations=observations)
    stages = {"motion", "operator", "deconvolution"}
    if observations != "single":
        stages.add("observations")
    stereo = deblur_stereo_frame(scene, 1, settings=settings)
    assert set(stereo.timings) == {"read", "exposure", "motion"}
    for result in stereo.frames.values():
        assert set(result.timings) == stages | {"exposure"}
        assert result.timings["motion"] == (stereo.timings["read"] + stereo.timings["motion"]) / 2
        assert result.timings["exposure"] == stereo.timings["exposure"] / 2
    alone = deblur_frame(scene, 1, settings=settings)
    assert set(alone.timings) == stages | {"exposure"}


def test_progress_names_frame_and_view(scene):
    seen = []
    # one solve per view: the other view only (the neighbouring frames' weighing solves twice)
    settings = DeblurSettings(**FAST, motion_source="gt", alpha=1e-3, observations="other-view")
    deblur_stereo_frame(scene, 1, settings=settings, progress=seen.append)
    stages = [p.stage for p in seen]
    assert stages[:3] == ["frame 1: exposure check", stages[1], "frame 1: motion (gt)"]
    assert stages[1].startswith("frame 1: exposure 0.0")
    assert "frame 1 right: blur operator (homography)" in stages
    irls = [p for p in seen if p.stage == "frame 1 left: IRLS"]
    assert [(p.done, p.total) for p in irls] == [(1, 2), (2, 2)]


def test_a_given_scene_flow_replaces_the_estimate(scene, monkeypatch):
    settings = DeblurSettings(**FAST, kernels="displacement", boundary_weights="paper")
    estimated = deblur_stereo_frame(scene, 1, settings=settings)
    sceneflow = estimated.motion.estimate.sceneflow
    reads, estimates, _ = _count(monkeypatch, scene)
    given = deblur_stereo_frame(scene, 1, settings=settings, sceneflow=sceneflow)
    frames = {(view, index) for view in ("left", "right") for index in (0, 1, 2)}
    assert estimates == [] and set(reads) == frames  # the neighbouring frames, observed
    for view in ("left", "right"):
        np.testing.assert_array_equal(given.frames[view].image, estimated.frames[view].image)
    with pytest.raises(InputError, match="left view"):
        deblur_stereo_frame(scene, 1, settings=settings, sceneflow=to_right_view(sceneflow))
    with pytest.raises(InputError, match="motion_source='sceneflow'"):
        deblur_stereo_frame(scene, 1, settings=TRUE, sceneflow=sceneflow)


def test_a_frame_of_exposure_zero_passes_through(scene):
    """No exposure, no blur: both views come back as their blurred frames, after the motion."""
    sharp = open_source(scene.root, exposure=0.0)
    stereo = deblur_stereo_frame(sharp, 1, settings=ESTIMATED)
    for view in ("left", "right"):
        frame = stereo.frames[view]
        assert np.array_equal(frame.image, np.clip(scene.read_frame(view, 1), 0, 1))
        assert frame.exposure == 0.0 and frame.motion.sceneflow is not None
    assert stereo.exposure is None  # given, not estimated


def test_the_exposure_estimated_per_stereo_frame_is_the_one_deblurred_for(scene):
    stereo = deblur_stereo_frame(scene, 1, settings=replace(ESTIMATED, exposure="auto"))
    found = stereo.exposure
    assert found.exposure.frame_rate == scene.info.exposure.frame_rate
    assert "exposure" in stereo.timings
    used = 0.0 if found.sharp else found.exposure.exposure  # the squares move about 2 px
    assert {f.exposure for f in stereo.frames.values()} == {used}


@pytest.mark.parametrize(("name", "duty"), [("upward", 0.0), ("long_exposure_roll", 0.8)])
def test_frames_whose_blur_reads_shorter_than_two_pixels_pass_through(tmp_path, name, duty):
    """A plane moving about 3 px per frame rendered sharp reads as 1.6 px of blur and passes
    through; the rolling camera exposed for 0.8 of the frame interval (about 10 px of blur)
    is deblurred for the estimate."""
    from stereodeblur.geometry.camera import Exposure
    from stereodeblur.synth.planar import FRAME_RATE, planar_setup
    from stereodeblur.synth.render import render_scene

    setup = planar_setup(name, size=(160, 120), num_frames=3)
    setup = replace(setup, exposure=Exposure(FRAME_RATE, duty / FRAME_RATE))
    root = write_rendered_scene(render_scene(setup, num_samples=24), tmp_path / name)
    settings = replace(TRUE, exposure="auto")
    stereo = deblur_stereo_frame(open_scene(root), 1, views=("left",), settings=settings)
    found, frame = stereo.exposure, stereo.frames["left"]
    unchanged = np.array_equal(frame.image, np.clip(frame.blurred, 0, 1))
    if duty == 0:
        assert found.sharp and found.exposure.exposure > 0, found  # read as a short blur
        assert frame.exposure == 0.0 and unchanged
    else:
        assert not found.sharp and found.blur > 5, found
        assert frame.exposure == found.exposure.exposure > 0 and not unchanged
