"""KITTI scene flow 2015, stereo/flow 2012 and raw folders: reading, and every malformed kind
of calibration or layout as a one-line error."""

import numpy as np
import pytest

from stereodeblur.cli import main
from stereodeblur.errors import InputError
from stereodeblur.io.camera_json import read_camera
from stereodeblur.io.formats import read_png, srgb_to_linear, write_png
from stereodeblur.io.kitti import (
    KITTI_FRAME_RATE,
    kitti_camera,
    open_kitti,
    read_timestamps,
)
from stereodeblur.io.sources import detect_source, open_source
from tests.io.stereo_layouts import (
    to_u8,
    write_kitti_2012,
    write_kitti_2015,
    write_kitti_raw,
)

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])
BASELINE = 0.54
NUM_FRAMES = 3

# Lines of a real KITTI calib_cam_to_cam.txt (2011_09_26), as KITTI writes them.
REAL_KITTI = """P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 \
7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03
P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 \
1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03
"""


def _frames(seed, grey=False):
    rng = np.random.default_rng(seed)
    shape = (24, 32) if grey else (24, 32, 3)
    return [to_u8(rng.random(shape)) / 255.0 for _ in range(NUM_FRAMES)]


@pytest.fixture(scope="module")
def clips():
    return _frames(1), _frames(2)


@pytest.fixture
def kitti(tmp_path, clips):
    return write_kitti_2015(tmp_path / "kitti", *clips, K, BASELINE)


def test_real_kitti_projection_matrices_give_the_colour_baseline(tmp_path):
    (tmp_path / "calib.txt").write_text("calib_time: 09-Jan-2012 13:57:47\n\n" + REAL_KITTI)
    camera, _ = kitti_camera(tmp_path / "calib.txt", "P_rect_02", "P_rect_03")
    assert camera.fx == 721.5377 and tuple(camera.K[:2, 2]) == (609.5593, 172.854)
    # About 0.54 m (KITTI's rig); first order: difference of P[0][3] over fx.
    assert camera.baseline == pytest.approx((44.85728 + 339.5242) / 721.5377, rel=1e-4)


def test_scene_flow_2015(kitti, clips):
    assert detect_source([kitti]) == "kitti-2015"
    source = open_source(kitti, exposure=0.02)
    assert source.kind == "kitti-2015" and source.num_frames == NUM_FRAMES
    assert source.shape == (24, 32) and source.channels == 3
    np.testing.assert_allclose(source.info.camera.K, K, rtol=1e-15)
    assert source.info.camera.baseline == pytest.approx(BASELINE, rel=1e-12)
    assert source.info.exposure.frame_rate == KITTI_FRAME_RATE
    for view, frames in zip(("left", "right"), clips, strict=True):
        for i, frame in enumerate(frames):
            stored = frame.astype(np.float32)
            np.testing.assert_array_equal(source.read_frame(view, i, linear=False), stored)
            np.testing.assert_array_equal(source.read_frame(view, i), srgb_to_linear(stored))
    assert not source.has_gt("flow", "left", 0)
    assert source.frame_path("right", 2).name == "000000_12.png"


def test_stereo_flow_2012_grey(tmp_path):
    left, right = _frames(3, grey=True), _frames(4, grey=True)
    root = write_kitti_2012(tmp_path / "kitti2012", left, right, K, BASELINE)
    source = open_source(root, exposure=0.02, frame_rate=10)
    assert source.kind == "kitti-2012" and source.channels == 1
    assert source.info.camera.baseline == pytest.approx(BASELINE, rel=1e-12)
    np.testing.assert_array_equal(
        source.read_frame("right", 1), srgb_to_linear(right[1].astype(np.float32))
    )


