"""Pushes: a CAD document tree validated, diffed against the scene's, applied to its tracer scene and stored.

Every push runs under the scene's lock. It decodes and validates the document, checks ``base_revision``,
diffs it against the current tree, applies the diff to the tracer scene (BLAS for new geometry, top level
for the rest), then writes the changed rows and the revision in one transaction whose
``UPDATE … WHERE revision = old`` guards against a writer in another process (`SceneStore.store_push`).
If the store fails, the in-memory scene is dropped and reloaded from the database on next use, so memory
never runs ahead of what was committed. Decoding reuses the previous push's bytes (`service.document`): a
byte-identical node list is recognised by one comparison, and otherwise only the nodes between the common
prefix and suffix are parsed, so the cost of a push follows what changed plus a few linear, vectorized passes.

A push also carries the nodes' identity records (product name, shape signature: what the CAD adapter matches
the next document by, served back by `Scenes.nodes`). They are kept per node uuid in memory and in
``node_identity``; a push compares them with the stored ones in memory and writes only those that changed (in
the push's transaction, or on their own when the tree is unchanged: no new revision). A dry run
(``push(..., dry_run=True)``) decodes, validates and diffs the same way and answers what the push would do,
changing nothing.

The scene remembers the nodes a push removes (``removed_nodes``: their node and identity records, path, world
placement and the assignments they carried) for ``removed_keep_revisions`` revisions and ``removed_keep_days``
days. The CAD adapter matches a document's new nodes against that memory (``GET /scenes/{id}/removed-nodes``);
a node that comes back under its old UUID is listed in ``restored_nodes`` and forgotten by the memory, and its
orphaned assignments are live again (``restored``).
"""

from __future__ import annotations

import contextlib
import datetime
import gc
import logging
import time
from collections.abc import Iterator
from typing import Any

from service.config import Settings
from service.document import count_nodes, decode_document, decode_incremental, remember, same_nodes
from service.elements import sync as element_sync
from service.errors import Conflict, Invalid, TooLarge
from service.scenes import Scenes, SceneState
from service.schemas import DocumentPush, IdentityIn
from service.store import IdentityChanges, Raced, RemovedChanges, color_of
from service.tree import ApplyStats, Tree, TreeDiff, TreeError, apply_to_scene, diff_trees

log = logging.getLogger("lumenlink.service")


@contextlib.contextmanager
def gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector: decoding a 20k-node document allocates ~10^6 objects,
    and generation-2 passes over them would otherwise cost more than the decode itself."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


