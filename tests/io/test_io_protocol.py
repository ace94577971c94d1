"""Every input kind satisfies the StereoScene protocol; check_readable finds bad frames up front."""

import inspect
import re
import subprocess
import sys

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.formats import check_png_file, write_png
from stereodeblur.io.frame_source import FrameSource
from stereodeblur.io.protocol import StereoScene
from stereodeblur.io.readable import check_files, check_readable
from stereodeblur.io.scene import scene_path
from stereodeblur.io.sources import open_source
from stereodeblur.io.video import write_video
from tests.conftest import write_tiny_scene
from tests.io.stereo_layouts import to_u8, write_kitti_2015, write_video_pair

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])
MEMBERS = [
    "root", "name", "kind", "paths", "warnings", "info", "num_frames", "shape", "channels",
    "numbering",
    "read_frame", "frame_label", "has_gt", "gt_path", "read_gt_disparity", "read_gt_flow",
    "read_gt_mixed", "read_gt_sharp", "describe",
]  # fmt: skip


def _frames(seed, count=3):
    rng = np.random.default_rng(seed)
    return [to_u8(rng.random((24, 32, 3))) / 255.0 for _ in range(count)]


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    root = tmp_path_factory.mktemp("sources")
    scene = write_tiny_scene(root / "scene", num_frames=3)
    kitti = write_kitti_2015(root / "kitti", _frames(1), _frames(2), K, 0.5)
    video = write_video_pair(root / "video", _frames(3), _frames(4), K, 0.5, frame_rate=25.0)
    return {
        "scene": open_source(scene),
        "kitti": open_source(kitti, exposure=0.01),
        "video": open_source(video[:2], calib=video[2], exposure=0.01),
    }


@pytest.mark.parametrize("kind", ["scene", "kitti", "video"])
def test_every_source_satisfies_the_protocol(kind, sources):
    source = sources[kind]
    assert isinstance(source, StereoScene)
    for member in MEMBERS:
        assert hasattr(source, member), member
    assert isinstance(source.paths, tuple) and all(hasattr(p, "resolve") for p in source.paths)
    assert isinstance(source.warnings, tuple) and source.name and source.kind
    h, w = source.shape
    assert (
        source.describe() == f"{source.kind} {source.name}: {source.num_frames} frames of {w}x{h}"
    )
    assert source.read_frame("right", 1).shape[:2] == (h, w)
    assert str(source.root) in source.frame_label("left", 1) or source.kind == "kitti-2015"


def test_the_protocol_names_what_the_contract_names():
    methods = {n for n, v in vars(StereoScene).items() if inspect.isfunction(v) and n[0] != "_"}
    assert set(StereoScene.__annotations__) | methods == set(MEMBERS)

    class Partial:  # everything but describe()
        def __getattr__(self, name):
            if name in MEMBERS and name != "describe":
                return None
            raise AttributeError(name)

    assert not isinstance(Partial(), StereoScene)


def test_scene_protocol_values(sources):
    scene = sources["scene"]
    assert (scene.kind, scene.name, scene.paths, scene.warnings) == (
        "scene", "scene", (scene.root,), ()
    )  # fmt: skip
    assert scene.frame_label("left", 2) == str(scene_path(scene.root, "frame", "left", 2))
    assert scene.has_gt("disparity", "left", 1) and not scene.has_gt("mixed", "left", 1)


@pytest.mark.parametrize("kind", ["kitti", "video"])
@pytest.mark.parametrize("what", ["disparity", "flow", "mixed", "sharp"])
def test_frame_sources_have_no_ground_truth(kind, what, sources):
    source = sources[kind]
    assert isinstance(source, FrameSource)
    assert source.has_gt(what, "left", 1) is False
    with pytest.raises(InputError, match=f"no ground-truth {what} for the left view of frame 1"):
        getattr(source, f"read_gt_{what}")("left", 1)
    with pytest.raises(InputError, match=re.escape(f"{source.name} ({source.kind})")):
        source.gt_path(what, "left", 1)


def test_sources_only_dispatch_no_import_circle():
    # The readers do not import the dispatcher: importing them leaves io.sources unloaded.
    code = (
        "import sys; import stereodeblur.io.kitti, stereodeblur.io.video, "
        "stereodeblur.io.frame_source, stereodeblur.io.readable; "
        "print('stereodeblur.io.sources' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    import stereodeblur.io.sources as sources

    assert not hasattr(sources, "FrameSource")  # it lives in io.frame_source only


# --------------------------------------------------------------------------- check_readable


def test_check_readable_accepts_good_inputs(sources):
    for source in sources.values():
        check_readable(source, ("left", "right"), range(source.num_frames))
        check_readable(source)


def test_check_readable_names_a_truncated_frame(tmp_path):
    scene = open_source(write_tiny_scene(tmp_path / "s", num_frames=3, gt=False))
    path = scene.frame_path("right", 2)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])  # header intact, data cut
    check_readable(scene, ("left", "right"), [0, 1])  # frame 2 not needed
    check_readable(scene, ("left",), [2])
    with pytest.raises(InputError, match=f"truncated PNG file {path}"):
        check_readable(scene, ("left", "right"), [0, 1, 2])


