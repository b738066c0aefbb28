"""``econmotor datapacks record-clip``: record a motion clip from a trained policy's rollout."""

from __future__ import annotations

import contextlib
from pathlib import Path

import typer

from econmotor.cli._app import console, datapacks_app, make_backend, set_cpu_threads
from econmotor.cli.validation import check_flags, check_name, check_output_file
from econmotor.config.datapacks import DatapackConfig, MotionClipRef, save_datapack_config
from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import DEFAULT_BACKEND, backend_class, known_backends


@datapacks_app.command("record-clip")
def record_clip_command(
    policy: str = typer.Option(..., "--policy", help="A run directory (policy id) of --motor-backend."),
    motor_backend: str = typer.Option(DEFAULT_BACKEND, "--motor-backend", help="The backend that trained it."),
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
    if not backend_class(motor_backend).capabilities.records_clips:
        raise ConfigError("--motor-backend", None, f"backend '{motor_backend}' does not record motion clips",
                          [b for b in known_backends() if backend_class(b).capabilities.records_clips])
    set_cpu_threads()
    path = make_backend(motor_backend).record_clip(policy, out, num_steps=steps, seed=seed)
    console.print(f"clip written: {path}")
    if datapack_out is not None:
        # relative to the datapack file when the clip lies below it, so the pair can be moved together
        clip_ref = path.resolve()
        with contextlib.suppress(ValueError):
            clip_ref = clip_ref.relative_to(datapack_out.resolve().parent)
        pack = DatapackConfig(id=datapack_id or path.stem, description=f"motion clip recorded from {policy}",
                              motion_clips=(MotionClipRef(str(clip_ref), 1.0),))
        console.print(f"datapack written: {save_datapack_config(pack, datapack_out)}")
