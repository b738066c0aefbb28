"""Compilation, ahead of need and from the persistent cache.

- :class:`CompiledAhead`: a jitted function lowered and compiled by XLA in a background thread
  (a non-daemon thread: the interpreter waits for it at exit instead of tearing down under a
  running compile, and an interrupted command ends through ``os._exit`` after its atexit handlers,
  ``cli/_interrupts.py``), so a run's evaluation compiles while its first training iterations run;
  a call waits for the compile, then runs the compiled executable. A training run compiles its iteration
  so, for the shapes of a train state (``jax.eval_shape``) while it resets its envs.
- :class:`CacheWatch`: counts JAX's persistent compilation cache hits (``jax.monitoring`` events), so
  a run can say when it started warm.
"""

from __future__ import annotations

import threading
from typing import Any

import jax

_HIT = "/jax/compilation_cache/cache_hits"
_SAVED = "/jax/compilation_cache/compile_time_saved_sec"


class CompiledAhead:
    """``jitted`` compiled for ``example_args`` (their shapes and dtypes) in a background thread.

    Args:
        jitted: a ``jax.jit`` function.
        example_args: arguments with the shapes, dtypes and tree structure of every later call (arrays, or
            ``jax.ShapeDtypeStruct`` trees such as ``jax.eval_shape`` gives).
        name: the thread's name.
    """

    def __init__(self, jitted: Any, *example_args: Any, name: str = "econmotor-compile") -> None:
        self._jitted = jitted
        self._compiled: Any = None
        self.error: BaseException | None = None
        #: a call's arguments were unlike the examples, so the jitted function (compiling anew) answers
        self.fell_back = False
        self._thread = threading.Thread(target=self._compile, args=example_args, name=name, daemon=False)
        self._thread.start()

    def _compile(self, *args: Any) -> None:
        try:
            self._compiled = self._jitted.lower(*args).compile()
        except Exception as exc:  # the call falls back to the jitted function, which raises it where it belongs
            self.error = exc

    @property
    def ready(self) -> bool:
        return not self._thread.is_alive()

    def __call__(self, *args: Any) -> Any:
        self._thread.join()
        if self._compiled is not None:
            try:
                return self._compiled(*args)
            except (TypeError, ValueError):  # arguments unlike the examples (shapes, dtypes): jit them
                self._compiled, self.fell_back = None, True
        return self._jitted(*args)


class CacheWatch:
    """Counts persistent-cache hits and the compile seconds they saved since it was made."""

    _lock = threading.Lock()
    _hits = 0
    _saved_s = 0.0
    _installed = False

    def __init__(self) -> None:
        cls = type(self)
        with cls._lock:
            if not cls._installed:
                jax.monitoring.register_event_listener(cls._on_event)
                jax.monitoring.register_event_duration_secs_listener(cls._on_duration)
                cls._installed = True
            self._start = (cls._hits, cls._saved_s)

    @classmethod
    def _on_event(cls, event: str, **_: Any) -> None:
        if event == _HIT:
            with cls._lock:
                cls._hits += 1

    @classmethod
    def _on_duration(cls, event: str, duration: float, **_: Any) -> None:
        if event == _SAVED:
            with cls._lock:
                cls._saved_s += float(duration)

    @property
    def hits(self) -> int:
        return type(self)._hits - self._start[0]

    @property
    def saved_s(self) -> float:
        return type(self)._saved_s - self._start[1]
