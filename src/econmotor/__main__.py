from econmotor.cli import entrypoint

entrypoint()
