"""The task catalog: task ids -> economics + one entry per backend that can run them."""

from econmotor.tasks.catalog import TaskCatalog, TaskSpec, get_task, load_catalog

__all__ = ["TaskCatalog", "TaskSpec", "get_task", "load_catalog"]
