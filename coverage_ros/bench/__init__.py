"""Benchmark harnesses behind scripts/bench_*: they print numbers, they are not tests."""
