"""econmotor.report"""
