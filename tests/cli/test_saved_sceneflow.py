"""`stereodeblur sceneflow` writes a file that `deblur --sceneflow FILE` reuses."""

import numpy as np

from stereodeblur.cli import main
from stereodeblur.io.formats import read_png
from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene


def test_saved_sceneflow_gives_the_same_frame_as_estimating(tmp_path, capsys):
    root = tmp_path / "scene"
    write_rendered_scene(make_planar_scene("yaw", size=(96, 72), num_samples=32), root)
    flow_dir = tmp_path / "sf"
    assert main(["sceneflow", str(root), "--frames", "1", "-o", str(flow_dir), "-q"]) == 0
    saved = flow_dir / "sceneflow" / "000001.npz"
    assert saved.is_file()
    common = ["--frames", "1", "--views", "left", "--irls", "2", "--cg", "5", "-q"]
    assert (
        main(["deblur", str(root), "-o", str(tmp_path / "a"), "--sceneflow", str(saved)] + common)
        == 0
    )
    assert main(["deblur", str(root), "-o", str(tmp_path / "b"), "--workers", "1"] + common) == 0
    a = read_png(tmp_path / "a" / "left" / "000001.png")
    b = read_png(tmp_path / "b" / "left" / "000001.png")
    np.testing.assert_array_equal(a, b)
    # A file for another frame size is refused with one line naming it.
    small = tmp_path / "small"
    write_rendered_scene(make_planar_scene("yaw", size=(64, 48), num_samples=8), small)
    capsys.readouterr()
    args = ["deblur", str(small), "-o", str(tmp_path / "c"), "--sceneflow", str(saved)]
    assert main(args + ["--frames", "1", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "000001.npz" in err[0] and "size" in err[0]
    assert not (tmp_path / "c").exists()
