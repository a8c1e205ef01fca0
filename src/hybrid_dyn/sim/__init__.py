"""Simulation: the DART plant and the dataset generator."""
