"""The device JAX runs the mjx backend on: its description, and XLA's persistent compilation cache (each jitted
function compiles once per process; the cache lets later processes skip most of it)."""

from __future__ import annotations

from pathlib import Path

import jax


def device_description() -> str:
    """The device JAX trains on, e.g. ``GPU (NVIDIA H100 80GB HBM3)`` or ``CPU (cpu)``."""
    device = jax.devices()[0]
    return f"{device.platform.upper()} ({device.device_kind})"


def enable_compilation_cache(path: str | Path | None) -> None:
    """Point JAX's persistent compilation cache at ``path`` unless the user configured one."""
    if path is None or jax.config.jax_compilation_cache_dir:
        return
    Path(path).mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
