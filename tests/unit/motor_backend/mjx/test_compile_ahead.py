"""An evaluation or iteration compiled ahead in a background thread (motor_backend/mjx/compile.py): the
same results as the jitted function, from the shapes of a state too, and a process whose compile is still
running ends cleanly, on a normal exit and on SIGINT / SIGTERM under the CLI's interrupt guard (no abort,
no "Fatal Python error")."""

from __future__ import annotations

import signal
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.motor_backend.mjx.compile import CacheWatch, CompiledAhead


def test_a_function_compiled_ahead_answers_as_the_jitted_one():
    jitted = jax.jit(lambda x, y: jnp.tanh(x @ y).sum(axis=0))
    x, y = jnp.ones((4, 3)), jnp.arange(6.0).reshape(3, 2)
    ahead = CompiledAhead(jitted, x, y)
    np.testing.assert_array_equal(np.asarray(ahead(x * 2, y)), np.asarray(jitted(x * 2, y)))
    assert ahead.ready and ahead.error is None
    wider = jnp.ones((4, 5)), jnp.ones((5, 2))  # unlike the examples: the jitted function answers
    np.testing.assert_array_equal(np.asarray(ahead(*wider)), np.asarray(jitted(*wider)))
    assert ahead.fell_back
    assert CacheWatch().hits == 0  # a new watch counts from now


def test_an_iteration_compiled_ahead_for_the_shapes_of_its_state_runs_the_state_it_is_given():
    """As ``MjxLearner`` compiles its iteration: for ``jax.eval_shape`` of the state and a Python float, donating
    the state; the concrete state and the weights 1.0 and 0.0 then run the executable compiled ahead."""
    def build():
        return {"w": jnp.ones((3, 3)), "step": jnp.asarray(0, jnp.int32)}

    def iteration(state, weight=1.0):
        return {"w": state["w"] * 2.0 * weight, "step": state["step"] + 1}, jnp.sum(state["w"])

    jitted = jax.jit(iteration, donate_argnums=0)
    ahead = CompiledAhead(jitted, jax.eval_shape(build), 1.0)
    state, total = ahead(build(), 1.0)
    state, _ = ahead(state, 0.0)
    assert float(total) == 9.0 and int(state["step"]) == 2 and float(jnp.sum(state["w"])) == 0.0
    assert not ahead.fell_back and ahead.error is None


# a program that takes XLA a while (a long unrolled scan), compiled ahead; the process then ends at once
SLOW_COMPILE = """
import os, signal, sys, time
import jax, jax.numpy as jnp
from econmotor.motor_backend.mjx.compile import CompiledAhead

def body(c, _):
    return jnp.sin(c) @ jnp.cos(c.T) + c, None

f = jax.jit(lambda c: jax.lax.scan(body, c, None, length=400, unroll=400)[0])
mode = sys.argv[1]
if mode != "exit":
    from econmotor.cli._interrupts import InterruptGuard, end_interrupted_process, interrupted_exit_code
    guard = InterruptGuard()
ahead = CompiledAhead(f, jnp.ones((32, 32)))
time.sleep(0.2)
print("compiling" if not ahead.ready else "compiled already", flush=True)
if mode == "exit":
    sys.exit(0)
try:
    signal.raise_signal(getattr(signal, mode))
    time.sleep(30)
except KeyboardInterrupt:
    guard.close()
    end_interrupted_process(interrupted_exit_code())
"""


@pytest.mark.parametrize(("mode", "code"), [("exit", 0), ("SIGINT", 130), ("SIGTERM", 143)])
def test_a_process_ends_cleanly_while_a_compile_runs_in_its_thread(mode: str, code: int):
    proc = subprocess.run([sys.executable, "-c", SLOW_COMPILE, mode], capture_output=True, text=True, timeout=300)
    assert proc.returncode == code, proc.stderr[-2000:]
    assert proc.stdout.startswith("compiling")  # the compile was still running when the process ended
    assert "Fatal Python error" not in proc.stderr and "Aborted" not in proc.stderr
    assert proc.returncode != -signal.SIGABRT
