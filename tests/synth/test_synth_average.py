"""`synth average`: blurred frames are exact means of sharp frames, and deblurring them helps."""

import dataclasses
import io
import json
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest

from stereodeblur.cli import main
from stereodeblur.evaluation.metrics import psnr
from stereodeblur.geometry.camera import Exposure
from stereodeblur.io.formats import read_png
from stereodeblur.io.scene import open_scene
from stereodeblur.synth.average import compose_flows
from stereodeblur.synth.planar import planar_setup, write_rendered_scene
from stereodeblur.synth.render import SceneSetup, render_scene

WINDOW = 5
BLURRED_FRAMES = 4


def _cli(*argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, err.getvalue()


@pytest.fixture(scope="module")
def fast_clip(tmp_path_factory):
    """A sharp (instantaneous) 100 fps clip of the rolling plane: WINDOW frames per 20 fps frame."""
    slow = planar_setup("long_exposure_roll", size=(64, 48), num_frames=BLURRED_FRAMES)
    plane = dataclasses.replace(slow.objects[0], twist=slow.objects[0].twist / WINDOW)
    setup = SceneSetup(
        "fast", slow.camera, Exposure(20.0 * WINDOW, 0.0), slow.size,
        BLURRED_FRAMES * WINDOW, (plane,),
    )  # fmt: skip
    scene = render_scene(setup, num_samples=1)
    return write_rendered_scene(scene, tmp_path_factory.mktemp("fast") / "scene")


@pytest.fixture(scope="module")
def averaged(fast_clip, tmp_path_factory):
    out = tmp_path_factory.mktemp("averaged") / "scene"
    code, err = _cli("synth", "average", fast_clip, out, "--window", WINDOW, "-q")
    assert code == 0, err
    return out


def test_each_blurred_frame_is_the_mean_of_its_window(fast_clip, averaged):
    source, scene = open_scene(fast_clip), open_scene(averaged)
    assert scene.num_frames == BLURRED_FRAMES
    assert scene.info.exposure.frame_rate == 20.0
    assert scene.info.exposure.exposure == pytest.approx(WINDOW / 100.0)
    for j in range(BLURRED_FRAMES):
        for view in ("left", "right"):
            window = [source.read_frame(view, j * WINDOW + k) for k in range(WINDOW)]
            mean = (np.sum(np.array(window, dtype=np.float64), axis=0) / WINDOW).astype(np.float32)
            stored = read_png(scene.frame_path(view, j))  # 16-bit levels
            np.testing.assert_array_equal(
                np.rint(stored * 65535), np.rint(mean.astype(np.float64) * 65535)
            )
            centre = j * WINDOW + WINDOW // 2
            np.testing.assert_array_equal(
                scene.read_gt_sharp(view, j), source.read_gt_sharp(view, centre)
            )
            np.testing.assert_array_equal(
                scene.read_gt_disparity(view, j), source.read_gt_disparity(view, centre)
            )
    record = json.loads((averaged / "gt" / "average.json").read_text())
    assert record["frames"][1] == {"index": 1, "source_frames": [5, 9], "centre": 7}


def test_deblurring_the_average_approaches_the_centre_frame(averaged, tmp_path):
    out = tmp_path / "deblurred"
    code, err = _cli(
        "deblur", averaged, "-o", out, "--motion-source", "gt", "--irls", "3", "--cg", "10",
        "--samples", "32", "--workers", "1", "-q",
    )  # fmt: skip
    assert code == 0, err
    blurred, deblurred = open_scene(averaged), open_scene(out)
    for j in range(BLURRED_FRAMES):
        for view in ("left", "right"):
            sharp = blurred.read_gt_sharp(view, j)
            before = psnr(blurred.read_frame(view, j), sharp)
            after = psnr(deblurred.read_frame(view, j), sharp)
            assert after > before + 1.5, (j, view, before, after)


def test_composed_flow_follows_the_chain():
    H, W = 12, 16
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    first = np.stack([0.1 * x + 1.0, np.full((H, W), 0.5)], -1)  # affine
    second = np.stack([np.full((H, W), -2.0), 0.05 * y], -1)
    total = compose_flows([first, second])
    x1, y1 = x + first[..., 0], y + first[..., 1]
    inside = (x1 <= W - 1) & (y1 <= H - 1)
    np.testing.assert_allclose(total[..., 0][inside], (first[..., 0] - 2.0)[inside], atol=1e-5)
    np.testing.assert_allclose(total[..., 1][inside], (0.5 + 0.05 * y1)[inside], atol=1e-5)
    assert np.all(np.isnan(total[~inside]))


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["--window", "4"], "odd"),
        (["--window", "0"], "positive"),
        (["--window", "3", "--stride", "2"], "--stride"),
        (["--window", "11"], "at least 2"),
    ],
)
def test_bad_windows(fast_clip, tmp_path, argv, fragment):
    out = tmp_path / "out"
    code, err = _cli("synth", "average", fast_clip, out, *argv)
    assert code == 2 and len(err.strip().splitlines()) == 1 and fragment in err, err
    assert not out.exists()
