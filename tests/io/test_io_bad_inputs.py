"""Bad inputs: each a one-line error naming the file or value and the
accepted range, exit code 2 from the command line, nothing else on the terminal."""

import hashlib
import json
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from stereodeblur.cli import main
from stereodeblur.errors import InputError
from stereodeblur.io.calibration import read_stereo_calibration
from stereodeblur.io.formats import MAX_PIXELS, read_png, read_png_header
from stereodeblur.io.intrinsics import check_intrinsics
from stereodeblur.io.scene import MIN_FRAME_SIZE, open_scene
from stereodeblur.io.sources import open_source
from stereodeblur.io.video import write_video
from stereodeblur.sceneflow.storage import load_sceneflow
from tests.conftest import write_tiny_scene
from tests.io.stereo_layouts import (
    opencv_calibration,
    to_u8,
    write_kitti_2015,
    write_opencv_yaml,
    write_video_pair,
)

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])
SIZE = (32, 24)  # width, height


def _one_line(error) -> str:
    text = str(error.value)
    assert "\n" not in text and "Traceback" not in text
    return text


def _cli(capfd, *argv):
    """Exit code and the stderr lines of ``stereodeblur ARGV`` (progress lines dropped)."""
    code = main([str(a) for a in argv])
    captured = capfd.readouterr()
    lines = [line for line in captured.err.strip().splitlines() if not line.startswith("[")]
    return code, lines


