"""Benchmarks users run: each prints its figures with the peer measured in the same run."""
