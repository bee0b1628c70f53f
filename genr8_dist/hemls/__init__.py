"""hemls"""
