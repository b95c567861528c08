"""What a Dask backend keeps on its workers (`tracer.backends.DaskBackend._ship`): the most recent shipments, at
most `KEEP_SHIPMENTS` of them and `KEEP_BYTES` together, and always the latest two (a query's scene and
receivers), so old revisions of a large scene do not pile up on every worker. The cluster is stood in for by a
client that records what it scatters (the policy is the backend's own; tests/tracer/test_dask_backend.py runs a
real cluster)."""

from __future__ import annotations

import numpy as np

from tracer.backends import DaskBackend, Shipment


class Scattered:
    status = "finished"


class RecordingClient:
    def __init__(self) -> None:
        self.sent: list[str] = []

    def scatter(self, data: dict, broadcast: bool, timeout: float) -> dict:
        assert broadcast
        self.sent.extend(data)
        return {name: Scattered() for name in data}


def shipment(megabytes: int, tag: int) -> Shipment:
    return Shipment((np.full(megabytes * 2**20 // 8, float(tag)), np.array([tag])))


def test_shipments_are_kept_by_count_and_by_bytes_and_sent_once() -> None:
    backend = DaskBackend("tcp://127.0.0.1:9")
    backend.KEEP_BYTES = 10 * 2**20
    client = RecordingClient()
    small = [shipment(1, k) for k in range(3)]
    assert small[0].nbytes == 2**20 + 8
    for s in small + small:              # the second time each is on the workers already: nothing sent
        backend._ship(client, s)
    assert len(client.sent) == 3
    big = [shipment(4, 10 + k) for k in range(3)]
    for s in big:
        backend._ship(client, s)
    kept = list(backend._shipped)
    assert kept == [big[1].key, big[2].key]              # 8 MB + 4 MB would pass 10 MB: the oldest go first
    huge = [shipment(12, 20), shipment(12, 21)]
    for s in huge:
        backend._ship(client, s)
    assert list(backend._shipped) == [s.key for s in huge]   # the latest two stay whatever their size
    backend.KEEP_BYTES = 2**40
    for k in range(DaskBackend.KEEP_SHIPMENTS + 5):
        backend._ship(client, shipment(0, 100 + k))
    assert len(backend._shipped) == DaskBackend.KEEP_SHIPMENTS
