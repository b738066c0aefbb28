"""The run registry (SQLAlchemy): tasks, robots, datapacks, runs, episodes, reports.

See :mod:`econmotor.store.registry` for usage.
"""

from econmotor.store.engine import DB_URL_ENV, default_db_url, registry_exists
from econmotor.store.models import EPISODE_COLUMNS, RUN_KINDS, RUN_STATUSES, SCHEMA_VERSION
from econmotor.store.records import EpisodeRecord, ReportRecord, RunRecord
from econmotor.store.registry import Registry

__all__ = [
    "DB_URL_ENV",
    "EPISODE_COLUMNS",
    "RUN_KINDS",
    "RUN_STATUSES",
    "SCHEMA_VERSION",
    "EpisodeRecord",
    "Registry",
    "ReportRecord",
    "RunRecord",
    "default_db_url",
    "registry_exists",
]
