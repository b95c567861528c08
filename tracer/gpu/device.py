"""Which device a process computes on: ``LUMENLINK_DEVICE=auto|cpu|cuda`` (``lumenlink serve --device``).

``auto`` takes CUDA where numba-cuda finds a GPU, else the CPU, with the reason logged once; ``cuda`` without a
usable GPU is an error at start (:class:`DeviceUnavailable`, ``lumenlink serve`` exits 2 with the reason).

Where CUDA is chosen, the photon batches of every query run on the card (:class:`tracer.gpu.backend.CudaBackend`:
one thread per batch, `tracer.gpu.transport`) and ray queries have their kernels too (:mod:`tracer.gpu.traverse`);
a scene that does not fit on the card (:class:`DoesNotFit`) is answered on the CPU, saying why. An answer's
``device`` says where its batches really ran (``"cuda:0 <card>"``, :func:`cpu_name`).
"""

from __future__ import annotations

import importlib.util
import logging
from dataclasses import dataclass

from tracer.errors import TracerError

log = logging.getLogger("lumenlink.device")

CHOICES = ("auto", "cpu", "cuda")


class DeviceUnavailable(TracerError, RuntimeError):
    """``cuda`` was asked for where no GPU can be used; the message says why (a `TracerError`: the package's one
    root, and a RuntimeError like `tracer.backends.BackendUnavailable`: the hardware is not there, not bad input)."""


class DoesNotFit(DeviceUnavailable):
    """What a query needs does not fit in the card's free memory (the message says how much was needed and free);
    `tracer.simulate.Simulation` then answers that query on the CPU, saying why."""


@dataclass(frozen=True)
class Device:
    requested: str    # auto, cpu or cuda
    kind: str         # "cuda" or "cpu": where GPU work goes
    name: str         # "cuda:0 NVIDIA H100 80GB HBM3", "cuda:0 simulator", "cpu"
    reason: str       # why the CPU, where auto fell back to it ("" otherwise)


def cpu_name(threads: int | None = None) -> str:
    """The ``device`` of an answer computed on the CPU: ``"cpu:<threads> threads"``."""
    if threads is None:
        import numba

        threads = int(numba.get_num_threads())
    return f"cpu:{int(threads)} threads"


def find_cuda() -> tuple[str | None, str]:
    """``("cuda:0 <name>", "")`` where numba-cuda finds a GPU (or runs its simulator), else ``(None, why not)``."""
    if importlib.util.find_spec("numba_cuda") is None:
        return None, "numba-cuda is not installed (pip install 'lumenlink[gpu]')"
    try:
        from tracer.gpu import cuda

        numba_cuda = cuda()
        from numba.core import config

        if config.ENABLE_CUDASIM:
            return "cuda:0 simulator", ""
        if not numba_cuda.is_available():
            return None, "numba-cuda finds no CUDA GPU (no driver or no device)"
        dev = numba_cuda.get_current_device()
        name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
        return f"cuda:{dev.id} {name}", ""
    except Exception as exc:   # noqa: BLE001 - any failure to reach the GPU is a reason to say
        return None, f"numba-cuda cannot use the GPU: {type(exc).__name__}: {exc}"


_LOGGED: set[str] = set()


def choose(requested: str) -> Device:
    """The device for ``requested`` (auto, cpu, cuda); raises :class:`DeviceUnavailable` for cuda without a GPU."""
    if requested not in CHOICES:
        raise ValueError(f"device must be one of {', '.join(CHOICES)}, got {requested!r}")
    if requested == "cpu":
        return Device("cpu", "cpu", "cpu", "")
    name, why = find_cuda()
    if name is None:
        if requested == "cuda":
            raise DeviceUnavailable(f"device cuda was asked for, but {why}")
        dev = Device("auto", "cpu", "cpu", why)
        if why not in _LOGGED:   # once per process
            _LOGGED.add(why)
            log.info("device auto: the CPU, because %s", why)
        return dev
    dev = Device(requested, "cuda", name, "")
    if name not in _LOGGED:
        _LOGGED.add(name)
        log.info("device %s: %s; photon batches run there (a scene that does not fit: on the CPU)", requested,
                 name)
    return dev
