"""Live updates for the pages: server-sent events per scene (``GET /scenes/{id}/events``, `service.routes.pages`).

Where the events come from:

- `LiveRegistry.subscribe`: every push or assignment change sends ``scene`` ``{"revision"}``; a deleted scene
  sends ``deleted`` and its streams end.
- `PageEventsMiddleware`, after a push this process answered 200 (``PUT /scenes/{id}/document``, not a dry run):
  the push's changes are remembered (`EventHub.last_push`: the page highlights them) and ``push`` is sent with
  the revision and how many nodes were added, moved, geometry-changed, removed and renamed; after a sensor
  simulation answered 200, ``result`` ``{"sensor", "revision"}``.
- The job runner (`service.jobs.JobRunner.jobs`), looked at every `POLL_SECONDS` while somebody listens to a scene:
  ``job`` with the job's state (no result) whenever its status or progress changed, and ``result`` when a sensor
  job succeeded.

Bounds: at most `MAX_STREAMS` streams at once (503 beyond), each open at most `STREAM_SECONDS` (the browser's
``EventSource`` reconnects by itself, `RETRY_MS` later), each with a queue of `QUEUE_EVENTS` (a reader that falls
behind loses events and gets ``resync``: read the state again); a comment line every `HEARTBEAT_SECONDS` keeps
proxies from closing an idle stream. `EventHub.close` ends every stream at once: uvicorn waits for open responses
before it shuts down, so `lumenlink serve` and the demo call it when they are asked to stop.

A push through another service process on the same database reaches these streams as ``scene`` (the registry
notifies when this process catches up), without the push's change lists.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import re
import threading
import time
from collections import OrderedDict
from collections.abc import AsyncIterator, Callable
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.live import DELETED, LiveRegistry

log = logging.getLogger("lumenlink.service.events")

MAX_STREAMS = 64           # event streams open at once, all scenes together
STREAM_SECONDS = 300.0     # s a stream stays open; the browser reconnects
RETRY_MS = 1000            # what the stream tells the browser to wait before it reconnects
HEARTBEAT_SECONDS = 15.0   # s between keep-alive comments on an idle stream
QUEUE_EVENTS = 256         # events waiting per stream before it is told to resync
POLL_SECONDS = 0.5         # s between looks at the job runner
KEEP_PUSHES = 256          # scenes whose last push is remembered (oldest forgotten first)
MAX_LISTED = 10_000        # UUIDs kept per change kind of a remembered push (the counts are exact)
CHANGE_KINDS = ("added", "moved", "geometry_changed", "removed", "renamed")

_CLOSE = object()


class _Stream:
    """One open event stream: its scene and its queue (touched only on the event loop)."""

    def __init__(self, scene_id: str) -> None:
        self.scene_id = scene_id
        self.queue: asyncio.Queue[Any] = asyncio.Queue(maxsize=QUEUE_EVENTS)
        self.lost = False

    def put(self, item: Any) -> None:
        if item is _CLOSE:
            while True:  # make room: closing must get through
                try:
                    self.queue.put_nowait(_CLOSE)
                    return
                except asyncio.QueueFull:
                    self.queue.get_nowait()
        try:
            self.queue.put_nowait(item)
        except asyncio.QueueFull:
            self.lost = True


def sse(event: str, data: Any) -> bytes:
    """One server-sent event: its name and a JSON line of data."""
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n".encode()


class EventHub:
    """``app.state.events``: the event streams of this process and what feeds them (module docstring).

    Parameters
    ----------
    live : LiveRegistry
        Its change notifications become ``scene`` / ``deleted`` events.
    jobs : callable() -> list of job states, optional
        The job runner's `jobs()` if one runs (`service.simulation.SimulationHub`); looked at while streams are open.
    """

    def __init__(self, live: LiveRegistry, jobs: Callable[[], list[dict[str, Any]]] | None = None) -> None:
        self._jobs = jobs
        self._lock = threading.Lock()
        self._streams: dict[str, set[_Stream]] = {}
        self._pushes: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._poller: asyncio.Task[None] | None = None
        self.closed = False
        live.subscribe(self._on_change)

    # -- what the pages read -------------------------------------------------------------------

    def last_push(self, scene_id: str) -> dict[str, Any] | None:
        """The changes of the scene's last push through this process (UUID lists capped at `MAX_LISTED`)."""
        with self._lock:
            push = self._pushes.get(scene_id)
            return dict(push) if push is not None else None

    def streams(self, scene_id: str | None = None) -> int:
        """How many streams are open (for one scene, or all)."""
        with self._lock:
            if scene_id is not None:
                return len(self._streams.get(scene_id, ()))
            return sum(len(s) for s in self._streams.values())

    # -- sources ---------------------------------------------------------------------------------

    def _on_change(self, scene_id: str, revision: int) -> None:
        """`LiveRegistry` listener (runs in the thread that changed the scene, under its lock): hand over, return."""
        if revision == DELETED:
            with self._lock:
                self._pushes.pop(scene_id, None)
            self.publish(scene_id, "deleted", {"revision": revision})
        else:
            self.publish(scene_id, "scene", {"revision": revision})

    def record_push(self, scene_id: str, answer: dict[str, Any]) -> None:
        """Remember a push's answer (the page highlights its changes) and tell the scene's streams."""
        record: dict[str, Any] = {"revision": answer.get("revision"), "at": time.time()}
        counts = {}
        for kind in CHANGE_KINDS:
            uuids = answer.get(kind) or []
            uuids = [str(u) for u in uuids] if isinstance(uuids, list) else []
            counts[kind] = len(uuids)
            record[kind] = uuids[:MAX_LISTED]
        record["counts"] = counts
        with self._lock:
            self._pushes[scene_id] = record
            self._pushes.move_to_end(scene_id)
            while len(self._pushes) > KEEP_PUSHES:
                self._pushes.popitem(last=False)
        self.publish(scene_id, "push", {"revision": record["revision"], "counts": counts})

    def publish(self, scene_id: str, event: str, data: Any) -> None:
        """Send an event to the scene's streams; from any thread, never blocks (nothing to do without streams)."""
        loop = self._loop
        if loop is None or self.closed:
            return
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is loop:
            self._deliver(scene_id, (event, data))
            return
        with contextlib.suppress(RuntimeError):  # the loop is closing: nobody is listening any more
            loop.call_soon_threadsafe(self._deliver, scene_id, (event, data))

    def _deliver(self, scene_id: str, item: Any) -> None:
        with self._lock:
            targets = list(self._streams.get(scene_id, ()))
        for stream in targets:
            stream.put(item)

    async def _poll_jobs(self) -> None:
        """While streams are open: job states of their scenes, sent when their status or progress changed."""
        baseline: dict[str, tuple[Any, ...]] | None = None   # job id -> what was last sent about it
        while not self.closed:
            await asyncio.sleep(POLL_SECONDS)
            jobs = self._jobs
            with self._lock:
                scenes = {s for s, streams in self._streams.items() if streams}
            if jobs is None or (not scenes and baseline is not None):
                continue
            try:
                states = jobs()
            except Exception:  # never let a look at the runner end the poller
                log.exception("reading the job runner for the event streams failed")
                continue
            seen: dict[str, tuple[Any, ...]] = {}
            for state in states:
                progress = state.get("progress") or {}
                key = (state.get("status"), progress.get("photons"), progress.get("seconds_left"))
                seen[state["id"]] = key
                if baseline is None or state.get("scene_id") not in scenes or baseline.get(state["id"]) == key:
                    continue  # the first look only learns what is there; the state route shows it
                public = {k: v for k, v in state.items() if k not in ("result", "generation")}
                self._deliver(state["scene_id"], ("job", public))
                if state.get("status") == "succeeded" and state.get("kind") == "sensor":
                    self._deliver(state["scene_id"], ("result", {"sensor": state.get("sensor"),
                                                                 "revision": state.get("revision")}))
            baseline = seen

    # -- streams ---------------------------------------------------------------------------------

    def has_room(self) -> bool:
        """Whether another stream may open now."""
        with self._lock:
            return not self.closed and sum(len(s) for s in self._streams.values()) < MAX_STREAMS

    def open(self, scene_id: str) -> _Stream | None:
        """Register a stream for the scene (call on the event loop); None when `MAX_STREAMS` are open or closed."""
        loop = asyncio.get_running_loop()
        with self._lock:
            if self.closed or sum(len(s) for s in self._streams.values()) >= MAX_STREAMS:
                return None
            self._loop = loop
            stream = _Stream(scene_id)
            self._streams.setdefault(scene_id, set()).add(stream)
        if self._poller is None or self._poller.done():
            self._poller = loop.create_task(self._poll_jobs(), name="lumenlink-events-jobs")
        return stream

    def _drop(self, stream: _Stream) -> None:
        with self._lock:
            streams = self._streams.get(stream.scene_id)
            if streams is not None:
                streams.discard(stream)
                if not streams:
                    del self._streams[stream.scene_id]

    async def stream(self, scene_id: str, hello: dict[str, Any]) -> AsyncIterator[bytes]:
        """The bytes of one event stream: ``retry``, ``hello`` (the state's revision), then events until the
        stream's time is up, the scene is deleted, the client goes away or the hub closes. The stream is
        registered here, when the response starts, so one that never starts holds no place."""
        stream = self.open(scene_id)
        if stream is None:
            return
        loop = asyncio.get_running_loop()
        deadline = loop.time() + STREAM_SECONDS
        try:
            yield f"retry: {RETRY_MS}\n\n".encode()
            yield sse("hello", hello)
            while not self.closed:
                left = deadline - loop.time()
                if left <= 0:
                    break
                try:
                    item = await asyncio.wait_for(stream.queue.get(), timeout=min(HEARTBEAT_SECONDS, left))
                except TimeoutError:
                    yield b": keep-alive\n\n"
                    continue
                if item is _CLOSE:
                    break
                if stream.lost:
                    stream.lost = False
                    yield sse("resync", {})
                event, data = item
                yield sse(event, data)
                if event == "deleted":
                    break
        finally:
            self._drop(stream)

    def close(self) -> None:
        """End every stream now and stop looking at jobs (from any thread, a signal handler included)."""
        self.closed = True
        loop = self._loop
        if loop is None:
            return

        def _close_all() -> None:
            with self._lock:
                streams = [s for group in self._streams.values() for s in group]
            for s in streams:
                s.put(_CLOSE)
            if self._poller is not None:
                self._poller.cancel()

        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(_close_all)


