"""deblur_clip checks everything before the first frame: a bad input is an InputError naming
the file, and nothing is written."""

import dataclasses
import shutil

import numpy as np
import pytest

from stereodeblur.clip import deblur_clip
from stereodeblur.errors import InputError
from stereodeblur.io.formats import write_flo, write_pfm
from stereodeblur.io.sources import SourceSpec
from stereodeblur.pipeline import DeblurSettings

SETTINGS = DeblurSettings(motion_source="gt", num_irls=1, num_cg=2, num_samples=8)


@pytest.fixture
def scene(clip_scene, tmp_path):
    return shutil.copytree(clip_scene, tmp_path / "scene")


def _run(scene, out, **options):
    return deblur_clip(
        SourceSpec.from_arguments(scene), out, settings=SETTINGS, progress=False, **options
    )


@pytest.mark.parametrize("kind", ["disparity", "flow"])
def test_unknown_ground_truth_is_an_input_error_before_any_frame(scene, tmp_path, kind):
    if kind == "flow":
        path = scene / "gt" / "flow" / "left" / "000007.flo"
        write_flo(path, np.full((48, 64, 2), np.inf, np.float32))
    else:
        path = scene / "gt" / "disparity" / "left" / "000007.pfm"
        write_pfm(path, np.zeros((48, 64), np.float32))
    out = tmp_path / "out"
    with pytest.raises(InputError, match=f"{path}.*unknown everywhere"):
        _run(scene, out, workers=1)
    assert not out.exists()


def test_truncated_frame_is_found_before_the_first_frame(scene, tmp_path):
    path = scene / "left" / "000009.png"
    path.write_bytes(path.read_bytes()[:-20])
    out = tmp_path / "out"
    with pytest.raises(InputError, match=str(path)):
        _run(scene, out, workers=1)
    assert not out.exists()


def test_only_the_views_a_run_reads_are_checked(scene, tmp_path):
    path = scene / "right" / "000001.png"
    path.write_bytes(b"")  # gt motion, alpha 'auto', one observation: the left view alone
    spec = SourceSpec.from_arguments(scene)
    settings = dataclasses.replace(SETTINGS, alpha="auto", observations="single")
    report = deblur_clip(
        spec,
        tmp_path / "out",
        settings=settings,
        progress=False,
        frames=[1],
        views=["left"],
        workers=1,
    )
    assert report.done == 1
    out = tmp_path / "default"  # the default alpha and observations use the right view
    with pytest.raises(InputError, match=str(path)):
        _run(scene, out, frames=[1], views=["left"], workers=1)
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"workers": 0}, "workers must be an integer of at least 1"),
        ({"workers": 2, "scheduler": "tcp://x:1"}, "either workers or a scheduler"),
        ({"views": ["top"]}, "views must be"),
        ({"frames": [0, 12]}, r"frames must lie in 0\.\.11"),
        ({"frames": range(0, 10**12)}, r"frames must lie in 0\.\.11"),
    ],
)
def test_bad_arguments(scene, tmp_path, options, message):
    with pytest.raises(InputError, match=message):
        _run(scene, tmp_path / "out", **options)
    assert not (tmp_path / "out").exists()


def test_a_run_that_writes_nothing_leaves_no_folder_and_no_log(scene, tmp_path):
    (scene / "gt" / "disparity" / "left" / "000003.pfm").write_bytes(b"PF\n")  # cut short
    out = tmp_path / "out"
    with pytest.raises(InputError):
        _run(scene, out, frames=[3], workers=1)
    assert not out.exists()
