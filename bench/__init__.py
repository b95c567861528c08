"""Benchmarks: each `bench/bench_*.py` module measures one thing against its peer, side by side."""
