import json

import numpy as np
import pytest

from stereodeblur.evaluation.sceneflow_bench import (
    MotorcycleResult,
    format_sceneflow_table,
    object_errors,
    run_motorcycle_check,
    run_sceneflow_benchmark,
)
from stereodeblur.geometry import StereoCamera
from stereodeblur.sceneflow.model import SceneFlow

CAMERA = StereoCamera([[90.0, 0.0, 39.5], [0.0, 90.0, 29.5], [0.0, 0.0, 1.0]], 0.25)


def test_object_errors_are_zero_for_the_true_scene_flow_and_measure_a_wrong_one():
    normal = np.array([0.02, -0.03, 0.4])
    twist = np.array([0.03, 0.01, -0.05, 0.0, 0.01, 0.02])
    labels = np.zeros((60, 80), np.int32)
    labels[:, 40:] = 1
    truth = SceneFlow(CAMERA, labels, [normal, normal], [twist, twist], np.zeros((60, 80), bool))
    objects = [{"id": 0, "name": "plane", "normal": normal.tolist(), "twist": twist.tolist()}]
    (err,) = object_errors(truth, objects, truth.disparity(), truth.flow(), 0)
    assert err.num_pixels == 60 * 80
    assert err.rotation_deg < 1e-6 and err.translation_error < 1e-9 and err.normal_deg < 1e-5
    wrong = SceneFlow(
        CAMERA,
        labels,
        [normal, normal],
        [twist, twist + [0.01, 0, 0, 0, 0, 0]],
        np.zeros((60, 80), bool),
    )
    (err,) = object_errors(wrong, objects, truth.disparity(), truth.flow(), 0)
    assert err.translation_error == pytest.approx(0.005, abs=5e-4)  # median of 0 and 0.01


def test_benchmark_on_a_small_planar_scene(tmp_path):
    planar = pytest.importorskip("stereodeblur.synth.planar")
    scene = planar.make_planar_scene("forward_yaw", size=(128, 96), num_samples=16)
    root = planar.write_rendered_scene(scene, tmp_path / "forward_yaw")
    (result,) = run_sceneflow_benchmark([root], frame=1, out=tmp_path / "out")
    assert result.scene == "forward_yaw" and result.size == (128, 96)
    assert result.ade < 0.2 and result.aep < 0.3
    assert result.aep < result.aep_initial
    assert np.isfinite(result.ade_outside_mixed) and np.isfinite(result.aep_outside_mixed)
    (obj,) = result.objects
    assert obj.num_pixels > 0.9 * 128 * 96
    assert obj.rotation_deg < 0.5
    assert (tmp_path / "out" / "forward_yaw" / "flow" / "left" / "000001.flo").is_file()
    saved = json.loads((tmp_path / "out" / "sceneflow_bench.json").read_text())
    assert saved[0]["scene"] == "forward_yaw"
    table = format_sceneflow_table([result])
    assert "| forward_yaw | 128x96 |" in table and "rotation error" in table


def test_table_with_the_motorcycle_row():
    m = MotorcycleResult((741, 500), 0.1, 0.15, 0.06, 0.09, 2.0, 0.01, 0.2, 0.1, 0.01, 9.0)
    table = format_sceneflow_table([], m)
    assert "| scene flow | 10.0% |" in table and "| plain SGBM | 15.0%" in table


@pytest.mark.slow
def test_motorcycle_static_clip():
    m = run_motorcycle_check()
    print(format_sceneflow_table([], m))
    assert m.bad2_sceneflow < m.bad2_sgbm
    assert m.mean_flow < 0.05 and m.max_flow < 1.0
    assert any("identical" in w for w in m.warnings)


def test_cli_entry_writes_tables(tmp_path, capsys):
    pytest.importorskip("stereodeblur.synth.planar")
    from stereodeblur.cli import main

    args = ["bench", "sceneflow", "--sizes", "96x72", "--scenes", "upward", "--no-motorcycle"]
    assert main([*args, "--work", str(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    assert "| upward | 96x72 |" in out
    assert (tmp_path / "sceneflow.md").read_text() == out.rstrip("\n") + "\n"
    data = json.loads((tmp_path / "sceneflow.json").read_text())
    assert data["scenes"][0]["scene"] == "upward" and data["motorcycle"] is None
