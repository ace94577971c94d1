"""``--scheduler`` at an address that is no Dask scheduler: one line, exit 2, within the
stated timeout, nothing written, no process or thread left. The peers are tiny TCP servers on
loopback that stop themselves."""

import contextlib
import os
import signal
import socket
import threading
import time

import pytest

from tests.faults.helpers import FAST, run_cli, start_run, tagged_processes, tree_checksums

pytest.importorskip("distributed")

GARBAGE = b"HTTP/1.0 400 Bad Request\r\nServer: not-dask\r\n\r\n" * 4


@contextlib.contextmanager
def tcp_peer(answer: bytes | None, lifetime: float = 60.0):
    """A server on 127.0.0.1 that accepts every connection and sends ``answer`` (None: says
    nothing and never closes); it stops when the block ends or after ``lifetime`` seconds."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.1)
    stop = threading.Event()
    accepted = []

    def serve():
        deadline = time.monotonic() + lifetime
        while not stop.is_set() and time.monotonic() < deadline:
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            accepted.append(conn)
            if answer is not None:
                with contextlib.suppress(OSError):
                    conn.sendall(answer)
        for conn in accepted:
            conn.close()
        server.close()

    thread = threading.Thread(target=serve, daemon=True, name="tcp-peer")
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}", accepted
    finally:
        stop.set()
        thread.join(5)


def test_peer_answering_garbage(tiny_scene, tmp_path):
    out = tmp_path / "out"
    before = tree_checksums(tiny_scene)
    with tcp_peer(GARBAGE) as (address, accepted):
        start = time.monotonic()
        run = start_run("deblur", tiny_scene, "-o", out, "--scheduler", address, *FAST)
        try:
            _, err = run.process.communicate(timeout=30)
        finally:
            if run.process.poll() is None:  # a hang: end the run's whole session
                os.killpg(run.process.pid, signal.SIGKILL)
                run.process.communicate()
        seconds = time.monotonic() - start
    lines = err.decode().strip().splitlines()
    assert run.process.returncode == 2 and len(lines) == 1, lines
    assert f"Dask scheduler at {address}" in lines[0] and "not as a Dask scheduler" in lines[0]
    assert accepted and seconds < 10, seconds  # refused at once, not after retries
    assert tagged_processes(run.mark) == []
    assert not out.exists() and tree_checksums(tiny_scene) == before


def test_peer_that_never_answers(tiny_scene, tmp_path, monkeypatch):
    import stereodeblur.clip.executors as executors

    monkeypatch.setattr(executors, "DASK_CONNECT_TIMEOUT", 2.0)
    out = tmp_path / "out"
    before = tree_checksums(tiny_scene)
    threads = set(threading.enumerate())
    with tcp_peer(None) as (address, accepted):
        start = time.monotonic()
        result = run_cli("deblur", tiny_scene, "-o", out, "--scheduler", address, *FAST)
        seconds = time.monotonic() - start
        assert accepted
    lines = result.stderr.strip().splitlines()
    assert result.code == 2 and len(lines) == 1, lines
    assert f"Dask scheduler at {address}: no answer within 2 s" in lines[0]
    assert seconds < 2.0 + 3.0, seconds
    assert set(threading.enumerate()) <= threads  # the exchange's thread has ended
    assert not out.exists() and tree_checksums(tiny_scene) == before


def test_the_timeout_is_stated_in_the_help():
    from stereodeblur.settings import DASK_CONNECT_TIMEOUT

    result = run_cli("deblur", "--help")
    assert f"within {DASK_CONNECT_TIMEOUT:g}" in " ".join(result.stdout.split())
