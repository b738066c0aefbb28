"""Seed-compatible entry point: ``python scripts/train_sac_objective.py ARGS`` = ``econmotor shadow ARGS``."""

import sys

from econmotor.cli import main

if __name__ == "__main__":
    sys.exit(main(["shadow", *sys.argv[1:]]))
