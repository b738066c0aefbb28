"""``econmotor datapacks record-clip``: record a motion clip from a trained policy's rollout."""

from __future__ import annotations

import contextlib
from pathlib import Path

import typer

from econmotor.cli._app import console, datapacks_app, set_cpu_threads
from econmotor.cli.validation import check_flags, check_name, check_output_file
from econmotor.motor_backend.datapacks import DatapackConfig, MotionClipRef, save_datapack_config


@datapacks_app.command("record-clip")
def record_clip_command(
    policy: str = typer.Option(..., "--policy", help="A mujoco run directory (policy id)."),
    out: Path = typer.Option(..., "--out", help="Clip file to write (.npz with qpos [T, nq] and fps)."),
    steps: int = typer.Option(500, "--steps", help="Control steps to record (stops early on a fall)."),
    seed: int = typer.Option(0, "--seed"),
    datapack_out: Path = typer.Option(None, "--datapack-out", help="Also write a datapack YAML using the clip."),
    datapack_id: str = typer.Option(None, "--datapack-id", help="Id of that datapack (default: the clip's name)."),
) -> None:
    """Roll a trained policy out deterministically and save its poses as a reference clip."""
    check_flags(steps=steps, seed=seed)
    check_output_file("--out", out)
    check_output_file("--datapack-out", datapack_out)
    check_name("--datapack-id", datapack_id)
    set_cpu_threads()
    from econmotor.motor_backend.mujoco.backend import MujocoBackend

    path = MujocoBackend().record_clip(policy, out, num_steps=steps, seed=seed)
    console.print(f"clip written: {path}")
    if datapack_out is not None:
        # relative to the datapack file when the clip lies below it, so the pair can be moved together
        clip_ref = path.resolve()
        with contextlib.suppress(ValueError):
            clip_ref = clip_ref.relative_to(datapack_out.resolve().parent)
        pack = DatapackConfig(id=datapack_id or path.stem, description=f"motion clip recorded from {policy}",
                              motion_clips=(MotionClipRef(str(clip_ref), 1.0),))
        console.print(f"datapack written: {save_datapack_config(pack, datapack_out)}")
