"""benchmarks/street_bound.py's report and options, on made-up figures."""

import importlib.util
from pathlib import Path

import pytest

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "street_bound.py"


@pytest.fixture(scope="module")
def bound():
    spec = importlib.util.spec_from_file_location("street_bound", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _result(monocular, oracle, true=None):
    true = oracle if true is None else true
    return {
        "blurred": 30.0,
        "initial-flow/monocular": monocular,
        "sceneflow/default": monocular,
        "gt/default": monocular,
        "true motion": (true, 1e-3, 1e-4),
        "oracle fill": (oracle, 1e-3, 3e-4),
        "residual/blurred": 0.004,
        "residual/gt": 0.0032,
        "residual/monocular": 0.0033,
    }


def test_the_report_names_the_streets_the_oracle_fill_leaves_below_the_margin(bound):
    results = {
        "street_1": _result(40.0, 40.6),
        "street_2": _result(40.0, 40.4),
        "street_3": _result(30.0, 31.0, true=30.8),
    }
    lines = bound.report(results, ["--size", "320x240"], 1.0)
    text = "\n".join(lines)
    assert "short of the needed PSNR on 1 of 3: street_2." in text
    row = next(line for line in lines if line.startswith("| street_2 "))
    assert "| 40.50 |" in row
    assert "40.40 (0.0003)" in row
    assert "over the true motion: +0.07 dB" in text
    assert row.endswith("| -0.10 | 4.00 / 3.20 / 3.30 |")
    header, rule = (line for line in lines if line.startswith(("| scene ", "|---")))
    assert header.count("|") == rule.count("|") == row.count("|")


def test_only_family_scenes_are_taken(bound, capsys):
    with pytest.raises(SystemExit) as exit_info:
        bound.parse(["--scenes", "street_1087,spheres"])
    assert exit_info.value.code == 2
    assert "'spheres' is not a family scene" in capsys.readouterr().err
    assert bound.parse(["--scenes", "street_1087", "--size", "640x480"]).size == (640, 480)
