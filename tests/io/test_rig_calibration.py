"""Calibrations of unrectified rigs: each format read back to the matrices written, the same
rectification from each, and one test per kind of bad file (one line naming the file and key,
exit 2)."""

import cv2
import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.calibration import StereoCalibration
from stereodeblur.io.rectify import rectify_rig, rectify_view
from stereodeblur.io.rig import StereoRig, read_calibration
from stereodeblur.io.sources import open_source
from stereodeblur.io.srgb import linear_to_srgb, srgb_to_linear
from stereodeblur.io.video import write_video
from tests.clip.clip_helpers import run_cli
from tests.io.rig_layouts import (
    kalibr_text,
    make_rig,
    ros_camera_info,
    write_opencv_folder,
    write_opencv_rig,
    write_ros_folder,
)
from tests.io.stereo_layouts import write_opencv_yaml

SIZE = (96, 72)
RIG = make_rig(SIZE)


def _same_rig(read, *, distortion_size=5):
    assert isinstance(read, StereoRig)
    np.testing.assert_allclose(read.left.K, RIG.K1, rtol=1e-12)
    np.testing.assert_allclose(read.right.K, RIG.K2, rtol=1e-12)
    np.testing.assert_allclose(read.left.distortion, RIG.D1[:distortion_size], atol=1e-15)
    np.testing.assert_allclose(read.right.distortion, RIG.D2[:distortion_size], atol=1e-15)
    np.testing.assert_allclose(read.rotation, RIG.R, atol=1e-9)
    np.testing.assert_allclose(read.translation, RIG.T, atol=1e-9)
    assert read.image_size in (SIZE, None)


def _opencv_json(path):
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in {"M1": RIG.K1, "D1": RIG.D1[None], "M2": RIG.K2, "D2": RIG.D2[None],
                       "R": RIG.R, "T": RIG.T[:, None]}.items():  # fmt: skip
        storage.write(key, value)
    storage.release()
    return path


def _kalibr(path):
    path.write_text(kalibr_text(RIG))
    return path


FORMATS = {
    "opencv file": (lambda tmp: write_opencv_rig(tmp / "stereo.yml", RIG), "OpenCV", 5),
    "opencv json": (lambda tmp: _opencv_json(tmp / "stereo.json"), "OpenCV", 5),
    "opencv folder": (lambda tmp: write_opencv_folder(tmp / "calib", RIG), "OpenCV", 5),
    "ros folder": (lambda tmp: write_ros_folder(tmp / "ros", RIG), "ROS camera_info", 5),
    "kalibr": (lambda tmp: _kalibr(tmp / "camchain.yaml"), "Kalibr camchain", 4),
}


@pytest.mark.parametrize("name", FORMATS)
def test_each_format_reads_back_and_rectifies_as_stereo_rectify(tmp_path, name):
    write, kind, coefficients = FORMATS[name]
    rig = read_calibration(write(tmp_path))
    _same_rig(rig, distortion_size=coefficients)
    assert rig.kind == kind
    rectification = rectify_rig(rig, SIZE, "frames")
    camera = rectification.calibration.camera
    np.testing.assert_allclose(camera.K, RIG.rectified_K, rtol=1e-6)
    assert camera.baseline == pytest.approx(RIG.rectified_baseline, rel=1e-6)
    expected = cv2.initUndistortRectifyMap(RIG.K1, RIG.D1, RIG.R1, RIG.P1, SIZE, cv2.CV_32FC1)
    np.testing.assert_allclose(rectification.maps["left"][0], expected[0], atol=1e-3)


def test_rectified_files_stay_rectified(tmp_path):
    """extrinsics.yml alone (R, T, P1, P2: no M2, D2) is a calibration of rectified frames."""
    entries = {"R": RIG.R, "T": RIG.T[:, None], "P1": RIG.P1, "P2": RIG.P2}
    read = read_calibration(write_opencv_yaml(tmp_path / "extrinsics.yml", entries))
    assert isinstance(read, StereoCalibration)
    np.testing.assert_allclose(read.camera.K, RIG.rectified_K, rtol=1e-12)


def test_a_file_with_rectified_projections_is_a_rectified_pair(tmp_path):
    """Everything stereoCalibrate and stereoRectify return in one file (M1 ... T, P1, P2, Q)
    describes frames already rectified: a raw rig needs the file without P1, P2 and Q."""
    entries = {"M1": RIG.K1, "D1": RIG.D1[None], "M2": RIG.K2, "D2": RIG.D2[None], "R": RIG.R,
               "T": RIG.T[:, None], "P1": RIG.P1, "P2": RIG.P2}  # fmt: skip
    read = read_calibration(write_opencv_yaml(tmp_path / "stereo.yml", entries))
    assert isinstance(read, StereoCalibration)
    np.testing.assert_allclose(read.camera.K, RIG.rectified_K, rtol=1e-12)
    del entries["P1"], entries["P2"]
    assert isinstance(read_calibration(write_opencv_yaml(tmp_path / "raw.yml", entries)), StereoRig)


def test_kalibr_equidistant_uses_the_fisheye_model(tmp_path):
    text = kalibr_text(RIG).replace("radtan", "equidistant")
    rig = read_calibration(_write(tmp_path / "camchain.yaml", text))
    assert rig.model == "fisheye"
    rectification = rectify_rig(rig, SIZE, "frames")
    assert rectification.calibration.camera.baseline == pytest.approx(0.12, rel=0.02)
    assert all(np.all(np.isfinite(m)) for maps in rectification.maps.values() for m in maps)


