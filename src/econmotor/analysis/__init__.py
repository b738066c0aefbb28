"""econmotor.analysis"""