def _tree_digest(root: Path) -> str:
    """Names and bytes of every file under ``root``."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        digest.update(str(path.relative_to(root)).encode())
        if path.is_file() and not path.is_symlink():
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _assert_refused(capfd, fragments, *argv, output=None):
    """Exit 2, one line with every fragment, and (with ``output``) nothing written or changed
    in the folder that holds the output and the inputs."""
    before = None if output is None else _tree_digest(output.parent)
    code, lines = _cli(capfd, *argv)
    if before is not None:
        assert _tree_digest(output.parent) == before
    assert code == 2, lines
    assert len(lines) == 1 and lines[0].startswith("stereodeblur: error: "), lines
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    if output is not None:
        assert not output.exists()
    return lines[0]


def _frames(seed, count=3, size=SIZE):
    rng = np.random.default_rng(seed)
    return [to_u8(rng.random((size[1], size[0], 3))) / 255.0 for _ in range(count)]


# --------------------------------------------------------------------------- camera.json


def test_camera_json_that_is_a_directory(tmp_path, capfd):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2, gt=False)
    (scene / "camera.json").unlink()
    (scene / "camera.json").mkdir()
    expected = f"{scene / 'camera.json'} is a directory, expected a JSON file"
    with pytest.raises(InputError) as error:
        open_scene(scene)
    assert _one_line(error) == expected
    out = tmp_path / "out"
    line = _assert_refused(capfd, [expected], "deblur", scene, "-o", out, output=out)
    assert "camera.json/camera.json" not in line


# --------------------------------------------------------------------------- saved scene flow


@pytest.mark.parametrize("kind", ["json", "pickled npz", "empty npz", "truncated npz", "text"])
def test_junk_scene_flow_file(kind, tmp_path):
    path = tmp_path / ("camera.json" if kind == "json" else "flow.npz")
    if kind == "json":
        path.write_text(json.dumps({"format": "stereo-video/1"}))
    elif kind == "pickled npz":
        keys = ["format", "labels", "normals", "twists", "occlusion", "view", "K", "baseline"]
        np.savez(path, **{k: np.array([object()], dtype=object) for k in keys})
    elif kind == "empty npz":
        np.savez(path, other=np.zeros(2))
    elif kind == "truncated npz":
        np.savez(path, labels=np.zeros((40, 40)))
        path.write_bytes(path.read_bytes()[:200])
    else:
        path.write_text("just text\n")
    with pytest.raises(InputError) as error:
        load_sceneflow(path)
    text = _one_line(error)
    assert str(path) in text and "unsafe" not in text and "allow_pickle" not in text


# --------------------------------------------------------------------------- videos


@pytest.fixture(scope="module")
def videos(tmp_path_factory):
    folder = tmp_path_factory.mktemp("videos")
    return write_video_pair(folder, _frames(1, 8), _frames(2, 8), K, 0.1, frame_rate=25.0)


def test_text_file_as_video_is_one_line_without_ffmpeg_noise(videos, tmp_path, capfd):
    left, _, calib = videos
    text = tmp_path / "notes.mp4"
    text.write_text("this is not a video\n" * 20)
    capfd.readouterr()
    with pytest.raises(InputError) as error:
        open_source([left, text], calib=calib, exposure=0.01)
    assert _one_line(error).startswith(f"{text} is not a readable video")
    assert capfd.readouterr().err == ""  # no OpenCV / FFmpeg log lines
    out = tmp_path / "out"
    _assert_refused(capfd, [str(text), "not a readable video"],
                    "deblur", left, text, "--calib", calib, "--exposure", "0.01", "-o", out,
                    output=out)  # fmt: skip


@pytest.mark.parametrize("image", ["png", "jpg"])
def test_still_image_as_video_is_refused(image, videos, tmp_path, capfd):
    left, _, calib = videos
    import cv2

    path = tmp_path / f"frame.{image}"
    cv2.imwrite(str(path), np.zeros((SIZE[1], SIZE[0], 3), np.uint8))
    with pytest.raises(InputError) as error:
        open_source([left, path], calib=calib, exposure=0.01)
    text = _one_line(error)
    assert text.startswith(f"{path} is a still image") and "not a video" in text
    assert "frames per second" not in text
    assert capfd.readouterr().err == ""
    out = tmp_path / "out"
    argv = ["deblur", left, path, "--calib", calib, "--exposure", "0.01", "-o", out]
    _assert_refused(capfd, [f"{path} is a still image"], *argv, output=out)


def test_videos_of_8_and_4_frames_use_4_with_a_warning(videos, tmp_path):
    left, _, calib = videos
    short = write_video(tmp_path / "short.mkv", [to_u8(f) for f in _frames(3, 4)], frame_rate=25)
    source = open_source([left, short], calib=calib, exposure=0.01)
    assert source.num_frames == 4
    assert source.warnings == (
        f"{left} has 8 frames and {short} 4: using the first 4 of both",
    )  # fmt: skip


def test_one_frame_video_is_refused(videos, tmp_path):
    left, _, calib = videos
    single = write_video(tmp_path / "one.mkv", [to_u8(_frames(4, 1)[0])], frame_rate=25)
    with pytest.raises(
        InputError, match=re.escape(f"{single} has 1 frame: a video needs at least 2")
    ):
        open_source([left, single], calib=calib, exposure=0.01)


# --------------------------------------------------------------------------- intrinsics


BAD_INTRINSICS = {
    # (row, column, value): the accepted range for 32x24 images in the message
    "cx far left": ((0, 2, -5000.0), "cx = -5000 is outside [-0.5 W, 1.5 W] = [-16, 48]"),
    "tiny fx": ((0, 0, 1e-9), "fx = 1e-09 is outside [W/20, 1000 W] = [1.6, 32000]"),
    "huge fy": ((1, 1, 1e7), "fy = 1e+07 is outside [H/20, 1000 H] = [1.2, 24000]"),
    "cy far below": ((1, 2, 400.0), "cy = 400 is outside [-0.5 H, 1.5 H] = [-12, 36]"),
}


def _bad_K(change):
    (row, column, value) = change
    bad = K.copy()
    bad[row, column] = value
    if (row, column) == (0, 0):
        bad[1, 1] = value  # rectified: fx = fy
    return bad


@pytest.mark.parametrize("case", list(BAD_INTRINSICS))
def test_one_rule_for_intrinsics_in_camera_json_yaml_and_kitti(case, videos, tmp_path, capfd):
    change, message = BAD_INTRINSICS[case]
    bad = _bad_K(change)
    # camera.json of a scene folder (its frames give the size)
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2, size=SIZE, gt=False)
    data = json.loads((scene / "camera.json").read_text())
    data["K"] = bad.tolist()
    (scene / "camera.json").write_text(json.dumps(data))
    with pytest.raises(InputError) as error:
        open_scene(scene)
    assert _one_line(error) == f"{scene / 'camera.json'}: {message} for 32x24 images"
    out = tmp_path / "out"
    _assert_refused(capfd, [message], "deblur", scene, "-o", out, output=out)
    # the same camera as a camera.json calibration of a video pair
    left, right, _ = videos
    with pytest.raises(InputError, match=re.escape(f"{scene / 'camera.json'}: {message}")):
        open_source([left, right], calib=scene / "camera.json", exposure=0.01)
    # as an OpenCV YAML calibration
    yaml = write_opencv_yaml(tmp_path / "calib.yml", opencv_calibration(bad, 0.1, SIZE))
    read_stereo_calibration(yaml)  # the file alone is fine: the rule needs the image size
    with pytest.raises(InputError) as error:
        open_source([left, right], calib=yaml, exposure=0.01)
    assert _one_line(error) == f"{yaml}: {message} for 32x24 images"
    argv = ["deblur", left, right, "--calib", yaml, "--exposure", "0.01", "-o", out]
    _assert_refused(capfd, [str(yaml), message], *argv, output=out)
    # as a KITTI calibration
    kitti = write_kitti_2015(tmp_path / "kitti", _frames(5, 2), _frames(6, 2), bad, 0.5)
    with pytest.raises(InputError, match=re.escape(f"P_rect_02: {message}")):
        open_source(kitti, exposure=0.01)


def test_real_cameras_pass_the_rule():
    check_intrinsics([[721.5, 0, 609.6], [0, 721.5, 172.9], [0, 0, 1]], (1242, 375), "KITTI")
    check_intrinsics([[70.0, 0, -10.0], [0, 70.0, 30.0], [0, 0, 1]], (32, 24), "crop")
    check_intrinsics([[2.0, 0, 16.0], [0, 2.0, 12.0], [0, 0, 1]], (32, 24), "fisheye-ish")
    with pytest.raises(InputError, match=r"skew K\[0\]\[1\] = 50 is outside \[-fx, fx\]"):
        check_intrinsics([[40.0, 50.0, 16.0], [0, 40.0, 12.0], [0, 0, 1]], (32, 24), "x")


# --------------------------------------------------------------------------- frame sizes


@pytest.mark.parametrize("side", [1, 8, MIN_FRAME_SIZE - 1])
def test_frames_below_the_minimum_size_name_the_file(side, tmp_path, capfd):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2, size=(side, side + 20), gt=False)
    expected = (
        f"{scene / 'left' / '000000.png'} is {side}x{side + 20}: frames must be at least "
        f"{MIN_FRAME_SIZE}x{MIN_FRAME_SIZE} pixels"
    )
    with pytest.raises(InputError) as error:
        open_scene(scene)
    assert _one_line(error) == expected
    out = tmp_path / "out"
    line = _assert_refused(capfd, [expected], "deblur", scene, "-o", out, output=out)
    assert "left_t" not in line


def test_minimum_size_is_accepted_and_deblurs(tmp_path, capfd):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=3, size=(MIN_FRAME_SIZE,) * 2)
    assert open_scene(scene).shape == (MIN_FRAME_SIZE, MIN_FRAME_SIZE)
    # The whole pipeline (scene flow, dense flow, census) runs at the minimum size.
    out = tmp_path / "out"
    code, lines = _cli(capfd, "deblur", scene, "-o", out, "--frames", "2", "--views", "left", "-q")
    assert code == 0, lines
    assert read_png(out / "left" / "000002.png").shape == (MIN_FRAME_SIZE, MIN_FRAME_SIZE, 3)


def test_small_kitti_and_video_frames_are_refused(tmp_path):
    kitti = write_kitti_2015(tmp_path / "kitti", _frames(1, 2, (8, 8)), _frames(2, 2, (8, 8)), K,
                             0.5)  # fmt: skip
    with pytest.raises(InputError, match=r"000000_10.png is 8x8: frames must be at least"):
        open_source(kitti, exposure=0.01)
    small = np.array([[4.0, 0, 4.0], [0, 4.0, 4.0], [0, 0, 1]])
    left, right, calib = write_video_pair(tmp_path / "v", _frames(3, 2, (8, 8)),
                                          _frames(4, 2, (8, 8)), small, 0.1)  # fmt: skip
    with pytest.raises(InputError, match=re.escape(f"{left} is 8x8: frames must be at least")):
        open_source([left, right], calib=calib, exposure=0.01)


def _png_declaring(width: int, height: int) -> bytes:
    """A small PNG file whose header declares ``width x height`` (8-bit grey)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data)
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


