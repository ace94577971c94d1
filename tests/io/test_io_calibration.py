"""Stereo calibration files: OpenCV FileStorage YAML/JSON and camera.json; one test per
malformed kind, each a one-line error naming the file."""

import json

import cv2
import numpy as np
import pytest

from stereodeblur.cli import main
from stereodeblur.errors import InputError
from stereodeblur.io.calibration import read_stereo_calibration
from tests.io.stereo_layouts import opencv_calibration, write_opencv_yaml, write_video_pair

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])
BASELINE = 0.12
SIZE = (32, 24)

GOOD_YAML = """%YAML:1.0
---
M1: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 40., 0., 15.5, 0., 40., 11.5, 0., 0., 1. ]
P1: !!opencv-matrix
   rows: 3
   cols: 4
   dt: d
   data: [ 40., 0., 15.5, 0., 0., 40., 11.5, 0., 0., 0., 1., 0. ]
P2: !!opencv-matrix
   rows: 3
   cols: 4
   dt: d
   data: [ 40., 0., 15.5, -4.8, 0., 40., 11.5, 0., 0., 0., 1., 0. ]
imageSize: [ 32, 24 ]
"""

HAND_EDITED = """# calibration of rig 2, edited by hand

P2: !!opencv-matrix

\tdata: [ 40., 0., 15.5, -4.8,
\t       0., 40., 11.5, 0.,

\t       0., 0., 1., 0. ]
\tdt: d
\tcols: 4   # four columns
\trows: 3
P1: !!opencv-matrix {rows: 3, cols: 4, dt: d, data: [40, 0, 15.5, 0, 0, 40, 11.5, 0, 0, 0, 1, 0]}
"""


def _camera_equal(camera, K_expected, baseline):
    np.testing.assert_allclose(camera.K, K_expected, rtol=1e-12)
    assert camera.baseline == pytest.approx(baseline, rel=1e-12)


def test_stereo_rectify_output_written_by_filestorage(tmp_path):
    K0 = np.array([[500.0, 0, 320], [0, 505, 240], [0, 0, 1]])
    R = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0]
    T = np.array([[-0.12], [0.002], [0.001]])
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(
        K0, np.zeros(5), K0, np.zeros(5), (640, 480), R, T, flags=cv2.CALIB_ZERO_DISPARITY
    )
    entries = {"M1": K0, "D1": np.zeros((1, 5)), "R": R, "T": T, "R1": R1, "R2": R2}
    entries.update({"P1": P1, "P2": P2, "Q": Q, "imageSize": (640, 480)})
    calibration = read_stereo_calibration(write_opencv_yaml(tmp_path / "stereo.yml", entries))
    # The rectified rig: P1's intrinsics, the cameras |T| apart.
    _camera_equal(calibration.camera, P1[:, :3], float(np.linalg.norm(T)))
    assert calibration.image_size == (640, 480)
    assert calibration.frame_rate is None and calibration.exposure is None


@pytest.mark.parametrize("keys", [("P1", "P2"), ("Q",), ("M1", "P1", "P2", "Q")])
def test_projection_matrices_or_q_alone(tmp_path, keys):
    entries = {k: v for k, v in opencv_calibration(K, BASELINE, SIZE).items() if k in keys}
    calibration = read_stereo_calibration(write_opencv_yaml(tmp_path / "c.yml", entries))
    _camera_equal(calibration.camera, K, BASELINE)


def test_hand_edited_yaml_still_parses(tmp_path):
    for name, text in {
        "good.yml": GOOD_YAML,
        "edited.yml": HAND_EDITED,
        "crlf.yml": GOOD_YAML.replace("\n", "\r\n"),
        "no-header.yaml": GOOD_YAML.split("---\n", 1)[1],
        "opencv-1.2.yml": GOOD_YAML.replace("%YAML:1.0", "%YAML 1.2"),
    }.items():
        (tmp_path / name).write_text(text, newline="")
        _camera_equal(read_stereo_calibration(tmp_path / name).camera, K, BASELINE)


def test_filestorage_json_and_camera_json(tmp_path):
    storage = cv2.FileStorage(str(tmp_path / "c.json"), cv2.FILE_STORAGE_WRITE)
    for key, value in opencv_calibration(K, BASELINE, SIZE).items():
        if key != "imageSize":
            storage.write(key, value)
    storage.release()
    _camera_equal(read_stereo_calibration(tmp_path / "c.json").camera, K, BASELINE)

    camera = {"format": "stereo-video/1", "K": K.tolist(), "baseline": BASELINE,
              "frame_rate": 30.0, "exposure": 0.01, "color": "srgb"}  # fmt: skip
    (tmp_path / "camera.json").write_text(json.dumps(camera))
    calibration = read_stereo_calibration(tmp_path / "camera.json")
    _camera_equal(calibration.camera, K, BASELINE)
    assert (calibration.frame_rate, calibration.exposure, calibration.color) == (30.0, 0.01, "srgb")