def test_raw_recording_takes_its_frame_rate_from_timestamps(tmp_path, clips):
    drive = write_kitti_raw(tmp_path / "2011_09_26", *clips, K, BASELINE, frame_rate=9.5)
    source = open_source(drive, exposure=0.02)
    assert source.kind == "kitti-raw"
    assert source.info.exposure.frame_rate == pytest.approx(9.5, rel=1e-7)  # ns stamps
    np.testing.assert_array_equal(
        source.read_frame("left", 2), srgb_to_linear(clips[0][2].astype(np.float32))
    )
    stamps = read_timestamps(drive / "image_02" / "timestamps.txt")
    np.testing.assert_allclose(np.diff(stamps), 1 / 9.5, atol=1e-9)


@pytest.mark.parametrize("layout", ["kitti-2015", "kitti-2012", "kitti-raw"])
def test_kitti_is_srgb_unless_told_linear(layout, tmp_path, clips):
    """KITTI's PNGs are camera output: read as sRGB (linearised); color='linear' overrides."""
    writers = {"kitti-2015": write_kitti_2015, "kitti-2012": write_kitti_2012}
    root = writers.get(layout, write_kitti_raw)(tmp_path / "2011_09_26", *clips, K, BASELINE)
    stored = clips[0][1].astype(np.float32)
    source = open_source(root, exposure=0.02)
    assert source.info.color == "srgb"
    np.testing.assert_array_equal(source.read_frame("left", 1), srgb_to_linear(stored))
    assert source.read_frame("left", 1).mean() < stored.mean()  # the curve darkens midtones
    linear = open_source(root, exposure=0.02, color="linear")
    assert linear.info.color == "linear"
    np.testing.assert_array_equal(linear.read_frame("left", 1), stored)


def test_results_are_written_back_in_the_inputs_encoding(kitti, clips, tmp_path):
    """A frame read linear and written by the output's writer (as a run does) gives back the
    stored sRGB values, and the output's camera.json says "srgb"."""
    from stereodeblur.io.scene import SceneWriter

    source = open_source(kitti, exposure=0.02)
    writer = SceneWriter(tmp_path / "out", source.info)
    path = writer.write_frame("left", 1, source.read_frame("left", 1))
    np.testing.assert_allclose(read_png(path), clips[0][1], atol=1e-4)
    assert read_camera(tmp_path / "out").color == "srgb"
    assert '"color": "srgb"' in (tmp_path / "out" / "camera.json").read_text()


def test_raw_recording_warns_of_dropped_frames(tmp_path, clips):
    drive = write_kitti_raw(tmp_path / "2011_09_26", *clips, K, BASELINE)
    stamps = drive / "image_02" / "timestamps.txt"
    lines = stamps.read_text().splitlines()
    lines[2] = "2011-09-26 13:02:25.500000000"  # 0.45 s after the previous frame
    stamps.write_text("\n".join(lines) + "\n")
    source = open_kitti(drive, exposure=0.02)
    assert len(source.warnings) == 1 and "dropped" in source.warnings[0]


def test_several_sequences_need_a_choice(kitti, clips):
    write_kitti_2015(kitti, *clips, K, BASELINE * 2, sequence=7, first=0)
    with pytest.raises(InputError, match="2 sequences .*choose one with sequence") as error:
        open_source(kitti, exposure=0.02)
    assert error.value.parameter == "sequence"
    seven = open_source(kitti, exposure=0.02, sequence=7)
    assert seven.info.camera.baseline == pytest.approx(2 * BASELINE)
    assert seven.frame_path("left", 0).name == "000007_00.png"
    assert open_source(kitti, exposure=0.02, sequence="000000").num_frames == NUM_FRAMES


def _edit(path, old, new):
    text = path.read_text()
    assert old in text, (old, path)
    path.write_text(text.replace(old, new, 1))


def _calib(root):
    return root / "calib_cam_to_cam" / "000000.txt"


def _p_rect(root, key):
    line = next(x for x in _calib(root).read_text().splitlines() if x.startswith(key + ":"))
    return line


