"""End-to-end runs through the command line on small scenes."""

import numpy as np

from stereodeblur.cli import main
from stereodeblur.evaluation.metrics import psnr
from stereodeblur.io.formats import read_png
from stereodeblur.io.scene import open_scene
from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene


def test_demo_writes_picture_and_improves(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "demo"), "--size", "160x120", "-q"]) == 0
    out = capsys.readouterr().out
    before = float(out.split("PSNR blurred")[1].split("dB")[0])
    after = float(out.split("PSNR deblurred")[1].split("dB")[0])
    assert after > before + 2.0, out
    picture = read_png(tmp_path / "demo" / "demo.png")
    assert picture.shape[0] == 120 and picture.shape[1] == 3 * 160 + 2 * 4


def test_deblur_cli_gt_homography_improves_psnr(tmp_path, capsys):
    root = tmp_path / "scene"
    write_rendered_scene(make_planar_scene("yaw", size=(96, 72), num_samples=32), root)
    out = tmp_path / "out"
    args = ["deblur", str(root), "-o", str(out), "--frames", "1", "--motion-source", "gt", "-q"]
    assert main(args) == 0
    scene = open_scene(root)
    sharp = scene.read_gt_sharp("left", 1)
    deblurred = read_png(out / "left" / "000001.png")
    assert psnr(deblurred, sharp, border=4) > psnr(scene.read_frame("left", 1), sharp, border=4)
    assert (out / "camera.json").read_text() == (root / "camera.json").read_text()
    assert not any(p.name.endswith(".tmp") for p in out.rglob("*"))
    # Deterministic: the same input gives the same output.
    again = tmp_path / "again"
    assert main(args[:3] + [str(again)] + args[4:]) == 0
    np.testing.assert_array_equal(read_png(again / "left" / "000001.png"), deblurred)
