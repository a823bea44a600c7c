"""Benchmarks behind ``vishap bench NAME``: one module per stage, each writing JSON and charts.

Benchmarks measure (speed, accuracy, latency, jitter); tests only check correctness.
"""
