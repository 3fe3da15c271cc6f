"""Benchmarks that print timings and ratios against peers measured in the same run.

Run one with ``python -m collision_sensor.tools.bench.<name>``; they are not tests and assert
nothing.
"""
