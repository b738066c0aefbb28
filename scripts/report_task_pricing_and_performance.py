#!/usr/bin/env python
"""Seed-compatible entry point: ``python scripts/report_task_pricing_and_performance.py ARGS``
is ``econmotor report ARGS`` (accepts the spec's example command line verbatim)."""

import sys

from econmotor.cli import main

if __name__ == "__main__":
    sys.exit(main(["report", *sys.argv[1:]]))
