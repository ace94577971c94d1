"""Interrupts that arrive while a pool spawns its workers act only once the spawning is done."""

from __future__ import annotations

import os
import signal

import pytest

from stereodeblur.clip.executors import _interrupts_deferred


class _Stop(Exception):
    pass


def _raise_stop(signum, frame):
    raise _Stop(signum)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_in_the_block_acts_after_it(sig):
    previous = signal.signal(sig, _raise_stop)
    finished = []
    try:
        with pytest.raises(_Stop):
            with _interrupts_deferred():
                os.kill(os.getpid(), sig)
                finished.append("the rest of the block ran")
        assert finished == ["the rest of the block ran"]
        assert signal.getsignal(sig) is _raise_stop  # restored
    finally:
        signal.signal(sig, previous)


def test_ctrl_c_becomes_keyboard_interrupt_after_the_block():
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt):
        with _interrupts_deferred():
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_no_signal_no_effect():
    with _interrupts_deferred():
        pass
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
