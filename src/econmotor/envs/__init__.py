"""econmotor.envs"""
