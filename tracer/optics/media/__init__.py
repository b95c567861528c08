"""Media: what the inside of a solid does to a photon between two surfaces (see `base`)."""
