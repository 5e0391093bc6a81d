"""Benchmarks: each prints a table and writes bench/results/*.json and PNG figures; run as python -m bench.NAME."""
