"""Datapacks, as the specification names them (``motor_backend/datapacks.py``): the schema and the provider live
in :mod:`econmotor.config.datapacks`, below every package that reads a datapack; these are its names."""

from econmotor.config.datapacks import (  # noqa: F401
    DATAPACK_KEYS,
    DatapackBundle,
    DatapackConfig,
    DatapackProvider,
    MotionClipRef,
    load_datapack_configs,
    parse_datapack,
    save_datapack_config,
)
