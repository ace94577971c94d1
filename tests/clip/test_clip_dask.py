"""A Dask LocalCluster (two worker processes on loopback) gives the serial result, even when
a worker is killed mid-run."""

import json
import logging
import os
import signal

import pytest

from stereodeblur.clip import deblur_clip
from stereodeblur.io.sources import SourceSpec
from stereodeblur.pipeline import DeblurSettings
from tests.clip.clip_helpers import FAST, frame_files, run_cli

distributed = pytest.importorskip("distributed")

SETTINGS = DeblurSettings(motion_source="gt", num_irls=2, num_cg=5, num_samples=16)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.CRITICAL,
    ) as local:
        with distributed.Client(local, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        yield local


def _same_as_reference(out, reference):
    assert frame_files(out) == frame_files(reference)
    for name in frame_files(out):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name


def test_cluster_gives_the_serial_result(cluster, clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        "deblur", clip_scene, "-o", out, "--scheduler", cluster.scheduler_address, "-q", *FAST
    )
    assert result.code == 0, result.stderr
    _same_as_reference(out, reference_run.output)
    log = [json.loads(line) for line in (out / "run-log.jsonl").read_text().splitlines()]
    assert log[0]["scheduler"] == cluster.scheduler_address
    assert len({r["worker"] for r in log if r["event"] == "frame"}) == 2


def test_killing_a_worker_mid_run_still_completes_every_frame(
    cluster, clip_scene, reference_run, tmp_path
):
    out = tmp_path / "out"
    killed = []

    def kill_a_busy_worker(record):
        # The worker that just finished a frame has already taken the next one.
        if not killed and record.status == "done":
            pid = int(record.worker.rsplit(":", 1)[1])
            assert pid != os.getpid()
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    report = deblur_clip(
        SourceSpec.from_arguments(clip_scene),
        out,
        settings=SETTINGS,
        scheduler=cluster.scheduler_address,
        progress=False,
        on_frame=kill_a_busy_worker,
    )
    assert killed
    assert report.failed == () and report.done == 24
    _same_as_reference(out, reference_run.output)
    workers = [r.worker for r in report.records]
    assert any(w.endswith(f":{killed[0]}") for w in workers)
    assert len(set(workers)) >= 2


def test_unreachable_scheduler_is_a_one_line_error(clip_scene, tmp_path, monkeypatch):
    import stereodeblur.clip.executors as clip

    monkeypatch.setattr(clip, "DASK_CONNECT_TIMEOUT", 1.0)
    out = tmp_path / "out"
    result = run_cli("deblur", clip_scene, "-o", out, "--scheduler", "tcp://127.0.0.1:9", *FAST)
    lines = result.stderr.strip().splitlines()
    assert result.code == 2 and len(lines) == 1, lines
    assert "cannot connect to the Dask scheduler at tcp://127.0.0.1:9" in lines[0]
    assert not out.exists()
