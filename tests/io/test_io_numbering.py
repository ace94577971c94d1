"""Frame numbers and names of sources (stereodeblur.io.numbering): KITTI keeps its own."""

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.numbering import SCENE_NUMBERING, FrameNumbering
from stereodeblur.io.sources import open_source
from tests.io.stereo_layouts import to_u8, write_kitti_2012, write_kitti_2015, write_kitti_raw

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])


def test_names_and_numbers():
    kitti = FrameNumbering(first=10, digits=2, prefix="000005_")
    assert (kitti.name(0), kitti.name(1), kitti.number(1), kitti.index(11)) == (
        "000005_10", "000005_11", 11, 1
    )  # fmt: skip
    assert SCENE_NUMBERING.name(42) == "000042"
    assert FrameNumbering(digits=10).name(42) == "0000000042"


@pytest.mark.parametrize("bad", [{"first": -1}, {"digits": 0}, {"prefix": "a/b"}])
def test_bad_numberings(bad):
    with pytest.raises(InputError):
        FrameNumbering(**bad)


@pytest.mark.parametrize(
    ("layout", "name"),
    [("kitti-2015", "000003_11"), ("kitti-2012", "000003_11"), ("kitti-raw", "0000000001")],
)
def test_kitti_sources_keep_their_frame_names(layout, name, tmp_path):
    rng = np.random.default_rng(0)
    frames = [to_u8(rng.random((24, 32))) / 255.0 for _ in range(3)]
    if layout == "kitti-raw":
        root = write_kitti_raw(tmp_path / "2011_09_26", frames, frames, K, 0.5)
    else:
        write = write_kitti_2015 if layout == "kitti-2015" else write_kitti_2012
        root = write(tmp_path / "k", frames, frames, K, 0.5, sequence=3)
    source = open_source(root, exposure=0.01)
    assert source.numbering.name(1) == name
    assert source.frame_path("left", 1).stem == name