class Pushes:
    """Applies pushed documents to the scenes of `scenes`."""

    def __init__(self, settings: Settings, scenes: Scenes) -> None:
        self.settings = settings
        self.scenes = scenes
        self.store = scenes.store

    def push(self, scene_id: str, body: bytes, dry_run: bool = False) -> dict[str, Any]:
        """Validate, diff, apply and store one pushed document; the answer of ``PUT /scenes/{id}/document``.

        With `dry_run` the body is decoded, validated and diffed exactly as for a push (a stale
        ``base_revision`` is still 409, an invalid body still 4xx), but nothing changes — not the
        database, the tree, the tracer scene, the identity records nor the live view — and
        geometries not uploaded yet are listed (``missing_geometries``) instead of refused.
        """
        t0 = time.perf_counter()
        state = self.scenes.state(scene_id)  # 404 before any work
        counted = count_nodes(body)   # a too-large tree is refused from its bytes: no decoding, no lock taken
        if counted > self.settings.max_nodes:
            raise TooLarge(f"the document has {counted} nodes; this service accepts at most "
                           f"{self.settings.max_nodes} (LUMENLINK_MAX_NODES)", limit=self.settings.max_nodes)
        with state.lock, gc_paused():
            state = self.scenes.state(scene_id)  # up to date under the lock (changed through another process)
            node_bytes = state.node_bytes
            missing: list[str] = []
            doc = same_nodes(body, node_bytes) if node_bytes is not None else None
            if doc is not None and doc.length_unit == state.tree.length_unit:
                # byte-identical node list: the tree is the current one
                new = state.tree
                t_decode = time.perf_counter()
            else:
                known = self.scenes.known_geometries
                inc = None
                if state.node_bytes is not None:  # decode only the nodes whose bytes changed
                    inc = decode_incremental(body, state.node_bytes, state.tree, known)
                if inc is not None:
                    decoded, node_bytes = inc
                else:
                    decoded = decode_document(body, state.tree.index, known)  # ValidationError
                    node_bytes = None
                doc = decoded.header
                t_decode = time.perf_counter()
                if len(decoded.uuids) > self.settings.max_nodes:   # a node list that is not the last member
                    raise TooLarge(f"the document has {len(decoded.uuids)} nodes; this service accepts at most "
                                   f"{self.settings.max_nodes} (LUMENLINK_MAX_NODES)", limit=self.settings.max_nodes)
                try:
                    new = Tree.build(*decoded.columns(), doc.length_unit, like=state.tree)
                except TreeError as exc:
                    raise Invalid(str(exc), problems=exc.problems[:100]) from exc
                missing = sorted(self.scenes.missing_geometries([g for g in set(new.geometries) if g is not None]))
                if missing and not dry_run:
                    raise Invalid(f"{len(missing)} geometry id(s) are not uploaded yet (PUT /geometries/{{id}} "
                                  f"first)", missing=missing)
            identity = _identity_of(doc, new)  # 422 naming a key that is no node of this push
            if dry_run:
                return self._dry_run_locked(state, doc, new, missing, t0, t_decode)
            answer = self._push_locked(state, doc, new, identity, t0, t_decode)
            # the tree is now exactly what these bytes describe, row for row
            state.node_bytes = node_bytes if node_bytes is not None else remember(body, state.tree.names)
            return answer

    @staticmethod
    def _diff(state: SceneState, doc: DocumentPush, new: Tree) -> TreeDiff:
        """The push's diff against the current tree; 409 if it changes the tree from a stale ``base_revision``."""
        diff = diff_trees(state.tree, new)
        if state.length_unit is None and len(new) == 0 and doc.length_unit != state.tree.length_unit:
            diff.length_unit_changed = False
        if doc.base_revision is not None and doc.base_revision != state.revision and not diff.is_empty():
            raise Conflict(f"base_revision {doc.base_revision} is stale: the scene is at revision {state.revision}",
                           current_revision=state.revision)
        return diff

    def _dry_run_locked(self, state: SceneState, doc: DocumentPush, new: Tree, missing: list[str], t0: float,
                        t_decode: float) -> dict[str, Any]:
        """What `_push_locked` would answer, computed without changing anything."""
        t_validate = time.perf_counter()
        diff = self._diff(state, doc, new)
        t_diff = time.perf_counter()
        added, removed = set(diff.added), set(diff.removed)
        orphaned = state.orphans(only_nodes=removed) if removed else []
        restored = state.orphans(only_nodes=added) if added else []
        # the geometries `apply_to_scene` would add to the tracer scene, and those it would find there
        to_build: set[str] = set()
        reused: set[str] = set()
        wanted = [new.geometries[new.index[u]] for u in list(diff.added) + diff.geometry_changed]
        wanted += [body["geometry"] for body in state.objects.values() if body.get("attached_to") in added]
        for g in wanted:
            if g is not None:
                (reused if g in state.geometries else to_build).add(g)
        instances = sum(1 for g in new.geometries if g is not None) + sum(
            1 for body in state.objects.values()
            if body.get("attached_to") is None or body["attached_to"] in new.index)
        seconds = {"decode": t_decode - t0, "validate": t_validate - t_decode, "diff": t_diff - t_validate,
                   "blas": 0.0, "tlas": 0.0, "commit": 0.0, "store": 0.0}
        seconds["total"] = time.perf_counter() - t0
        out = _answer(state, doc, diff, {}, seconds, orphaned, restored, blas_reused=len(reused))
        out["restored_nodes"] = [u for u in diff.added if u in state.removed]
        out.update(instances=instances, dry_run=True, blas_to_build=sorted(to_build), missing_geometries=missing)
        return out

    def _push_locked(self, state: SceneState, doc: DocumentPush, new: Tree, identity: dict[str, IdentityIn], t0: float,
                     t_decode: float) -> dict[str, Any]:
        """Apply and store a validated push; every check comes before the first change to the scene or database."""
        t_validate = time.perf_counter()
        diff = self._diff(state, doc, new)
        t_diff = time.perf_counter()
        changes = _identity_changes(state.identity, identity)
        seconds = {"decode": t_decode - t0, "validate": t_validate - t_decode, "diff": t_diff - t_validate}
        if diff.is_empty():
            return self._push_unchanged_locked(state, doc, new, identity, diff, changes, seconds, t0)

        old_tree = state.tree
        removed = set(diff.removed)
        added = set(diff.added)
        restored_nodes = [u for u in diff.added if u in state.removed]
        memory = self._removed_changes(state, old_tree, diff)
        apply_stats, commit, applied, t_commit = _apply_and_commit(self.scenes, state, new, diff, removed, added)
        orphaned = state.orphans(only_nodes=removed) if removed else []
        restored = state.orphans(only_nodes=added) if added else []
        seconds.update(applied)
        for rec in memory[0].values():
            rec["assignments"] = [{"kind": o["kind"], "id": o["id"]} for o in orphaned if o["node"] == rec["uuid"]]
        try:
            self._store(state, doc, old_tree, new, diff, seconds, changes, memory)
        except Exception:
            self.scenes.forget(state.id)
            raise
        t_store = time.perf_counter()
        seconds["store"] = t_store - t_commit
        seconds["total"] = t_store - t0
        state.revision += 1
        state.length_unit = doc.length_unit
        state.last_commit = commit
        state.identity = identity
        for u in memory[1]:
            state.removed.pop(u, None)
        state.removed.update(memory[0])
        state.live = None
        self.scenes.live.notify(state.id, state.revision)
        out = _answer(state, doc, diff, commit, seconds, orphaned, restored,
                      blas_reused=len(apply_stats.reused_geometries))
        out["restored_nodes"] = restored_nodes
        return out

    def _push_unchanged_locked(self, state: SceneState, doc: DocumentPush, new: Tree, identity: dict[str, IdentityIn],
                               diff: TreeDiff, changes: IdentityChanges | None, seconds: dict[str, float],
                               t0: float) -> dict[str, Any]:
        """A push that leaves the tree as it is: no new revision, but its row order and identity records are
        taken (and stored when they changed), so the next push compares against exactly this body."""
        reordered = new.uuids != state.tree.uuids
        old_index = state.tree.index
        state.tree = new  # the same tree; its rows now follow this body's order
        t_store = time.perf_counter()
        if changes is not None or reordered:  # identity records or the order changed: stored, no new revision
            try:
                if reordered:  # the [k] ranks of same-named siblings follow the order: a restart must see it
                    self.store.store_order(state.id, state.version, new.uuids, old_index, changes)
                else:
                    self.store.store_identity(state.id, state.version, changes)  # type: ignore[arg-type]
            except Raced as exc:
                self.scenes.forget(state.id)
                now = self.store.version(state.id)
                current = now[0] if now is not None else None
                raise Conflict(f"the scene changed under this push through another service process (now at "
                               f"revision {current})", current_revision=current) from exc
            except Exception:
                self.scenes.forget(state.id)
                raise
            state.identity = identity
            state.assign_revision += 1
            if reordered:
                state.live = None
        seconds.update(blas=0.0, tlas=0.0, commit=0.0, store=time.perf_counter() - t_store)
        seconds["total"] = time.perf_counter() - t0
        return _answer(state, doc, diff, {}, seconds, [], [], blas_reused=0)

    def _removed_changes(self, state: SceneState, old: Tree, diff: TreeDiff) -> RemovedChanges:
        """What this push does to the scene's memory of removed nodes: a record for each node it removes (what
        ``GET …/nodes`` said of it, and when), and the uuids to forget: those that come back, and those
        remembered longer than ``removed_keep_revisions`` revisions or ``removed_keep_days`` days."""
        revision = state.revision + 1
        now = datetime.datetime.now(datetime.UTC)
        keep_r, keep_s = self.settings.removed_keep_revisions, self.settings.removed_keep_days * 86400.0
        drop = [u for u in diff.added if u in state.removed]
        for u, rec in state.removed.items():
            age = (now - datetime.datetime.fromisoformat(rec["removed_at"])).total_seconds()
            if revision - int(rec["removed_revision"]) >= keep_r or age > keep_s:
                drop.append(u)
        write: dict[str, dict] = {}
        if diff.removed and keep_r > 0 and keep_s > 0:
            paths = old.paths()
            world_doc = old.world_doc
            if world_doc is None:
                world_doc = old.world.copy()
                world_doc[:, :3, 3] /= old.scale
            for u in diff.removed:
                i = old.index[u]
                ident = state.identity.get(u)
                write[u] = {"uuid": u, "parent": old.parents[i], "name": old.names[i], "path": paths[i],
                            "transform": old.local[i].ravel().tolist(), "world": world_doc[i].ravel().tolist(),
                            "geometry": old.geometries[i], "color": color_of(old.colors[i]),
                            "product": ident.product if ident is not None else None,
                            "signature": ident.signature.model_dump(exclude_none=True)
                            if ident is not None and ident.signature is not None else None,
                            "length_unit": old.length_unit, "removed_revision": revision,
                            "removed_at": now.isoformat(), "assignments": []}
        return write, sorted(set(drop))

    def _store(self, state: SceneState, doc: DocumentPush, old: Tree, new: Tree, diff: TreeDiff,
               seconds: dict[str, float], identity_changes: IdentityChanges | None = None,
               removed_changes: RemovedChanges | None = None) -> None:
        summary = diff.summary()
        summary = {k: (len(v) if isinstance(v, list) else v) for k, v in summary.items()}
        summary["seconds"] = {k: round(v, 6) for k, v in seconds.items()}
        self.store.store_push(state.id, state.revision, doc.length_unit,
                              doc.source.model_dump() if doc.source else None, old, new, diff, summary,
                              identity_changes, removed_changes)


