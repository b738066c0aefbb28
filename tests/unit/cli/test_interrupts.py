"""The interrupt guard every command runs under: SIGTERM raises KeyboardInterrupt, and when the command
returns everything is as before (handlers, wakeup fd, SIGALRM), so an in-process caller goes on."""

import signal
import time

import pytest

from econmotor.cli import _interrupts, main
from econmotor.cli._interrupts import InterruptGuard, was_interrupted


def test_sigterm_raises_keyboard_interrupt_and_the_guard_puts_everything_back():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)}
    guard = InterruptGuard(grace_s=5.0)
    try:
        with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
            signal.raise_signal(signal.SIGTERM)
            time.sleep(1)  # the handler runs at the next bytecode
    finally:
        guard.close()
    assert was_interrupted()
    _interrupts._received.clear()  # this process goes on: the next test starts uninterrupted
    assert {s: signal.getsignal(s) for s in before} == before
    assert signal.set_wakeup_fd(-1) == -1  # no wakeup fd left behind
    time.sleep(0.1)  # the watcher saw the command end: it does not end this process


def test_a_command_leaves_the_process_as_it_found_it():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)}
    assert main(["tasks"]) == 0
    assert {s: signal.getsignal(s) for s in before} == before
    assert signal.set_wakeup_fd(-1) == -1
