import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.geometry import StereoCamera
from stereodeblur.io.formats import read_flo, read_mask, read_pfm
from stereodeblur.sceneflow import load_sceneflow, save_sceneflow, write_sceneflow_outputs
from stereodeblur.sceneflow.model import SceneFlow

CAMERA = StereoCamera([[80.0, 0.0, 31.5], [0.0, 80.0, 23.5], [0.0, 0.0, 1.0]], 0.2)


def _sceneflow(view="left"):
    rng = np.random.default_rng(0)
    labels = np.zeros((48, 64), np.int32)
    labels[:, 32:] = 1
    labels[30:, :] = 2
    normals = np.array([[0.01, -0.02, 0.4], [0.0, 0.03, 0.3], [-0.02, 0.0, 0.5]])
    twists = rng.normal(0, 0.02, (3, 6))
    occlusion = rng.random(labels.shape) < 0.1
    return SceneFlow(CAMERA, labels, normals, twists, occlusion, view)


@pytest.mark.parametrize("view", ["left", "right"])
def test_round_trip(tmp_path, view):
    sf = _sceneflow(view)
    path = save_sceneflow(tmp_path / "sub" / "sf.npz", sf)
    back = load_sceneflow(path)
    np.testing.assert_array_equal(back.labels, sf.labels)
    np.testing.assert_array_equal(back.normals, sf.normals)
    np.testing.assert_array_equal(back.twists, sf.twists)
    np.testing.assert_array_equal(back.occlusion, sf.occlusion)
    np.testing.assert_array_equal(back.camera.K, sf.camera.K)
    assert back.camera.baseline == sf.camera.baseline
    assert back.view == view
    assert [p.name for p in tmp_path.joinpath("sub").iterdir()] == ["sf.npz"]  # no temp file


def test_outputs_in_the_gt_layout(tmp_path):
    sf = _sceneflow()
    paths = write_sceneflow_outputs(tmp_path, sf, 7)
    assert paths["disparity"] == tmp_path / "disparity" / "left" / "000007.pfm"
    assert paths["flow"] == tmp_path / "flow" / "left" / "000007.flo"
    assert paths["occlusion"] == tmp_path / "occlusion" / "left" / "000007.png"
    assert paths["sceneflow"] == tmp_path / "sceneflow" / "000007.npz"
    np.testing.assert_allclose(read_pfm(paths["disparity"]), sf.disparity(), rtol=1e-6)
    np.testing.assert_allclose(read_flo(paths["flow"]), sf.flow(), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(read_mask(paths["occlusion"]), sf.occlusion)
    np.testing.assert_array_equal(load_sceneflow(paths["sceneflow"]).labels, sf.labels)


def test_bad_files_are_reported(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_sceneflow(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file at all")
    with pytest.raises(InputError, match="junk.npz"):
        load_sceneflow(junk)
    partial = tmp_path / "partial.npz"
    np.savez(partial, labels=np.zeros((2, 2), np.int32))
    with pytest.raises(InputError, match="missing"):
        load_sceneflow(partial)
    sf = _sceneflow()
    wrong = tmp_path / "wrong.npz"
    save_sceneflow(wrong, sf)
    data = dict(np.load(wrong))
    data["format"] = np.array("something-else/9")
    np.savez(wrong, **data)
    with pytest.raises(InputError, match="unsupported"):
        load_sceneflow(wrong)
    data["format"] = np.array("stereodeblur-sceneflow/1")
    data["labels"] = np.full((48, 64), 5, np.int32)  # beyond the 3 segments
    np.savez(wrong, **data)
    with pytest.raises(InputError, match="labels"):
        load_sceneflow(wrong)
    with pytest.raises(InputError, match="frame_index"):
        write_sceneflow_outputs(tmp_path, sf, -1)
    with pytest.raises(InputError, match="SceneFlow"):
        save_sceneflow(tmp_path / "x.npz", "not a scene flow")
