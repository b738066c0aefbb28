"""SQLAlchemy 2 tables of the run registry (schema version :data:`SCHEMA_VERSION`).

Tables: ``econmotor_schema`` (one row: the schema version), ``tasks``, ``robots``,
``datapacks``, ``runs`` (train and eval runs), ``run_datapacks`` (which datapacks a
run used, in order), ``episodes`` (one per-episode summary per row) and ``reports``.

Metric dictionaries are stored as JSON. JSON has no infinity or NaN, yet econ
metrics legitimately hold ``inf`` (a robot that completed nothing has an infinite
unit cost), so :class:`FloatJSON` stores non-finite floats as ``{"$float": "inf"}``
and reads them back as floats: what goes in comes out equal.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from typing import Any

from sqlalchemy import JSON, DateTime, Float, ForeignKey, Index, Integer, String, Text
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator

#: Bump when a table or column changes; an older or newer database is refused with a clear error.
SCHEMA_VERSION = 1

RUN_KINDS = ("train", "eval", "shadow")  # shadow: econmotor shadow runs (no evaluation episodes)
#: ``abandoned``: was ``running`` but its owner process is gone (killed); set when a registry is opened.
RUN_STATUSES = ("running", "completed", "failed", "interrupted", "abandoned")

#: Per-episode summary fields also stored as columns (for SQL filters and fast vector reads).
EPISODE_COLUMNS = (
    "mpl_units_per_hour",
    "error_rate",
    "energy_wh",
    "energy_wh_per_unit",
    "units_completed",
    "units_attempted",
    "errors",
    "episode_length_s",
    "implied_wage_usd_per_hour",
    "wage_parity",
    "robot_unit_cost_usd",
    "risk_score",
    "novelty_score",
)


def utc_now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def encode_floats(value: Any) -> Any:
    """Replace non-finite floats (at any depth) by ``{"$float": "inf" | "-inf" | "nan"}``."""
    if isinstance(value, float) and not math.isfinite(value):
        return {"$float": repr(value)}
    if isinstance(value, dict):
        return {str(k): encode_floats(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [encode_floats(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):  # numpy scalars
        return encode_floats(value.item())
    return value


def decode_floats(value: Any) -> Any:
    """Inverse of :func:`encode_floats`."""
    if isinstance(value, dict):
        if set(value) == {"$float"}:
            return float(value["$float"])
        return {k: decode_floats(v) for k, v in value.items()}
    if isinstance(value, list):
        return [decode_floats(v) for v in value]
    return value


class FloatJSON(TypeDecorator):
    """JSON that round-trips ``inf`` and ``nan`` (see the module docstring)."""

    impl = JSON
    cache_ok = True

    def process_bind_param(self, value: Any, dialect: Any) -> Any:
        if value is None:
            return None
        # json round trip: fails here (not inside the driver) on values JSON cannot hold
        return json.loads(json.dumps(encode_floats(value), allow_nan=False))

    def process_result_value(self, value: Any, dialect: Any) -> Any:
        return None if value is None else decode_floats(value)


class Base(DeclarativeBase):
    pass


class SchemaVersionRow(Base):
    __tablename__ = "econmotor_schema"

    version: Mapped[int] = mapped_column(Integer, primary_key=True)
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utc_now)


class TaskRow(Base):
    """A task id and the economics it was priced with (the catalog entry at the time)."""

    __tablename__ = "tasks"

    task_id: Mapped[str] = mapped_column(String(200), primary_key=True)
    description: Mapped[str] = mapped_column(Text, default="")
    unit: Mapped[str] = mapped_column(String(200), default="")
    error_definition: Mapped[str] = mapped_column(Text, default="")
    economics: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    source: Mapped[str] = mapped_column(Text, default="")
    updated_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utc_now)


class RobotRow(Base):
    """A robot (or simulated body) the backends train, e.g. ``hopper`` (one id on every backend; older
    registries hold ``mujoco:Hopper-v5``-style ids, read as any other string)."""

    __tablename__ = "robots"

    robot_id: Mapped[str] = mapped_column(String(200), primary_key=True)
    backend: Mapped[str] = mapped_column(String(100), default="")
    description: Mapped[str] = mapped_column(Text, default="")
    details: Mapped[dict] = mapped_column(FloatJSON, default=dict)


class DatapackRow(Base):
    """A datapack as validated YAML (``DatapackConfig.to_dict()``), addressable by id."""

    __tablename__ = "datapacks"

    datapack_id: Mapped[str] = mapped_column(String(200), primary_key=True)
    description: Mapped[str] = mapped_column(Text, default="")
    config: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    source: Mapped[str] = mapped_column(Text, default="")
    registered_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utc_now)


class RunRow(Base):
    """One training or evaluation run, recorded when it starts and updated when it ends."""

    __tablename__ = "runs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    kind: Mapped[str] = mapped_column(String(16))
    parent_run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id"), nullable=True)
    task_id: Mapped[str] = mapped_column(ForeignKey("tasks.task_id"))
    backend: Mapped[str] = mapped_column(String(100))
    robot_id: Mapped[str | None] = mapped_column(ForeignKey("robots.robot_id"), nullable=True)
    objective_name: Mapped[str] = mapped_column(String(200), default="objective")
    objective: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    datapack_ids: Mapped[list] = mapped_column(FloatJSON, default=list)
    config: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    seed: Mapped[int | None] = mapped_column(Integer, nullable=True)
    num_envs: Mapped[int | None] = mapped_column(Integer, nullable=True)
    max_steps: Mapped[int | None] = mapped_column(Integer, nullable=True)
    policy_path: Mapped[str | None] = mapped_column(Text, nullable=True)
    raw_metrics: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    econ_metrics: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    training_curve: Mapped[list] = mapped_column(FloatJSON, default=list)
    artifacts: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    status: Mapped[str] = mapped_column(String(16), default="running")
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    notes: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utc_now)
    finished_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)

    episodes: Mapped[list[EpisodeRow]] = relationship(back_populates="run", order_by="EpisodeRow.episode_index")

    __table_args__ = (Index("ix_runs_task_backend", "task_id", "backend"),)


class RunDatapackRow(Base):
    """Which datapacks a run used, in order (for SQL filters on datapacks)."""

    __tablename__ = "run_datapacks"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    datapack_id: Mapped[str] = mapped_column(String(200), primary_key=True)
    position: Mapped[int] = mapped_column(Integer, default=0)


class EpisodeRow(Base):
    """One evaluation episode: key fields as columns, the whole summary as JSON."""

    __tablename__ = "episodes"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), index=True)
    episode_index: Mapped[int] = mapped_column(Integer)
    termination_reason: Mapped[str] = mapped_column(String(100), default="max_steps")
    summary: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    mpl_units_per_hour: Mapped[float | None] = mapped_column(Float, nullable=True)
    error_rate: Mapped[float | None] = mapped_column(Float, nullable=True)
    energy_wh: Mapped[float | None] = mapped_column(Float, nullable=True)
    energy_wh_per_unit: Mapped[float | None] = mapped_column(Float, nullable=True)
    units_completed: Mapped[float | None] = mapped_column(Float, nullable=True)
    units_attempted: Mapped[float | None] = mapped_column(Float, nullable=True)
    errors: Mapped[float | None] = mapped_column(Float, nullable=True)
    episode_length_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    implied_wage_usd_per_hour: Mapped[float | None] = mapped_column(Float, nullable=True)
    wage_parity: Mapped[float | None] = mapped_column(Float, nullable=True)
    robot_unit_cost_usd: Mapped[float | None] = mapped_column(Float, nullable=True)
    risk_score: Mapped[float | None] = mapped_column(Float, nullable=True)
    novelty_score: Mapped[float | None] = mapped_column(Float, nullable=True)

    run: Mapped[RunRow] = relationship(back_populates="episodes")


class ReportRow(Base):
    """A rendered report: the JSON document and where its files were written."""

    __tablename__ = "reports"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    task_id: Mapped[str] = mapped_column(ForeignKey("tasks.task_id"))
    train_run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id"), nullable=True)
    eval_run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id"), nullable=True)
    document: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    files: Mapped[dict] = mapped_column(FloatJSON, default=dict)
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utc_now)
