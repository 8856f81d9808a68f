"""Simulation: glints on the engraved geometry, stereo triangulation, verification."""
