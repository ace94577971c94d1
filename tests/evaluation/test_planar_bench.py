"""``stereodeblur bench planar`` on one small rendered scene."""

import math

from stereodeblur.evaluation.planar_bench import evaluate_scene, format_table, summary
from stereodeblur.synth.planar import write_planar_set


def test_planar_row_has_gt_and_scene_flow_columns(tmp_path):
    (root,) = write_planar_set(tmp_path, size=(160, 120), names=["upward"])
    row = evaluate_scene(root, "upward", "160x120")
    for value in (row.psnr_displacement, row.psnr_homography, row.psnr_sceneflow):
        assert math.isfinite(value) and value > row.psnr_blurred
    # The bench's check is one-sided: the estimated motion may score its alpha by the
    # held-out observations and so beat the true motion's alpha (1e-4 vs 3e-5 here).
    assert row.psnr_sceneflow > row.psnr_homography - 1.0
    table = format_table([row])
    assert table.count("\n") == 2 and "scene flow - gt" in table
    assert "estimated scene flow within 1 dB of the true motion on" in summary([row])


def test_run_planar_bench_writes_the_table_it_returns(tmp_path):
    from stereodeblur.evaluation.planar_bench import run_planar_bench

    bench = run_planar_bench(tmp_path, sizes=[(64, 48)], scenes=["upward"])
    (row,) = bench.rows
    assert row.scene == "upward" and row.size == "64x48"
    assert bench.markdown.read_text() == bench.table + "\n\n" + bench.summary + "\n"
    assert '"psnr_homography"' in bench.json.read_text()
