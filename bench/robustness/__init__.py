"""Robustness sweeps of the controllers (`python -m bench.robustness`; see __main__'s docstring)."""