def test_frames_are_rectified_in_linear_light(tmp_path):
    """An sRGB video of a raw rig: decoded, remapped, and encoded again when asked."""
    rng = np.random.default_rng(3)
    frames = [rng.uniform(0, 1, (SIZE[1], SIZE[0], 3)).astype(np.float32) for _ in range(2)]
    videos = [write_video(tmp_path / f"{v}.mkv", frames, frame_rate=10.0) for v in "lr"]
    calib = write_opencv_rig(tmp_path / "rig.yml", RIG)
    source = open_source(videos, calib=calib, exposure=0.01, color="srgb")
    assert "rectified on reading (OpenCV calibration)" in source.describe()
    stored = np.rint(frames[1] * 255) / 255
    expected = rectify_view(source.rectification, "right", srgb_to_linear(stored))
    np.testing.assert_allclose(source.read_frame("right", 1), expected, atol=1e-6)
    encoded = source.read_frame("right", 1, linear=False)
    np.testing.assert_allclose(encoded, linear_to_srgb(expected), atol=1e-5)


# --------------------------------------------------------------------------- bad files


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _opencv(tmp, **changes):
    entries = {"M1": RIG.K1, "D1": RIG.D1[None], "M2": RIG.K2, "D2": RIG.D2[None],
               "R": RIG.R, "T": RIG.T[:, None], "imageSize": SIZE}  # fmt: skip
    entries.update(changes)
    return write_opencv_yaml(tmp / "rig.yml", {k: v for k, v in entries.items() if v is not None})


def _ros(tmp, view="right", old="", new=""):
    folder = write_ros_folder(tmp / "ros", RIG)
    text = (folder / f"{view}.yaml").read_text()
    assert old in text
    (folder / f"{view}.yaml").write_text(text.replace(old, new, 1))
    return folder


def _vertical():
    return {"R": np.eye(3), "T": np.array([[0.0], [-0.12], [0.0]])}


BAD = {
    "missing T": (lambda t: _opencv(t, T=None), "rig.yml: missing 'T'"),
    "missing D1": (lambda t: _opencv(t, D1=None), "missing 'D1'"),
    "M2 not 3x3": (lambda t: _opencv(t, M2=np.eye(2)), "'M2' must be a 3x3 camera matrix"),
    "D1 wrong length": (lambda t: _opencv(t, D1=np.zeros((1, 6))), "'D1' has 6 distortion"),
    "R not a rotation": (lambda t: _opencv(t, R=2 * np.eye(3)), "'R' is not a rotation"),
    "T zero": (lambda t: _opencv(t, T=np.zeros((3, 1))), "'T' is zero"),
    "T non-finite": (
        lambda t: _opencv(t, T=np.array([[-0.12], [np.nan], [0.0]])),
        "matrix 'T' (line 34): 'data': '.Nan' is not a finite number",
    ),
    "vertical baseline": (lambda t: _opencv(t, **_vertical()), "'T' (the rig rectified)"),
    "views swapped": (lambda t: _opencv(t, T=-RIG.T[:, None]), "swapped"),
    "image size": (lambda t: _opencv(t, imageSize=(640, 480)), "is for 640x480 images"),
    "one ROS file": (
        lambda t: _write(t / "left.yaml", ros_camera_info(RIG, "left")),
        "camera_info file of one camera",
    ),
    "ROS no baseline": (
        lambda t: _ros(t, old=f"{RIG.P2[0, 3]:.17g}", new="0"),
        "right.yaml: 'projection_matrix' has no baseline",
    ),
    "ROS bad projection": (
        lambda t: _ros(t, old="rows: 3\n  cols: 4", new="rows: 4\n  cols: 3"),
        "right.yaml: 'projection_matrix' must be 3x4",
    ),
    "ROS model": (
        lambda t: _ros(t, old="plumb_bob", new="kannala"),
        "right.yaml: 'distortion_model' 'kannala' is not supported",
    ),
    "ROS missing key": (
        lambda t: _ros(t, view="left", old="rectification_matrix", new="rect"),
        "left.yaml: missing 'rectification_matrix'",
    ),
    "Kalibr omni": (
        lambda t: _write(t / "camchain.yaml", kalibr_text(RIG).replace("pinhole", "omni", 1)),
        "'cam0': camera_model 'omni' is not supported",
    ),
    "Kalibr no T_cn_cnm1": (
        lambda t: _write(t / "camchain.yaml", kalibr_text(RIG).replace("T_cn_cnm1", "T_x")),
        "'cam1': missing 'T_cn_cnm1'",
    ),
    "Kalibr resolution": (
        lambda t: _write(t / "camchain.yaml", kalibr_text(RIG).replace("[96, 72]", "[96]", 1)),
        "resolution must be [width, height]",
    ),
    "Kalibr invalid YAML": (
        lambda t: _write(t / "camchain.yaml", kalibr_text(RIG) + "cam2: [unclosed\n"),
        "invalid YAML",
    ),
    "empty folder": (lambda t: (t / "empty").mkdir() or t / "empty", "is a folder without"),
}


@pytest.mark.parametrize("name", BAD)
def test_bad_rig_calibration_is_one_line_naming_the_file(tmp_path, name):
    make, fragment = BAD[name]
    frames = [np.full((SIZE[1], SIZE[0], 3), 0.5, np.float32)] * 2
    (tmp_path / "in").mkdir()
    videos = [write_video(tmp_path / "in" / f"{v}.mkv", frames, frame_rate=10) for v in "lr"]
    calib = make(tmp_path / "in")
    with pytest.raises(InputError) as caught:
        open_source(videos, calib=calib, exposure=0.01)
    message = str(caught.value)
    assert fragment in message and "\n" not in message, message
    result = run_cli("deblur", *videos, "--calib", calib, "--exposure", 0.01, "-o", tmp_path / "o")
    err = result.stderr.strip().splitlines()
    assert result.code == 2 and len(err) == 1 and str(calib) in err[0], result.stderr
    assert not (tmp_path / "o").exists()
