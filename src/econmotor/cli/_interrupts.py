"""SIGINT and SIGTERM for every command: a KeyboardInterrupt in the main thread, with a deadline.

Python runs a signal handler in the main thread between two bytecodes. A long call that does not
return to the interpreter delays it: SQLite waiting for another process's write lock (up to the
registry's 120 s busy timeout), a long C routine. So the signal also wakes a watcher thread
(``signal.set_wakeup_fd``: the interpreter's C-level handler writes the signal number to a socket
at once, whatever the main thread is doing). If the command has not ended
:data:`INTERRUPT_GRACE_S` seconds later, the watcher records this process's running runs as
``interrupted`` (:func:`econmotor.store.owners.interrupt_own_runs`), says so in one line (with
the command's note of what it kept and how to resume, :func:`set_deadline_note`) and ends the
process with the shell's status for the signal (:func:`interrupted_exit_code`: 130 for SIGINT,
143 for SIGTERM). While it does, an ``alarm`` of :data:`LAST_RESORT_S` seconds
stands behind it: SIGALRM's default action ends the process even if the watcher is stuck too.

A KeyboardInterrupt raised where Python swallows exceptions is delivered again. The handler runs
at whatever bytecode the main thread is at, and that can be inside a garbage-collector callback
(JAX registers one that frees XLA buffers at every collection), a ``__del__`` or a weakref
callback: Python prints "Exception ignored in ..." and goes on as if no signal had come. The
guard's ``sys.unraisablehook`` sees such a KeyboardInterrupt and the watcher raises it again in the
main thread (``_thread.interrupt_main``) a moment later, outside the callback.

An interrupted command that did stop in time ends the process at once
(:func:`end_interrupted_process`), without the interpreter's teardown.

Typer turns a KeyboardInterrupt that leaves a command into exit status 130, whatever the signal (a
SIGTERM too), and says nothing. The app's group (:class:`InterruptibleGroup`) carries it past Typer
as :class:`CommandInterrupted`, so :func:`econmotor.cli.main` says so and exits with the signal's status.
"""

from __future__ import annotations

import _thread
import atexit
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, NoReturn

from typer.core import TyperGroup

from econmotor.store.owners import interrupt_own_runs

#: seconds a command has, after SIGINT or SIGTERM, to stop by itself (it records what it was doing)
INTERRUPT_GRACE_S = 6.0
#: seconds the watcher has to record the runs and exit before the kernel ends the process
LAST_RESORT_S = 3
#: seconds between the watcher's checks for an interrupt that was swallowed (module docstring)
REDELIVER_POLL_S = 0.05
_INTERRUPTS = (signal.SIGINT, signal.SIGTERM)
#: the interrupts this process has received (in order)
_received: list[int] = []
#: what the running command kept and how to resume it, said when the watcher ends the command
_deadline_note: list[Callable[[], str]] = []


def _raise_interrupt(signum: int, frame: object) -> None:
    _received.append(signum)
    raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")


def interrupted_exit_code() -> int:
    """The exit status of a command ended by the first interrupt it received: ``128 + signal``, as a
    shell reports a process the signal ended (130 for SIGINT, 143 for SIGTERM; job schedulers read
    it); 130 when no signal was received (a KeyboardInterrupt raised some other way)."""
    return 128 + (_received[0] if _received else signal.SIGINT)


def was_interrupted() -> bool:
    """Whether this process has received SIGINT or SIGTERM while a guard was installed."""
    return bool(_received)


def set_deadline_note(note: Callable[[], str]) -> None:
    """What the watcher says after recording the runs, if it has to end this command: the note the
    command prints when it stops by itself (what it kept, how to resume). Called in the watcher
    thread while the main thread is stuck, so it reads files, not the command's open registry."""
    _deadline_note[:] = [note]


def end_interrupted_process(exit_code: int) -> NoReturn:
    """End the process of an interrupted command now: its atexit handlers run (under an alarm of
    :data:`LAST_RESORT_S` seconds), then ``os._exit``, skipping the interpreter's teardown.

    The command has recorded its runs and printed its note; the teardown is where a library's
    background work can hold the process: after SIGTERM during an MJX cell's XLA compilation the
    sweep returned in 0.3 s, then teardown waited 46 s and crashed (SIGSEGV).
    """
    signal.alarm(LAST_RESORT_S)
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(exit_code)


