"""econmotor.store"""
