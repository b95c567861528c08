"""LumenLink: keeps a physically based light simulation in step with a CAD model.

This package holds only the command line and the end-to-end demo; the work is done by
`tracer` (ray tracing and light transport), `cad_adapter` (CAD documents to pushed trees)
and `service` (the REST service that holds scenes).
"""

__version__ = "0.1.0"
