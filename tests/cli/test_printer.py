"""The one progress printer: lines on stderr, throttled counted stages, silent with -q."""

import io

from stereodeblur.cli import main
from stereodeblur.cli.printer import ProgressPrinter, progress_printer
from stereodeblur.progress import Progress


def test_counted_stages_print_their_first_and_last_report():
    stream = io.StringIO()
    printer = ProgressPrinter(stream, min_interval=3600)
    printer(Progress("rendering"))
    for done in range(1, 11):
        printer(Progress("IRLS", done, 10))
    printer(Progress("writing"))
    lines = [line.split("] ", 1)[1] for line in stream.getvalue().splitlines()]
    assert lines == ["rendering", "IRLS 1/10", "IRLS 10/10", "writing"]


def test_every_report_prints_without_throttling():
    stream = io.StringIO()
    printer = ProgressPrinter(stream, min_interval=0)
    for done in range(1, 4):
        printer(Progress("CG", done, 3))
    assert len(stream.getvalue().splitlines()) == 3


def test_quiet_gives_no_printer():
    assert progress_printer(True) is None
    assert isinstance(progress_printer(False), ProgressPrinter)


def test_quiet_flag_silences_a_command(tmp_path, capsys):
    argv = ["synth", "planar", "--size", "32x24", "--scenes", "yaw"]
    assert main([*argv, str(tmp_path / "a")]) == 0
    assert any(line.startswith("[") for line in capsys.readouterr().err.splitlines())
    assert main([*argv, str(tmp_path / "b"), "-q"]) == 0
    assert capsys.readouterr().err == ""
