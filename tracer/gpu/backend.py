"""`CudaBackend`: a query's photon batches on the CUDA card (the backend contract of `tracer.backends`).

    backend.run(kernel_id, scene: Shipment, query: Shipment, batch0, n_batches, size) -> (values, counters)
    backend.describe() -> {"name": "cuda", "device": "cuda:0 NVIDIA H100 80GB HBM3"}

Each batch is one CUDA thread (`tracer.gpu.transport`), seeded by its index as on the CPU, so the answer agrees
with `InProcess`'s within error bars. The scene's committed arrays stay on the card (:class:`DeviceScene`: sent
once per revision; a new revision whose geometry store is unchanged, a move, sends the top level only); the
materials, lights and the query's small arrays are sent once per `Shipment` key. The most recent
`KEEP_SCENES` scenes and `KEEP_SHIPMENTS` shipments stay.

One GPU job at a time: a process-wide lock holds each `run` (uploads, launch, read-back), so concurrent queries
queue for the card batch round by batch round.

A scene that does not fit: before any upload the bytes it needs are compared with the card's free memory
(:func:`free_bytes`, one small function tests replace); where they do not fit, `run` raises
`tracer.gpu.device.DoesNotFit` (a `TracerError`) saying how much was needed and free, and
`tracer.simulate.Simulation` answers that query on the CPU, saying why. Never a crash: a CUDA out-of-memory error
during an upload becomes the same error, and a kernel that fails to compile, launch or finish on the card a
`DeviceUnavailable`, which `Simulation` answers on the CPU the same way.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

import numpy as np

from tracer.accel.traverse import SceneArrays
from tracer.backends import BatchShape, KernelId, Shipment, nbytes
from tracer.gpu.device import DeviceUnavailable, DoesNotFit, choose
from tracer.gpu.transport import THREADS, Tallies, backward_kernel, forward_kernel
from tracer.gpu.traverse import SIMULATOR, STORE_FIELDS, TOP_FIELDS, DeviceScene, array_identity, cuda

#: one GPU job at a time in this process, whichever backend object runs it
GPU_LOCK = threading.Lock()
#: bytes of the card left free beyond what a run needs (the kernels' local memory, the CUDA context's own)
HEADROOM = 64 << 20


def free_bytes() -> int:
    """Free memory of the current CUDA device, bytes (``cuda.current_context().get_memory_info()``)."""
    if SIMULATOR:   # the simulator's memory is the host's: say the card has what it asks for
        return 1 << 62
    return int(cuda.current_context().get_memory_info()[0])


def _same(a: SceneArrays, b: SceneArrays, fields: tuple[str, ...]) -> bool:
    """Whether `a` and `b` hold the same host arrays in `fields` (the same memory, shape and type, as
    `DeviceScene` tells them apart: a revision's arrays are views of the scene's; `a` is kept alive beside its copy on
    the card, so its memory cannot be another array's)."""
    return all(array_identity(getattr(a, f)) == array_identity(getattr(b, f)) for f in fields)


def _to_card(obj: Any) -> Any:
    """`obj` (arrays, NamedTuples of arrays, numbers) with every array on the card; in the simulator the host
    arrays themselves (its kernels call the CPU's compiled code, which takes numpy arrays)."""
    if isinstance(obj, np.ndarray):
        return obj if SIMULATOR else cuda.to_device(np.ascontiguousarray(obj))
    if isinstance(obj, tuple) and hasattr(obj, "_fields"):
        return type(obj)(*(_to_card(o) for o in obj))
    if isinstance(obj, tuple):
        return tuple(_to_card(o) for o in obj)
    return obj


#: one batch per thread: a round of thousands of small batches, so the card has threads to run (its constants are
#: unmeasured: no GPU was lent yet; bench/bench_gpu.py measures photons/s and the time to 1 % on one)
GPU_SHAPE = BatchShape(forward_photons=256, backward_paths=1, first_round=1024, max_round=16384)


class CudaBackend:
    """Photon batches on CUDA device 0 (see the module docstring). Raises `tracer.gpu.device.DeviceUnavailable`
    at construction where numba-cuda finds no GPU (nor its simulator)."""

    name = "cuda"
    KEEP_SCENES = 2       # scenes' arrays kept on the card, most recent first
    KEEP_SHIPMENTS = 16   # materials, lights and queries kept on the card

    def __init__(self, shape: BatchShape = GPU_SHAPE) -> None:
        self.device = choose("cuda").name
        self.shape = shape
        self._scenes: OrderedDict[int, tuple[SceneArrays, DeviceScene]] = OrderedDict()   # id -> (host, card)
        self._shipped: OrderedDict[str, Any] = OrderedDict()   # shipment key -> its small arrays on the card
        self._n = 0

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "device": self.device}

    # -- data on the card -----------------------------------------------------------------------

    def _check_fits(self, nbytes: int, what: str) -> None:
        free = free_bytes()
        if nbytes + HEADROOM > free:
            raise DoesNotFit(f"{what} needs {_size(nbytes)} on {self.device}, which has {_size(free)} free "
                             f"({_size(HEADROOM)} kept in reserve)")

    def _scene(self, sa: SceneArrays) -> DeviceScene:
        """The card's copy of `sa`: the one kept where it is the same host arrays; else one whose geometry store
        is the same, brought up to date (a new revision after a move: the top level only); else a new upload."""
        for k, (host, ds) in self._scenes.items():
            if host is sa or _same(host, sa, SceneArrays._fields):
                self._scenes.move_to_end(k)
                return ds
        for k, (host, ds) in reversed(self._scenes.items()):
            if _same(host, sa, STORE_FIELDS):
                self._check_fits(nbytes(tuple(getattr(sa, f) for f in TOP_FIELDS)), "the scene's top level")
                try:
                    ds.update(sa)
                except Exception as exc:   # noqa: BLE001 - a failed upload leaves this copy half updated: drop it
                    del self._scenes[k]
                    raise _upload_error(exc, self.device) from None
                self._scenes[k] = (sa, ds)
                self._scenes.move_to_end(k)
                return ds
        need = nbytes(tuple(sa))
        if need + HEADROOM > free_bytes() and self._scenes:
            self._scenes.clear()   # what this backend holds is not needed for the new scene: free it now
            if not SIMULATOR:
                cuda.current_context().deallocations.clear()   # numba-cuda frees in batches, later, by default
        self._check_fits(need, "the scene")
        try:
            ds = DeviceScene(sa)
        except Exception as exc:   # noqa: BLE001 - an allocation the card refused despite the check
            raise _upload_error(exc, self.device) from None
        self._n += 1
        self._scenes[self._n] = (sa, ds)
        while len(self._scenes) > self.KEEP_SCENES:
            self._scenes.popitem(last=False)
        return ds

    def _small(self, key: str, parts: tuple) -> Any:
        """`parts` on the card, sent once per shipment key."""
        card = self._shipped.get(key)
        if card is None:
            self._check_fits(nbytes(parts), "the query's data")
            try:
                card = _to_card(parts)
            except Exception as exc:   # noqa: BLE001
                raise _upload_error(exc, self.device) from None
            self._shipped[key] = card
            while len(self._shipped) > self.KEEP_SHIPMENTS:
                self._shipped.popitem(last=False)
        self._shipped.move_to_end(key)
        return card

    # -- batches --------------------------------------------------------------------------------

    def run(self, kernel_id: KernelId, scene: Shipment, query: Shipment, batch0: int, n_batches: int, size: int):
        """Batches batch0 … batch0 + n_batches − 1 (`size` photons, or paths per patch, each) on the card."""
        from tracer.transport import backward
        from tracer.transport import forward as transport

        sa, mats, lights = scene.parts
        if kernel_id[0] == "forward":
            sens, n_bins = query.parts[1], int(query.parts[2])
            bins = n_bins * transport.tally_columns(bool(sens.observe[0]), bool(sens.observe[1]))
            n_counters = len(transport.COUNTERS)
        elif kernel_id[0] == "backward":
            bins, n_counters = int(query.parts[0].kind.shape[0]), len(backward.COUNTERS)
        else:
            raise ValueError(f"unknown kernel {kernel_id!r}")
        out = Tallies(np.zeros((n_batches, bins)), np.zeros((n_batches, n_counters), np.int64))
        blocks = (n_batches + THREADS - 1) // THREADS
        with GPU_LOCK:
            ds = self._scene(sa)
            m, lt = self._small(scene.key + ":materials-lights", (mats, lights))
            q = self._small(query.key, query.parts)
            self._check_fits(nbytes(out), "the batches' tallies")
            try:
                card = _to_card(out)
                if SIMULATOR:   # the kernel's njit callees run as the CPU's code: they call kinds by address
                    from tracer.optics.lights.dispatch import bind as bind_lights
                    from tracer.optics.surfaces.dispatch import bind

                    m, lt = bind(ds._kernel_arrays(), m), bind_lights(lt)
                if kernel_id[0] == "forward":
                    ra, sens, n_bins, seed = q
                    w0 = lights.flux_total[0] / size   # as forward_batches
                    forward_kernel[blocks, THREADS](ds._kernel_arrays(), ra, m, lt, sens, n_bins, seed, batch0, size,
                                                    w0, card)
                else:
                    qa, seed = q
                    backward_kernel[blocks, THREADS](ds._kernel_arrays(), m, lt, qa, seed, batch0, size, card)
                if SIMULATOR:
                    return out.values, out.counters
                return card.values.copy_to_host(), card.counters.copy_to_host()
            except Exception as exc:   # noqa: BLE001 - compiling, launching or reading back failed on the card:
                # the query is answered on the CPU, saying why (`tracer.simulate`), never a crash
                raise DeviceUnavailable(f"the {kernel_id[0]} kernel failed on {self.device}: "
                                        f"{type(exc).__name__}: {str(exc)[:500]}") from exc


def _size(nbytes: int) -> str:
    """Bytes for people: "3.2 KiB", "12.0 MiB", "1.5 GiB"."""
    for unit, shift in (("GiB", 30), ("MiB", 20)):
        if nbytes >= 1 << shift:
            return f"{nbytes / (1 << shift):.1f} {unit}"
    return f"{nbytes / 1024:.1f} KiB"


def _upload_error(exc: Exception, device: str) -> DoesNotFit:
    return DoesNotFit(f"the data could not be placed on {device}: {type(exc).__name__}: {exc}")
