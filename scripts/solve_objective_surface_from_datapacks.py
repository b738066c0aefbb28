#!/usr/bin/env python
"""Seed-compatible entry point: ``econmotor solve`` (see ``econmotor solve --help``)."""

import sys

from econmotor.cli import main

if __name__ == "__main__":
    sys.exit(main(["solve", *sys.argv[1:]]))
