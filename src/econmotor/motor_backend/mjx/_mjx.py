"""``mujoco.mjx``, imported without its two lines of noise.

At import, ``mujoco.mjx`` prints ``Failed to import warp: ...`` and ``Failed to import
mujoco_warp: ...`` to stdout when NVIDIA Warp, its optional second implementation, is absent.
The JAX implementation this backend runs needs neither; to a user the lines read as a failure,
and they would mix into a command's stdout. Any other line the import prints is passed on.
"""

from __future__ import annotations

import contextlib
import io

with contextlib.redirect_stdout(io.StringIO()) as _printed:
    from mujoco import mjx

for _line in _printed.getvalue().splitlines():
    if not _line.startswith(("Failed to import warp:", "Failed to import mujoco_warp:")):
        print(_line)

__all__ = ["mjx"]