@pytest.mark.parametrize("size", [(60000, 60000), (2**21, 20), (20, 2**21)])
def test_huge_png_header_is_refused_before_decoding(size, tmp_path, capfd):
    path = tmp_path / "huge.png"
    path.write_bytes(_png_declaring(*size))
    for reader in (read_png_header, read_png):
        with pytest.raises(InputError) as error:
            reader(path)
        text = _one_line(error)
        assert text.startswith(f"{path} is {size[0]}x{size[1]}: images may have at most")
        assert str(MAX_PIXELS) in text
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2, gt=False)
    (scene / "right" / "000001.png").write_bytes(_png_declaring(*size))
    out = tmp_path / "out"
    _assert_refused(capfd, [str(scene / "right" / "000001.png"), str(MAX_PIXELS)],
                    "deblur", scene, "-o", out, output=out)  # fmt: skip


def test_quiet_stderr_restores_fd_2_after_concurrent_use():
    import os
    import threading
    import time

    from stereodeblur.io.formats import quiet_stderr

    before = os.fstat(2)
    null = os.stat(os.devnull)

    silenced = []

    def work(seed):
        for k in range(20):
            with quiet_stderr():
                inside = os.fstat(2)
                silenced.append((inside.st_dev, inside.st_ino) == (null.st_dev, null.st_ino))
                time.sleep(0.0005 * ((seed + k) % 3))

    threads = [threading.Thread(target=work, args=(i,)) for i in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(silenced) == 120 and all(silenced)
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("baseline", 1e306, "baseline must be a number in [1e-06, 1e+06] scene units"),
        ("baseline", 1e-9, "baseline must be a number in [1e-06, 1e+06] scene units"),
        ("frame_rate", 1e300, "frame_rate must be a number in (0, 1e+06] per second"),
    ],
)
def test_absurd_baseline_or_frame_rate_in_camera_json(key, value, message, tmp_path, capfd):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2, size=SIZE, gt=False)
    data = json.loads((scene / "camera.json").read_text())
    data[key] = value
    (scene / "camera.json").write_text(json.dumps(data))
    out = tmp_path / "out"
    _assert_refused(capfd, [str(scene / "camera.json"), message], "deblur", scene, "-o", out,
                    output=out)  # fmt: skip
