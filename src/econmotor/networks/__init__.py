"""econmotor.networks"""