def _apply_and_commit(scenes: Scenes, state: SceneState, new: Tree, diff: TreeDiff, removed: set[str],
                      added: set[str]) -> tuple[ApplyStats, dict[str, Any], dict[str, float], float]:
    """Apply the diff to the tracer scene, its objects and parts, and commit it: (what `apply_to_scene` did,
    the commit's report, the seconds of blas, tlas and commit, when the commit ended). If any step fails the
    scene is dropped, to be reloaded from the database: memory never runs ahead of what was stored."""
    try:
        t_apply = time.perf_counter()
        load_seconds = [0.0]

        def ensure(gid: str) -> bool:
            tl = time.perf_counter()
            try:
                return scenes.ensure_geometry(state, gid)
            finally:
                load_seconds[0] += time.perf_counter() - tl

        apply_stats = apply_to_scene(state.tracer, state.instances, new, diff, ensure)
        state.tree = new
        moved = set(diff.moved)
        for oid, body in state.objects.items():
            node = body.get("attached_to")
            if node is not None and (node in moved or node in removed or node in added):
                scenes.place_object(state, oid, body)
        if state.elements:
            if diff.length_unit_changed:   # the parts' millimetres per object unit changed: put them on anew
                state.element_instances.clear()
            element_sync(state, scenes.elements)
        t_applied = time.perf_counter()
        commit = scenes.commit(state)
        t_commit = time.perf_counter()
    except Exception:
        log.exception("applying a push to scene %s failed; reloading it from the database", state.id)
        scenes.forget(state.id)
        raise
    seconds = {"blas": commit["blas_seconds"] + load_seconds[0],
               "tlas": commit["tlas_seconds"] + (t_applied - t_apply - load_seconds[0]),
               "commit": t_commit - t_applied}
    return apply_stats, commit, seconds, t_commit


