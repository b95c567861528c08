"""Errors of the tracer package: one root, :class:`TracerError`, a :class:`ValueError`. Every error the tracer
raises derives from it (materials, lights, spectra, polarization, effects, photometry, queries, and
`tracer.backends.BackendUnavailable`, which is also a RuntimeError: the compute backend is not there).

Jitted kernels never raise; the Python facade (:mod:`tracer.scene`) validates its input before any
state changes and raises these, so a failed call leaves the scene as it was.
"""

from __future__ import annotations


class TracerError(ValueError):
    """Bad input to the tracer (shape, dtype, non-finite value, unknown id, singular transform...)."""


class NotCommittedError(TracerError):
    """A query on a scene that was never committed, or that has changes not yet committed."""


class UnknownIdError(TracerError, KeyError):
    """A geometry id or instance id that the scene does not hold."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


class SimulationError(TracerError):
    """A query or a scene the transport cannot simulate; the message says why."""
