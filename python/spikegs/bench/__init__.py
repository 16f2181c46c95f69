"""Benchmarks: every figure is an error next to a time, with a ratio against a named alternative."""