def _replace(old, new):
    assert old in GOOD_YAML
    return GOOD_YAML.replace(old, new)


MALFORMED = {
    "empty": ("", "empty"),
    "binary": ("\x00\x01\x02", "not a text file"),
    "xml": ('<?xml version="1.0"?>\n<opencv_storage/>\n', "XML"),
    "not key-value": (GOOD_YAML + "hello world\n", "line 19"),
    "no projection": (GOOD_YAML.split("P1:")[0], "no rectified projection matrices"),
    "P1 only": (GOOD_YAML.split("P2:")[0], "no 'P2'"),
    "duplicate key": (GOOD_YAML + "P1: 3\n", "appears twice"),
    "not a matrix": (_replace("P2: !!opencv-matrix", "P2: 7\nX: !!opencv-matrix"), "'P2'"),
    "missing data": (_replace("data: [ 40., 0., 15.5, -4.8,", "datum: [ 40., 0., 15.5, -4.8,"),
                     "unexpected"),
    "missing rows": (GOOD_YAML.replace("   rows: 3\n   cols: 4", "   cols: 4"), "no 'rows'"),
    "too few values": (_replace("-4.8, 0., 40.", "-4.8, 40."), "11 values"),
    "not a number": (_replace("-4.8", "minus4.8"), "'minus4.8' is not a number"),
    "non-finite": (_replace("-4.8", ".Inf"), "not a finite number"),
    "truncated": (GOOD_YAML.split("imageSize")[0].rsplit("0., 1., 0. ]", 1)[0], "not closed"),
    "wrong shape": (_replace("rows: 3\n   cols: 4\n   dt: d\n   data: [ 40., 0., 15.5, 0., 0.",
                             "rows: 4\n   cols: 3\n   dt: d\n   data: [ 40., 0., 15.5, 0., 0."),
                    "must be 3x4"),
    "swapped views": (_replace("-4.8", "4.8"), "swapped"),
    "vertical stereo": (_replace("-4.8, 0., 40., 11.5, 0.,", "0., 0., 40., 11.5, -4.8,"),
                        "horizontal"),
    "different focal lengths": (_replace("[ 40., 0., 15.5, -4.8", "[ 41., 0., 15.5, -4.8"),
                                "different fx"),
    "wrong image size": (_replace("imageSize: [ 32, 24 ]", "imageSize: [ 64, 48 ]"),
                         "64x48 images"),
    "q disagrees": (GOOD_YAML + "Q: !!opencv-matrix\n rows: 4\n cols: 4\n dt: d\n data: [1, 0, "
                    "0, -15.5, 0, 1, 0, -11.5, 0, 0, 0, 40, 0, 0, 5, 0]\n", "disagree"),
    "camera.json": ('{"format": "stereo-video/1", "K": [[40, 0, 15.5]], "baseline": 0.12, '
                    '"frame_rate": 20, "exposure": 0.01}', "'K' must be a 3x3"),
}  # fmt: skip


@pytest.fixture(scope="module")
def videos(tmp_path_factory):
    rng = np.random.default_rng(3)
    frames = [rng.random((SIZE[1], SIZE[0], 3)).astype(np.float32) for _ in range(3)]
    left, right, _ = write_video_pair(tmp_path_factory.mktemp("videos"), frames, frames, K, 0.12)
    return left, right


def test_good_calibration_opens_the_videos(videos, tmp_path):
    calib = tmp_path / "good.yml"
    calib.write_text(GOOD_YAML)
    from stereodeblur.io.sources import open_source

    source = open_source(videos, calib=calib, exposure=0.01)
    _camera_equal(source.info.camera, K, BASELINE)


@pytest.mark.parametrize("kind", list(MALFORMED))
def test_malformed_calibration_is_one_line_naming_the_file(kind, videos, tmp_path, capsys):
    text, fragment = MALFORMED[kind]
    calib = tmp_path / ("bad.json" if kind == "camera.json" else "bad.yml")
    calib.write_bytes(text.encode("utf-8"))
    out = tmp_path / "out"
    code = main(["deblur", *map(str, videos), "--calib", str(calib), "--exposure", "0.01",
                 "-o", str(out)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("stereodeblur: error: ")
    assert str(calib) in err[0] and fragment in err[0], err[0]
    assert not out.exists()
    if kind != "wrong image size":  # checked against the videos, not in the file alone
        with pytest.raises(InputError):
            read_stereo_calibration(calib)
