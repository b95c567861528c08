"""UUIDs carried inside STEP files (placeholder until the writer lands)."""

from __future__ import annotations


def carried_uuids(reader, doc) -> dict[str, str]:
    return {}
