"""Benchmarks of the catadioptric project, run with `python -m bench` (`make bench`)."""
