"""LumenLink: keeps a physically based light simulation in step with a CAD model.

This package holds the command line, the Python client of the service (`lumenlink.Client`,
`lumenlink/client.py`) and the end-to-end demo; the work is done by `tracer` (ray tracing and light
transport), `cad_adapter` (CAD documents to pushed trees) and `service` (the REST service that holds
scenes).
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"
__all__ = ["Client", "LumenLinkError", "ServiceUnreachable"]


def __getattr__(name: str) -> Any:   # the client loads httpx on first use only (`lumenlink --help` stays quick)
    if name in __all__:
        from lumenlink import client

        return getattr(client, name)
    raise AttributeError(f"module 'lumenlink' has no attribute {name!r}")
