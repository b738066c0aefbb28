"""The MuJoCo (CPU) courier backend: Gymnasium robots, SB3 learners, the economic overlay."""