def _answer(state: SceneState, doc: DocumentPush, diff: TreeDiff, commit: dict, seconds: dict,
            orphaned: list, restored: list, blas_reused: int) -> dict[str, Any]:
    out: dict[str, Any] = {"scene": state.id, "revision": state.revision, "base_revision": doc.base_revision}
    out.update(diff.summary())
    out.update(blas_built=commit.get("blas_built", 0), blas_reused=blas_reused,
               blas_loaded=commit.get("blas_loaded", 0),
               instances=len(state.instances) + len(state.object_instances),
               seconds=seconds, orphaned=orphaned, restored=restored, restored_nodes=[],
               reconciliation=doc.reconciliation.model_dump() if doc.reconciliation is not None else None,
               dry_run=False)
    return out


def _identity_of(doc: DocumentPush, new: Tree) -> dict[str, IdentityIn]:
    """The push's identity records (uuid -> record); 422 if a key is not the uuid of a node of the pushed tree `new`."""
    if not doc.identity:
        return {}
    index = new.index
    unknown = [u for u in doc.identity if u not in index]
    if unknown:
        more = f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else ""
        raise Invalid(f"identity: {unknown[0]} is not the uuid of a node in this push{more}", unknown=unknown[:100],
                      errors=[{"loc": ["identity", u], "msg": "not the uuid of a node in this push",
                               "type": "unknown_node"} for u in unknown[:100]])
    return doc.identity


def _identity_changes(old: dict[str, IdentityIn], new: dict[str, IdentityIn]) -> IdentityChanges | None:
    """What to write so that the stored records `old` become `new`: (records to insert, uuids whose rows
    to delete first, whether to delete every row of the scene instead), or None when they are equal.
    One pass over the records in memory (model equality: field values only); only changed records reach
    the database."""
    if not new:
        return ({}, [], True) if old else None
    write = {u: r for u, r in new.items() if old.get(u) != r}
    drop = [u for u in old if u not in new] + [u for u in write if u in old]
    if not write and not drop:
        return None
    return write, drop, False