class CommandInterrupted(Exception):
    """A KeyboardInterrupt that left a command (its message: the signal), on its way to
    :func:`econmotor.cli.main` past Typer, which would end it as exit 130 whatever the signal."""


class InterruptibleGroup(TyperGroup):
    """The app's command group: a KeyboardInterrupt that leaves a command leaves Typer as
    :class:`CommandInterrupted` (module docstring)."""

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise CommandInterrupted(str(exc)) from exc


class InterruptGuard:
    """SIGINT and SIGTERM raise KeyboardInterrupt, whatever disposition the process inherited, and
    a watcher thread enforces the deadline (module docstring). :meth:`close` puts everything back.

    A shell that starts a job in the background (or ``make`` under ``trap '' INT``) leaves SIGINT
    ignored, and Python then installs no handler of its own; the run would not stop on Ctrl-C or
    be recorded as interrupted. Every long command turns KeyboardInterrupt into a recorded
    ``interrupted`` run and a note of what was kept and how to resume. Outside the main thread
    (where signals cannot be handled) it does nothing.
    """

    def __init__(self, grace_s: float = INTERRUPT_GRACE_S) -> None:
        self.previous: dict[int, object] = {}
        self._done = threading.Event()
        self._swallowed = threading.Event()
        self._old_unraisablehook = sys.unraisablehook
        self._sockets: tuple[socket.socket, socket.socket] | None = None
        self._old_wakeup_fd = -1
        self._old_alarm: object = None
        if threading.current_thread() is not threading.main_thread():
            return
        self.previous = {signum: signal.signal(signum, _raise_interrupt) for signum in _INTERRUPTS}
        self._old_alarm = signal.signal(signal.SIGALRM, signal.SIG_DFL)
        reader, writer = socket.socketpair()
        writer.setblocking(False)
        self._sockets = (reader, writer)
        self._old_wakeup_fd = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
        sys.unraisablehook = self._unraisable
        threading.Thread(target=self._watch, args=(reader, grace_s), name="econmotor-interrupt-deadline",
                         daemon=True).start()

    def _watch(self, reader: socket.socket, grace_s: float) -> None:
        while True:
            try:
                data = reader.recv(64)
            except OSError:
                return
            if not data:  # closed: the command ended
                return
            received = [signum for signum in data if signum in _INTERRUPTS]
            if received:
                break
        _received.extend(received)
        deadline = time.monotonic() + grace_s
        while not self._done.wait(REDELIVER_POLL_S):
            if self._swallowed.is_set():
                self._swallowed.clear()
                _thread.interrupt_main(received[0])
            if time.monotonic() >= deadline:
                break
        if self._done.is_set():
            return
        name = signal.Signals(received[0]).name
        signal.alarm(LAST_RESORT_S)
        try:
            marked = interrupt_own_runs(f"KeyboardInterrupt: signal {name} (the command was still busy "
                                        f"{grace_s:.0f} s later, in a call that cannot be interrupted)")
        except Exception:  # the last word: whatever the registry says, the process ends
            marked = []
        runs = f"run(s) {', '.join(f'#{i}' for i in marked)} recorded as interrupted" if marked \
            else "no running run of this process to record"
        try:
            note = "".join(f" {say()}" for say in _deadline_note)
        except Exception:  # the note is a courtesy: the process ends all the same
            note = ""
        sys.stderr.write(f"interrupted ({name}): still busy {grace_s:.0f} s later in a call that cannot be "
                         f"interrupted; {runs}; exiting now.{note}\n")
        sys.stderr.flush()
        os._exit(interrupted_exit_code())

    def _unraisable(self, unraisable: sys.UnraisableHookArgs) -> None:
        """A KeyboardInterrupt that Python swallowed (module docstring): the watcher raises it
        again. It must not be raised here: an exception in this hook is swallowed too."""
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _received and not self._done.is_set():
            self._swallowed.set()
            return
        self._old_unraisablehook(unraisable)

    def close(self) -> None:
        """The command has ended: stop the watcher and put the previous handlers back."""
        self._done.set()
        _deadline_note.clear()
        if self._sockets is None:
            return
        sys.unraisablehook = self._old_unraisablehook
        signal.set_wakeup_fd(self._old_wakeup_fd)
        for sock in self._sockets:
            sock.close()
        for signum, handler in self.previous.items():
            if handler is not None:  # None: a handler not set from Python, which cannot be put back
                signal.signal(signum, handler)
        if self._old_alarm is not None:
            signal.signal(signal.SIGALRM, self._old_alarm)
