"""econmotor.rl"""
