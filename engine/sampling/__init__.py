"""Inference: energies on decoded motion, the guided streaming sampler and its events."""
