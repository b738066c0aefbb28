"""The interrupt guard every command runs under: SIGTERM raises KeyboardInterrupt, and when the command
returns everything is as before (handlers, wakeup fd, SIGALRM), so an in-process caller goes on."""

import signal
import subprocess
import sys
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


SWALLOWED = """
import gc, signal, sys, time
from econmotor.cli._interrupts import InterruptGuard

sent = []
def raise_inside_a_gc_callback(phase, info):  # as JAX's XLA collector: the handler runs in here
    if phase == "start" and not sent:
        sent.append(phase)
        signal.raise_signal(signal.SIGTERM)

guard = InterruptGuard(grace_s=3600.0)  # the deadline cannot end it: only the raise again can
gc.callbacks.append(raise_inside_a_gc_callback)
try:
    while True:
        gc.collect()
        sum(range(20_000))
except KeyboardInterrupt as exc:
    print(f"caught {exc}")
finally:
    guard.close()
"""


def test_an_interrupt_swallowed_in_a_gc_callback_is_raised_again():
    """Python swallows an exception raised in a gc callback ("Exception ignored in ..."); JAX runs
    one at every collection, and an MJX sweep's SIGTERM was lost there until the 6 s deadline."""
    proc = subprocess.run([sys.executable, "-c", SWALLOWED], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    # raised again by the watcher: with an hour's grace, its deadline (which exits 143 and says "still busy")
    # cannot be what ended the loop
    assert proc.stdout == "caught signal SIGTERM\n", proc.stdout + proc.stderr
    assert "still busy" not in proc.stderr
    assert "Exception ignored" not in proc.stderr


IGNORES_INTERRUPTS = """
import time
from econmotor.cli._interrupts import InterruptGuard, set_deadline_note

guard = InterruptGuard(grace_s=1.0)
set_deadline_note(lambda: "Resume with: econmotor train --resume")


def busy():
    while True:  # a command that never stops by itself
        try:
            time.sleep(0.05)
        except KeyboardInterrupt:
            pass


said = False
while True:  # an interrupt that lands between the inner try blocks (a loaded machine) is swallowed here
    try:
        if not said:  # "ready" inside the try: the test's SIGTERM can arrive before print returns
            print("ready", flush=True)
            said = True
        busy()
    except KeyboardInterrupt:
        pass
"""


def test_the_deadline_ends_a_command_that_does_not_stop_and_says_its_note():
    proc = subprocess.Popen([sys.executable, "-c", IGNORES_INTERRUPTS], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "ready\n"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 143  # 128 + SIGTERM
    assert "interrupted (SIGTERM): still busy 1 s later" in err
    assert err.rstrip().endswith("exiting now. Resume with: econmotor train --resume"), err


#: a command that never stops by itself and has no note of its own: the interrupt's KeyboardInterrupt leaves it
#: (registered on the real app in this child process only)
UNTIL_INTERRUPTED = """
import sys, time
from econmotor.cli import app, main

@app.command("until-interrupted")
def until_interrupted() -> None:
    print("ready", flush=True)
    while True:
        time.sleep(0.05)

sys.exit(main(["until-interrupted"]))
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_command_without_its_own_note_exits_with_the_signals_status(signum):
    """Typer turns a KeyboardInterrupt that leaves a command into exit 130, whatever the signal: a SIGTERM to a
    holosoma ``report --policy`` (whose evaluation has no note of its own) exited 130, not 143."""
    proc = subprocess.Popen([sys.executable, "-c", UNTIL_INTERRUPTED], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "ready\n"
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 128 + signum, err  # 130 for SIGINT, 143 for SIGTERM
    name = signal.Signals(signum).name
    assert f"interrupted (signal {name}): nothing further was written" in " ".join(err.split())
    assert "still busy" not in err  # it stopped by itself, not by the deadline