_PUSH = re.compile(r"^/scenes/([0-9a-fA-F-]{36})/document$")
_SIMULATE = re.compile(r"^/scenes/([0-9a-fA-F-]{36})/sensors/([0-9a-fA-F-]{36})/simulate$")
PARSE_IN_THREAD_BYTES = 1 << 20   # a larger push answer is decoded off the event loop


class PageEventsMiddleware:
    """Watches the answers of pushes and sensor simulations for `EventHub` (module docstring); passes every
    message on unchanged. Installed innermost, so it sees only requests the other middleware let through."""

    def __init__(self, app: ASGIApp, events: EventHub) -> None:
        self.app = app
        self.events = events

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path, method = scope.get("path", ""), scope.get("method")
        push = _PUSH.match(path) if method == "PUT" else None
        simulate = _SIMULATE.match(path) if method == "POST" else None
        if push is None and simulate is None:
            await self.app(scope, receive, send)
            return
        status = [0]
        chunks: list[bytes] = []

        async def watching(message: Message) -> None:
            if message["type"] == "http.response.start":
                status[0] = message["status"]
            elif message["type"] == "http.response.body" and status[0] == 200 and push is not None:
                chunks.append(message.get("body", b""))
            await send(message)

        await self.app(scope, receive, watching)
        if status[0] != 200:
            return
        if simulate is not None:
            scene_id, sensor_id = simulate.group(1), simulate.group(2)
            self.events.publish(scene_id, "result", {"sensor": sensor_id})
            return
        assert push is not None
        body = b"".join(chunks)
        try:
            answer = (await run_in_threadpool(json.loads, body) if len(body) > PARSE_IN_THREAD_BYTES
                      else json.loads(body))
        except ValueError:
            return
        if isinstance(answer, dict) and not answer.get("dry_run"):
            self.events.record_push(push.group(1), answer)


def closing_server(app: Any, **config: Any) -> Any:
    """A `uvicorn.Server` for `app` that ends the app's event streams (``app.state.events``) as soon as it is asked
    to stop: uvicorn waits for open responses before it shuts down, and an event stream would stay open."""
    import uvicorn

    class _ClosingServer(uvicorn.Server):
        def handle_exit(self, sig: int, frame: Any) -> None:
            events = getattr(app.state, "events", None)
            if events is not None:
                events.close()
            super().handle_exit(sig, frame)

    return _ClosingServer(uvicorn.Config(app, **config))