MALFORMED = {
    "missing calibration file": (lambda r: _calib(r).unlink(), "not found"),
    "missing key": (lambda r: _edit(_calib(r), _p_rect(r, "P_rect_03"), ""), "'P_rect_03'"),
    "too few numbers": (
        lambda r: _edit(_calib(r), _p_rect(r, "P_rect_02"), _p_rect(r, "P_rect_02")[:-25]),
        "expected 12",
    ),
    "not a number": (lambda r: _edit(_calib(r), "P_rect_02: 40", "P_rect_02: forty"), "'forty'"),
    "duplicate key": (
        lambda r: _calib(r).write_text(_calib(r).read_text() + _p_rect(r, "P_rect_02") + "\n"),
        "appears twice",
    ),
    "line without a key": (
        lambda r: _calib(r).write_text("just some words\n" + _calib(r).read_text()),
        "line 1",
    ),
    "swapped views": (
        lambda r: (
            _edit(_calib(r), "P_rect_02:", "P_rect_XX:")
            or _edit(_calib(r), "P_rect_03:", "P_rect_02:")
            or _edit(_calib(r), "P_rect_XX:", "P_rect_03:")
        ),
        "swapped",
    ),
    "different focal lengths": (
        lambda r: _edit(_calib(r), "P_rect_03: 40 ", "P_rect_03: 41 "),
        "different fx",
    ),
    "unrectified size": (
        lambda r: _edit(_calib(r), "S_rect_02: 3.200000e+01", "S_rect_02: 1.392000e+03"),
        "unrectified",
    ),
    "missing right frame": (
        lambda r: (r / "image_3" / "000000_11.png").unlink(),
        "000000_11.png",
    ),
    "gap in the frames": (
        lambda r: (r / "image_2" / "000000_11.png").unlink(),
        "000000_11.png",
    ),
    "frames of different sizes": (
        lambda r: write_png(r / "image_3" / "000000_12.png", np.zeros((10, 10, 3)), bit_depth=8),
        "000000_12.png",
    ),
}


@pytest.mark.parametrize("kind", list(MALFORMED))
def test_malformed_kitti_is_one_line_naming_the_file(kind, kitti, tmp_path, capsys):
    damage, fragment = MALFORMED[kind]
    damage(kitti)
    out = tmp_path / "out"
    code = main(["deblur", str(kitti), "--exposure", "0.02", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("stereodeblur: error: ")
    assert str(kitti) in err[0] and fragment in err[0], err[0]
    assert not out.exists()


RAW_MALFORMED = {
    "no calibration": (lambda d: (d.parent / "calib_cam_to_cam.txt").unlink(), "calib_cam_to_cam"),
    "missing timestamps": (lambda d: (d / "image_02" / "timestamps.txt").unlink(), "timestamps"),
    "malformed timestamp": (
        lambda d: _edit(d / "image_02" / "timestamps.txt", "2011-09-26 13:02:25.05", "yesterday"),
        "line 2",
    ),
    "time going backwards": (
        lambda d: _edit(d / "image_02" / "timestamps.txt", "13:02:25.1", "13:02:24.1"),
        "increase",
    ),
    "too few timestamps": (
        lambda d: (d / "image_02" / "timestamps.txt").write_text(
            "2011-09-26 13:02:25.000000000\n2011-09-26 13:02:25.050000000\n"
        ),
        "2 timestamps for 3 frames",
    ),
}


@pytest.mark.parametrize("kind", list(RAW_MALFORMED))
def test_malformed_raw_recording_is_one_line(kind, tmp_path, clips, capsys):
    drive = write_kitti_raw(tmp_path / "2011_09_26", *clips, K, BASELINE)
    damage, fragment = RAW_MALFORMED[kind]
    damage(drive)
    out = tmp_path / "out"
    code = main(["deblur", str(drive), "--exposure", "0.02", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and str(tmp_path) in err[0] and fragment in err[0], err
    assert not out.exists()


def test_missing_2012_calibration_key(tmp_path, capsys):
    root = write_kitti_2012(tmp_path / "k", _frames(5, True), _frames(6, True), K, BASELINE)
    calib = root / "calib" / "000000.txt"
    calib.write_text("\n".join(x for x in calib.read_text().splitlines() if x[:3] != "P1:"))
    code = main(["deblur", str(root), "--exposure", "0.02", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and str(calib) in err[0] and "'P1'" in err[0]
