"""Optical elements: thin sheets with their own physics on a node (see `base`)."""
