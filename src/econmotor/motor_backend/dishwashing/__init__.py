"""The analytic dishwashing workcell backend (SB3 on :mod:`econmotor.envs.dishwashing`)."""
