import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from stereodeblur.cli import main
from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.paper_bench import weight_statistics
from stereodeblur.evaluation.paper_columns import (
    ALPHA_SWEEP,
    COLUMNS,
    MASKED_COLUMNS,
    TRUE_MOTION,
    sweep_column,
)
from stereodeblur.io.formats import read_png

TINY = [
    "bench",
    "paper",
    "--size",
    "64x48",
    "--scenes",
    "squares",
    "--irls",
    "2",
    "--cg",
    "3",
    "--samples",
    "8",
    "--render-samples",
    "6",
    "--alpha-sweep",
    "-q",
]


def test_bench_on_a_tiny_scene_fills_every_column_and_resumes(tmp_path, capsys, monkeypatch):
    work = tmp_path / "work"
    assert main([*TINY, "--work", str(work)]) == 0
    text = capsys.readouterr().out
    for column in COLUMNS:
        assert column.title in text
    headings = ("Table 2", "Table 3", "Table 4", "gt/mixed", "true motion", "Alpha", "weights")
    for heading in headings:
        assert heading in text
    folder = work / "64x48"
    assert (folder / "paper.md").read_text() == text.rstrip("\n") + "\n"
    (row,) = json.loads((folder / "paper.json").read_text())
    keys = [c.key for c in COLUMNS + MASKED_COLUMNS + (TRUE_MOTION,)]
    keys += [sweep_column(a).key for a in ALPHA_SWEEP]
    assert sorted(row["columns"]) == sorted(keys)
    for key, entry in row["columns"].items():
        assert 10 < entry["psnr"] < 60 and 0 < entry["ssim"] <= 1, key
    assert 2e-5 <= row["columns"]["ours-full"]["alpha"] <= 3e-3  # auto
    assert row["columns"]["sweep-3e-05"]["alpha"] == 3e-5
    assert row["columns"]["homographies"]["alpha"] == 1e-3
    assert not math.isnan(row["columns"]["homographies"]["ade"])
    assert not math.isnan(row["columns"]["initial-flow"]["aep"])
    assert math.isnan(row["columns"]["ours-true-motion"]["aep"])
    assert "ours with the true motion - initial optical flow" in text
    assert "ours (full) - monocular (same defaults)" in text
    assert 2e-5 <= row["columns"]["monocular"]["alpha"] <= 3e-3  # auto
    assert not math.isnan(row["columns"]["monocular"]["aep"])
    for key, entry in row["columns"].items():
        assert 0 <= entry["mixed_mse"] < 0.1, key  # the tiny scene has gt/mixed pixels
    assert 0 <= row["columns"]["ours-full"]["changed_last_percent"] <= 100
    figure = read_png(folder / "figures" / "squares.png")
    assert figure.shape[1] == 64 * (len(COLUMNS) + 2)
    # A second run reads every result from the cache: deblurring it again would fail.
    monkeypatch.setattr(paper_bench, "run_column", None)
    assert main([*TINY, "--work", str(work)]) == 0
    assert "Table 3" in capsys.readouterr().out
    # A damaged cache entry (an interrupted write from outside) is computed again.
    monkeypatch.undo()
    damaged = folder / "cache" / "squares" / "homographies.json"
    damaged.write_text('{"column": "homogr')
    assert main([*TINY, "--work", str(work)]) == 0
    assert json.loads(damaged.read_text())["column"] == "homographies"


def test_weight_statistics_count_low_weights_near_boundaries_and_flow_errors():
    shape = (20, 30)
    weights = np.ones(shape, np.float32)
    weights[5, 5:10] = 0.1  # next to the mixed pixel (5, 7): explained
    weights[15, 20] = 0.2  # where the flow is wrong: explained
    weights[15, 2] = 0.3  # neither: unexplained
    mixed = np.zeros(shape, bool)
    mixed[7, 7] = True
    flow_error = np.zeros(shape)
    flow_error[15, 20] = 2.0
    previous = weights.copy()
    previous[0, :6] = 0.5  # six pixels changed by 0.5 in the last update
    result = SimpleNamespace(
        result=SimpleNamespace(weights=weights, weights_history=(previous, weights)), trust=None
    )
    stats = weight_statistics(result, mixed, flow_error)
    assert stats["low_weight_percent"] == pytest.approx(100 * 7 / 600)
    assert stats["low_weight_explained_percent"] == pytest.approx(100 * 6 / 7)
    assert stats["changed_last_percent"] == pytest.approx(100 * 6 / 600)
    fixed = SimpleNamespace(
        result=SimpleNamespace(weights=weights, weights_history=None), trust=None
    )
    assert weight_statistics(fixed, mixed, flow_error) == {}
    ones = np.ones(shape, np.float32)
    trusted = SimpleNamespace(
        result=SimpleNamespace(weights=ones, weights_history=None), trust=weights
    )
    stats = weight_statistics(trusted, mixed, flow_error)
    assert stats["low_weight_explained_percent"] == pytest.approx(100 * 6 / 7)
    assert stats["changed_last_percent"] == 0


def test_unknown_scene_is_a_one_line_error(tmp_path, capsys):
    code = main(["bench", "paper", "--scenes", "teapot", "--work", str(tmp_path)])
    assert code == 2
    assert "unknown scene 'teapot'" in capsys.readouterr().err


def test_the_paper_columns_keep_the_paper_iteration_counts():
    from stereodeblur.settings import NUM_CG, NUM_IRLS, PAPER_CG, PAPER_IRLS, DeblurSettings

    paper_keys = {c.key for c in COLUMNS[:5] + MASKED_COLUMNS}
    for column in COLUMNS + MASKED_COLUMNS + (TRUE_MOTION, sweep_column(1e-3)):
        settings = column.settings(DeblurSettings())
        counts = (settings.num_irls, settings.num_cg)
        expected = (PAPER_IRLS, PAPER_CG) if column.key in paper_keys else (NUM_IRLS, NUM_CG)
        assert counts == expected, column.key
        given = column.settings(DeblurSettings(num_irls=3, num_cg=7))  # --irls 3 --cg 7
        assert (given.num_irls, given.num_cg) == (3, 7), column.key
    assert [c.boundary_mask for c in MASKED_COLUMNS] == ["gt"] * 4


def test_two_processes_render_a_shared_bench_scene_once(tmp_path, monkeypatch):
    """Two benchmark scripts on one work folder (here threads: ``flock`` locks separate opens
    of one file): the second waits for the first's render and finds both variants written,
    instead of removing its half-written folder."""
    import threading
    import time

    from stereodeblur.synth import objects

    calls = []
    make = objects.make_object_scene

    def slow_make(name, **kwargs):
        calls.append(name)
        time.sleep(0.5)
        return make(name, **kwargs)

    monkeypatch.setattr(objects, "make_object_scene", slow_make)
    names = ["squares", "squares" + paper_bench.NOISY_SUFFIX]

    def render():
        paper_bench.render_missing(tmp_path, names, (32, 24), num_samples=4)

    threads = [threading.Thread(target=render) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert calls == ["squares"]
    assert all((tmp_path / name / "camera.json").is_file() for name in names)
