"""Surfaces: what a surface (or a thin optical element) does to a photon that reaches it (see `base`)."""
