"""econmotor: economic objectives for robot motor policies."""

__version__ = "0.1.0"