def test_check_readable_names_a_replaced_frame_of_another_size(tmp_path):
    scene = open_source(write_tiny_scene(tmp_path / "s", num_frames=3, gt=False))
    path = scene.frame_path("left", 1)
    write_tiny_scene(tmp_path / "big", num_frames=2, size=(48, 40), gt=False)
    path.write_bytes((tmp_path / "big" / "left" / "000000.png").read_bytes())
    with pytest.raises(InputError, match=rf"{path} is 48x40 RGB, expected 40x32 RGB"):
        check_readable(scene, ("left",), [0, 1])
    path.write_bytes(b"not a png")
    with pytest.raises(InputError, match=f"not a PNG file: {path}"):
        check_readable(scene, ("left",), [1])
    path.unlink()
    with pytest.raises(FileNotFoundError, match=str(path)):
        check_readable(scene, ("left",), [1])


def test_check_readable_kitti_frame(tmp_path):
    root = write_kitti_2015(tmp_path / "kitti", _frames(1), _frames(2), K, 0.5)
    source = open_source(root, exposure=0.01)
    path = source.frame_path("right", 1)
    path.write_bytes(path.read_bytes()[:-12])  # IEND chunk cut off
    with pytest.raises(InputError, match=f"truncated PNG file {path}: no end chunk"):
        check_readable(source)


def test_check_readable_video_shortened_after_opening(tmp_path):
    left, right, calib = write_video_pair(tmp_path, _frames(1, 5), _frames(2, 5), K, 0.5)
    source = open_source([left, right], calib=calib, exposure=0.01)
    write_video(right, [to_u8(f) for f in _frames(3, 2)], frame_rate=20.0)
    check_readable(source, ("left", "right"), [0, 1])
    with pytest.raises(InputError, match=rf"{right} has 2 frames now, expected at least 4"):
        check_readable(source, ("left", "right"), [2, 3])
    right.write_text("junk")
    with pytest.raises(InputError, match=f"{right} is not a readable video"):
        check_readable(source, ("right",), [0])


@pytest.mark.parametrize(
    "views, indices, fragment",
    [(("middle",), [0], "view must be"), (("left",), [3], "out of range 0..2"),
     (("left",), [-1], "out of range")],
)  # fmt: skip
def test_check_readable_bad_arguments(views, indices, fragment, sources):
    with pytest.raises(InputError, match=fragment):
        check_readable(sources["scene"], views, indices)


def test_png_layout_rejects_data_without_idat(tmp_path):
    scene = write_tiny_scene(tmp_path / "s", num_frames=2, gt=False)
    data = (scene / "left" / "000000.png").read_bytes()
    bad = tmp_path / "bad.png"
    bad.write_bytes(data[:33] + b"\x00\x00\x00\x00IEND\xaeB`\x82")
    with pytest.raises(InputError, match="no image data"):
        check_png_file(bad)
    bad.write_bytes(data[:33] + b"\xff\xff\xff\xffIDAT")
    with pytest.raises(InputError, match="truncated PNG file"):
        check_png_file(bad)


def test_check_files_reads_ground_truth_headers(tmp_path):
    scene = open_source(write_tiny_scene(tmp_path / "s", num_frames=3))
    size = (scene.shape[1], scene.shape[0])
    paths = [scene.gt_path(kind, "left", 1) for kind in ("sharp", "disparity", "flow")]
    check_files(paths, size=size)
    with pytest.raises(InputError, match=r"000001.pfm is 40x32, expected 41x32 like the frames"):
        check_files(paths[1:], size=(41, 32))
    disparity, flow = paths[1], paths[2]
    flow.write_bytes(flow.read_bytes()[:-8])
    with pytest.raises(InputError, match=f"corrupt FLO file {flow}: expected 10240 data bytes"):
        check_files(paths, size=size)
    disparity.write_bytes(b"Pf\n40 32\n-1\n" + bytes(16))
    with pytest.raises(InputError, match=f"corrupt PFM file {disparity}: expected 5120 data"):
        check_files([disparity])
    with pytest.raises(FileNotFoundError, match="000002.flo"):
        check_files([scene.gt_path("flow", "left", 2)])
    with pytest.raises(InputError, match="expected a .png, .pfm or .flo file"):
        check_files([scene.root / "camera.json"])


def test_kitti_frames_after_the_first_are_checked_by_check_readable(tmp_path):
    root = write_kitti_2015(tmp_path / "kitti", _frames(1), _frames(2), K, 0.5)
    path = root / "image_3" / "000000_12.png"
    write_png(path, np.zeros((24, 30, 3)), bit_depth=8)
    source = open_source(root, exposure=0.01)
    check_readable(source, ("left", "right"), [0, 1])
    with pytest.raises(InputError, match=rf"{path} is 30x24 RGB, expected 32x24 RGB"):
        check_readable(source)
    path.write_bytes(b"")
    with pytest.raises(InputError, match=f"not a PNG file: {path}"):
        check_readable(source, ("right",), [2])
