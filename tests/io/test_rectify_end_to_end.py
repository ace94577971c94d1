"""The rectification test: a rendered rig with lens distortion and the right camera turned by
about a degree, rectified on reading, deblurs like the same rig rendered rectified.

One planar scene is rendered in the rectified geometry of a synthetic rig (the camera
``cv2.stereoRectify`` gives it) at four times the size, with a lens blur of 0.7 px. The
rectified clip is its mean over each pixel; the raw frames the distorted, turned cameras
record are its means over each raw pixel's area, found with the inverse of the
rectification maps. Both clips are written as lossless 8-bit video pairs (the rectified one
with its rectified calibration, the raw one with the rig's ``stereoCalibrate`` calibration)
and deblurred with estimated motion.

The claim checked: against the sharp rectified render, the raw rig's deblurred frame is at
most 0.5 dB below the rectified clip's, over the interior (a border of 8 px left out, where
the raw frames' warp runs off the render). Without the lens blur (pixels as sharp as a box
filter makes them) the interpolation of rectification costs more than that. The same raw
frames read as if they were rectified (distortion and rotation ignored) fall far below, so
the test can fail.
"""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import pytest

from stereodeblur.evaluation.metrics import psnr
from stereodeblur.geometry.camera import VIEWS, StereoCamera
from stereodeblur.io.formats import read_png
from stereodeblur.io.sources import open_source
from stereodeblur.io.video import write_video
from stereodeblur.synth.planar import planar_setup
from stereodeblur.synth.render import render_scene
from tests.clip.clip_helpers import run_cli
from tests.io.rig_layouts import area_mean, fine_camera, make_rig, raw_from_fine, write_opencv_rig
from tests.io.stereo_layouts import opencv_calibration, to_u8, write_opencv_yaml

SIZE = (128, 96)
LENS_SIGMA = 0.7  # px: the lens's blur (Gaussian sigma); no camera delivers box-filtered pixels
FINE = 4  # the scene is rendered at 4x the size and averaged over pixels
BORDER = 8
TOLERANCE_DB = 0.5
ESTIMATED = ["--motion-source", "sceneflow", "--irls", "4", "--cg", "10", "--samples", "24"]
OPTIONS = ["--frames", "1", "--views", "left", "--workers", "1", "-q", "--color", "linear"]


def _lens(image):
    """The lens's blur, at the fine render's scale."""
    return cv2.GaussianBlur(image, (0, 0), LENS_SIGMA * FINE) if LENS_SIGMA else image


@pytest.fixture(scope="module")
def rig_clips(tmp_path_factory):
    """The rectified clip and the raw rig's clip as video pairs, and the sharp truth.

    The scene is rendered once at ``FINE`` times the size; the rectified clip and the
    truth are its means over each pixel, the raw clip its means over each raw pixel's area
    (seen through the distortion and rotation), so neither clip has interpolation the
    other lacks.
    """
    rig = make_rig(SIZE)
    camera = StereoCamera(rig.rectified_K, rig.rectified_baseline)
    fine = StereoCamera(fine_camera(rig.rectified_K, FINE), rig.rectified_baseline)
    fine_size = (SIZE[0] * FINE, SIZE[1] * FINE)
    setup = dataclasses.replace(
        planar_setup("yaw", size=fine_size, num_frames=3), camera=fine, size=fine_size
    )
    scene = render_scene(setup, num_samples=24)
    lens = {v: [_lens(f) for f in scene.frames[v]] for v in VIEWS}
    root = tmp_path_factory.mktemp("rig")
    rate = scene.exposure.frame_rate
    frames = {
        "rectified": {v: [area_mean(f, FINE) for f in lens[v]] for v in VIEWS},
        "raw": {v: [raw_from_fine(rig, v, f, FINE) for f in lens[v]] for v in VIEWS},
    }
    clips = {}
    for kind, views in frames.items():
        (root / kind).mkdir()
        clips[kind] = [
            write_video(
                root / kind / f"{view}.mkv", [to_u8(f) for f in views[view]], frame_rate=rate
            )
            for view in VIEWS
        ]
    rectified = opencv_calibration(camera.K, camera.baseline, SIZE)
    clips["rectified"].append(write_opencv_yaml(root / "rectified.yml", rectified))
    clips["raw"].append(write_opencv_rig(root / "stereo_calibration.yml", rig))
    # The raw frames with a calibration that ignores the distortion and the rotation.
    clips["ignored"] = [*clips["raw"][:2], clips["rectified"][2]]
    return {
        "clips": clips,
        "frames": frames["rectified"],
        "sharp": area_mean(_lens(scene.sharp["left"][1]), FINE),
        "exposure": scene.exposure.exposure,
        "rig": rig,
    }


def _deblur(rig_clips, kind, out):
    left, right, calib = rig_clips["clips"][kind]
    exposure = rig_clips["exposure"]
    result = run_cli(
        "deblur", left, right, "--calib", calib, "--exposure", exposure, "-o", out,
        *OPTIONS, *ESTIMATED,
    )  # fmt: skip
    assert result.code == 0, result.stderr
    return read_png(out / "left" / "000001.png")


def test_raw_frames_read_rectified(rig_clips):
    """Reading the raw videos gives the rectified renders back (two interpolations apart)."""
    rectified = rig_clips["frames"]
    scores = {}
    for kind in ("raw", "ignored"):
        left, right, calib = rig_clips["clips"][kind]
        source = open_source([left, right], calib=calib, exposure=0.01, color="linear")
        scores[kind] = min(
            psnr(source.read_frame(view, 1), rectified[view][1], border=BORDER) for view in VIEWS
        )
    print("PSNR of the frames read against the rectified clip (dB):", json.dumps(scores))
    assert scores["raw"] >= 35.0, scores
    assert scores["ignored"] <= scores["raw"] - 10.0, scores


def test_raw_rig_deblurs_as_the_rectified_one(rig_clips, tmp_path):
    truth = rig_clips["sharp"]
    blurred = rig_clips["frames"]["left"][1]
    scores = {"blurred": psnr(blurred, truth, border=BORDER)}
    for kind in ("rectified", "raw", "ignored"):
        scores[kind] = psnr(_deblur(rig_clips, kind, tmp_path / kind), truth, border=BORDER)
    print("PSNR against the sharp render (dB):", json.dumps(scores))
    assert scores["rectified"] > scores["blurred"] + 1.0, scores
    assert scores["raw"] >= scores["rectified"] - TOLERANCE_DB, scores
    assert scores["ignored"] < scores["rectified"] - TOLERANCE_DB, scores
    # The results are in the rectified geometry, with the rectified camera beside them.
    written = json.loads((tmp_path / "raw" / "camera.json").read_text())
    rig = rig_clips["rig"]
    np.testing.assert_allclose(written["K"], rig.rectified_K, rtol=1e-9)
    assert written["baseline"] == pytest.approx(rig.rectified_baseline, rel=1e-9)
