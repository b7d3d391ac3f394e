"""Simulation helpers shared by the demo, the benchmark and the stress test."""
