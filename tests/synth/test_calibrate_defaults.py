"""The protocol runner's bookkeeping (benchmarks/calibrate_defaults.py), on made-up figures."""

import importlib.util
import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "calibrate_defaults.py"


@pytest.fixture(scope="module")
def runner():
    spec = importlib.util.spec_from_file_location("calibrate_defaults", PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def _row(runner, name, default, paper, best):
    columns = {"gt/default": {"psnr": default, "ssim": 0.9, "alpha": 1e-4, "seconds": 1.0}}
    columns["gt/paper"] = {"psnr": paper, "ssim": 0.9, "alpha": 1e-3, "seconds": 1.0}
    for i, alpha in enumerate(runner.ALPHAS):
        psnr = best if i == 2 else best - 1 - i
        columns[f"gt/{runner.alpha_key(alpha)}"] = {"psnr": psnr, "ssim": 0.9, "alpha": alpha}
    return {"scene": name, "columns": columns}


def test_columns_cover_the_protocol(runner):
    keys = [(c.motion_source, c.key) for c in runner.columns_for(("gt", "sceneflow"))]
    # default, paper, the candidates, the default's and adaptive's alpha grids; the monocular
    assert len(keys) == 2 * (2 + len(runner.CANDIDATES) + 2 * len(runner.ALPHAS)) + 1
    assert len(set(keys)) == len(keys)
    assert ("initial-flow", "monocular") in keys and ("sceneflow", "paper") in keys
    columns = {c.key: c.settings() for c in runner.columns_for(("gt",))}
    assert columns["cross-view"].alpha == "cross-view"
    assert columns["cross-view"].boundary_weights == columns["default"].boundary_weights
    other = columns["adaptive-cross-view"]
    assert (other.alpha, other.boundary_weights) == ("cross-view", "adaptive")
    assert runner.grid_prefix("adaptive-cross-view") == "adaptive-"
    assert runner.grid_prefix("cross-view") == ""
    assert columns["adaptive-alpha=0.001"].alpha == 1e-3
    assert columns["adaptive-alpha=0.001"].boundary_weights == "adaptive"
    assert columns["observations"].observations == "all"
    (mono,) = [c for c in runner.columns_for(("sceneflow",)) if c.key == "monocular"]
    assert mono.settings().boundary_weights == "adaptive"  # its strongest handling
    assert ("initial-flow", "monocular") not in [
        (c.motion_source, c.key) for c in runner.columns_for(("gt",))
    ]
    paper = [c for c in runner.columns_for(("gt",)) if c.key == "paper"][0].settings()
    assert paper.alpha == 1e-3 and paper.boundary_weights == "none"
    mono = runner.columns_for(("sceneflow",))[-1].settings()
    assert (mono.motion_source, mono.kernels) == ("initial-flow", "displacement")


def test_checks_pass_and_fail_on_the_issue_limits(runner):
    good = [_row(runner, "a", 30.0, 30.2, 30.3), _row(runner, "b", 25.0, 24.0, 25.4)]
    assert all(ok for _, ok, _ in runner.checks(good, ("gt",)))
    gaps = runner.gaps(good[0], "gt")
    assert gaps["best_alpha"] == "0.0001" and math.isclose(gaps["below_best"], 0.3)
    below_paper = good + [_row(runner, "c", 28.0, 28.6, 28.5)]
    results = {name: ok for name, ok, _ in runner.checks(below_paper, ("gt",))}
    assert [ok for ok in results.values()] == [True, True, False]
    exact = [_row(runner, f"e{i}", 30.0, 29.0, 30.0) for i in range(4)]
    far = good + exact + [_row(runner, "d", 20.0, 19.0, 21.6)]  # mean gap 0.38 dB
    assert [ok for _, ok, _ in runner.checks(far, ("gt",))] == [True, False, True]


def test_a_candidate_is_checked_like_the_default_against_its_own_grid(runner):
    rows = [_row(runner, "a", 30.0, 30.2, 30.3), _row(runner, "b", 25.0, 24.0, 25.4)]
    for row, psnr in zip(rows, (28.0, 25.3), strict=True):
        row["columns"]["gt/cross-view"] = {"psnr": psnr, "alpha": 1e-3}
        row["columns"]["gt/adaptive-cross-view"] = {"psnr": psnr, "alpha": 1e-3}
        for alpha in runner.ALPHAS:  # the adaptive grid peaks 2 dB lower
            grid = row["columns"][f"gt/{runner.alpha_key(alpha)}"]
            row["columns"][f"gt/adaptive-{runner.alpha_key(alpha)}"] = grid | {
                "psnr": grid["psnr"] - 2
            }
    assert all(ok for _, ok, _ in runner.checks(rows, ("gt",)))
    candidate = runner.checks(rows, ("gt",), "cross-view")
    assert [ok for _, ok, _ in candidate] == [False, False, False]  # 2.3 dB off on "a"
    assert all("cross-view" in name for name, _, _ in candidate)
    other = runner.checks(rows, ("gt",), "adaptive-cross-view")  # 0.3 dB off its grid's best
    assert [ok for _, ok, _ in other] == [True, True, False]


def test_scene_lists_follow_the_split(runner):
    assert runner.scene_list("train", 3, ("family", "street")) == [
        ("family", 0),
        ("street", 0),
        ("family", 1),
    ]
    assert runner.scene_list("test", 2, ("street",)) == [("street", 1000), ("street", 1001)]
    assert runner.scene_list("test", 3, ("family", "street"), skip=40) == [
        ("family", 1020),
        ("street", 1020),
        ("family", 1021),
    ]
    args = runner.parse([])
    assert args.split == "train" and args.output.endswith("calibrate_defaults_train_320x240.md")
    with pytest.raises(SystemExit):
        runner.parse(["--kinds", "forest"])
    with pytest.raises(SystemExit):
        runner.parse(["--skip", "3"])  # not a multiple of the two kinds
    only = ["--split", "test", "--scenes", "4", "--skip", "40", "--only"]
    assert runner.parse([*only, "street_1020,family_1021"]).only == ("street_1020", "family_1021")
    with pytest.raises(SystemExit):
        runner.parse([*only, "family_1022"])  # not among the four scenes


def test_split_note_counts_seeds_not_scenes(runner):
    def note(*argv):
        return runner.split_note(runner.parse(["--split", "test", *argv]))

    streets = note("--skip", "100", "--kinds", "street")  # seeds from 1100
    assert "seed 1100" in streets and "rendered after" in streets
    studied = note("--skip", "100")  # both kinds: seeds from 1050, looked at while tuning
    assert "seed 1050" in studied and "`--skip 160`" in studied
    assert "rendered after" not in studied
    assert "rendered after" in note("--skip", "160")
    assert "tuned on" in runner.split_note(runner.parse([]))


def test_monocular_check_needs_every_semi_real_scene(runner):
    def row(name, kind, default, mono):
        columns = {"sceneflow/default": {"psnr": default}, "initial-flow/monocular": {"psnr": mono}}
        return {"scene": name, "kind": kind, "columns": columns}

    rows = [row("street_0", "street", 31.0, 30.0), row("family_0", "family", 20.0, 30.0)]
    ((name, ok, figures),) = runner.monocular_checks(rows, ["default"])
    assert ok and "1 semi-real scenes" in name and "mean +1.00 dB" in figures  # family ignored
    rows.append(row("street_1", "street", 30.2, 30.0))  # mean +0.60, but one at +0.20
    ((_, ok, figures),) = runner.monocular_checks(rows, ["default"])
    assert not ok and "worst +0.20 dB (street_1)" in figures
    assert runner.monocular_checks(rows[1:2], ["default"]) == []


def test_the_monocular_bound_takes_each_street_scenes_best_grid_alpha(runner):
    def row(name, kind, grid, mono):
        columns = {f"gt/alpha={a:g}": {"psnr": p} for a, p in grid.items()}
        columns["initial-flow/monocular"] = {"psnr": mono}
        return {"scene": name, "kind": kind, "columns": columns}

    rows = [
        row("street_0", "street", {1e-4: 31.0, 1e-3: 32.0}, 30.0),  # best +2.00
        row("street_1", "street", {1e-4: 30.3, 1e-3: 29.0}, 30.0),  # best +0.30
        row("family_0", "family", {1e-4: 10.0}, 30.0),  # not a street: ignored
    ]
    (line,) = runner.monocular_bounds(rows, ["gt"])
    assert "mean +1.15 dB" in line and "on 1 of 2" in line
    assert runner.monocular_bounds(rows, ["sceneflow"]) == []  # no grid column of it


def test_without_the_grid_the_default_is_set_against_the_candidates(runner):
    keys = [c.key for c in runner.columns_for(("sceneflow",), ("no-relabel",), grid=False)]
    assert keys == ["default", "paper", "no-relabel", "monocular"]
    assert runner.columns_for(("sceneflow",), ("no-relabel",))[0].settings().relabel_radius > 0
    off = runner.columns_for(("sceneflow",), ("no-relabel",))[2].settings()
    assert off.relabel_radius == 0

    def row(name, default, other):
        columns = {"sceneflow/default": {"psnr": default}, "sceneflow/no-relabel": {"psnr": other}}
        return {"scene": name, "kind": "family", "columns": columns}

    rows = [row("a", 31.0, 30.0), row("b", 29.5, 30.0), row("c", 32.0, 31.0)]
    lines = runner.candidate_table(rows, ("sceneflow",), ("no-relabel",))
    assert lines[2] == "| sceneflow | default | 30.83 | | | |"
    assert lines[3] == "| sceneflow | no-relabel | 30.33 | +0.50 | -0.50 (b) | 1 of 3 |"
    assert not runner.parse(["--no-grid"]).grid and runner.parse([]).grid


def test_a_result_is_found_under_another_column_or_archived(runner, tmp_path):
    import json

    default = tmp_path / "sceneflow_default.json"
    default.write_text(json.dumps({"psnr": 30.0, "signature": "before"}))
    runner._archive(default)  # the default's settings change: its result is kept
    default.write_text(json.dumps({"psnr": 31.0, "signature": "after"}))
    assert runner._cached_elsewhere(tmp_path, "sceneflow", "before")["psnr"] == 30.0
    assert runner._cached_elsewhere(tmp_path, "sceneflow", "after")["psnr"] == 31.0
    assert runner._cached_elsewhere(tmp_path, "sceneflow", "other") is None
    assert runner._cached_elsewhere(tmp_path, "gt", "before") is None
    runner._archive(tmp_path / "sceneflow_missing.json")  # nothing to keep


_PARENT_COMPILES_AFTER_RUN_ALL = """
import sys
import numba
import numpy as np
sys.path.insert(0, {folder!r})
import calibrate_defaults

@numba.njit(parallel=True)
def total(x):
    s = 0.0
    for i in numba.prange(x.size):
        s += x[i]
    return s

total(np.ones(8))  # numba's threads run in the parent before the pool
assert calibrate_defaults.run_all(abs, [-1, -2, -3], 2) == [1, 2, 3]

@numba.njit
def add_one(x):  # defined after the pool: numba compiles it here
    return x + 1

print(add_one(1))
"""


def test_the_parent_still_compiles_after_a_parallel_run():
    """run_all leaves the parent's NUMBA_NUM_THREADS alone: set there after numba's threads
    ran, it would make every later compilation in the parent fail ("Cannot set
    NUMBA_NUM_THREADS to a different value once the threads have been launched")."""
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    code = _PARENT_COMPILES_AFTER_RUN_ALL.format(folder=str(PATH.parent))
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["2"]


def test_two_runs_render_a_shared_scene_once(runner, tmp_path, monkeypatch):
    """Two processes (here threads: ``flock`` locks separate opens of one file) asking for the
    same scene: the second waits for the first's render instead of removing its half-written
    folder, and reuses it."""
    import threading
    import time

    from stereodeblur.synth import family

    calls = []

    def slow_write(spec, root):
        calls.append(spec.name)
        partial = root.with_name(root.name + ".partial")
        (partial / "gt").mkdir(parents=True)
        time.sleep(0.5)
        (partial / "gt" / "family.json").write_text(family.spec_json(spec), encoding="utf-8")
        partial.rename(root)
        return root

    monkeypatch.setattr(family, "write_family_scene", slow_write)
    roots = []

    def ask():
        roots.append(runner.ensure_scene("family", 3, (64, 48), tmp_path))

    threads = [threading.Thread(target=ask) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert calls == ["family_0003"] and len(roots) == 2 and roots[0] == roots[1]
    assert (roots[0] / "gt" / "family.json").is_file()


def test_a_cached_column_is_read_only_with_the_motion_it_would_take_now(
    runner, tmp_path, monkeypatch
):
    """A column's cached result is reused only if it was made with the motion the calibration
    would take now: a result of a motion estimated again is computed afresh."""
    flows = {"now": np.zeros((4, 6, 2), np.float32)}
    monkeypatch.setattr(
        runner,
        "motion_for",
        lambda *args: SimpleNamespace(
            sceneflow=None, flow_forward=flows["now"], flow_backward=None
        ),
    )
    column = runner.Column(runner.alpha_key(1e-4), "initial-flow", {"alpha": 1e-4})
    cache = tmp_path / "results" / "family_0000"
    path = runner._column_path(cache, column)

    def stored():
        _, signature = runner._column_signature(None, column, {}, {}, cache)
        return runner._stored(path, column.motion_source, signature)

    assert stored() is None
    path.parent.mkdir(parents=True)
    signature = runner._signature(column.settings()) + runner.motion_tag(runner.motion_for())
    path.write_text(json.dumps({"psnr": 30.0, "signature": signature}))
    assert stored()["psnr"] == 30.0
    flows["now"] = np.ones((4, 6, 2), np.float32)  # the motion estimated again, otherwise
    assert stored() is None


def test_a_columns_signature_names_its_motion_not_the_estimators_settings(runner):
    from stereodeblur.sceneflow.settings import SceneFlowSettings

    default = runner.Column("default", "sceneflow")
    other = runner.Column("other", "sceneflow", {"sceneflow": SceneFlowSettings(truncation=8.0)})
    assert runner._signature(other.settings()) == runner._signature(default.settings())
    assert "SceneFlowSettings" not in runner._signature(default.settings())
    paper = runner.Column("paper", "sceneflow", {"alpha": 1e-3})
    assert runner._signature(paper.settings()) != runner._signature(default.settings())
