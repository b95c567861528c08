"""Bottom level: binned-SAH BVHs over triangles, flattened for traversal, built many at a time.

Layout (pbrt's ``LinearBVHNode`` as structure of arrays, one row per node, depth-first order):

``node_box`` (k, 6) float64
    ``xmin, ymin, zmin, xmax, ymax, zmax`` of the node.
``node_a`` (k,) int32
    interior: index of the second child (the first child is the next row);
    leaf: first position of its primitives in the leaf order (local to the geometry).
``node_n`` (k,) int32
    leaf: number of primitives (> 0); interior: ``-(axis + 1)``, the split axis, so traversal can
    visit the near child first.

For traversal, :func:`collapse` and :func:`tracer.accel.rows4.pack_rows` turn each tree into *child-box rows*: one
64-byte float32 row per interior node holding both children's boxes and references (leaves are
encoded in the reference), so a ray tests both children from one cache line and never fetches a
child it misses. The boxes are exact in float32 because the vertices are float32 (the geometry id
hashes them so); `pack_rows` still rounds outward. Traversal reads `tracer.accel.rows4.pack_wide`'s 4-wide
rows made from them: four boxes quantised to 8 bits in one 64-byte row. The top level is built by
the same code and laid out in 8-wide float32 rows instead (:mod:`tracer.accel.tlas`, :mod:`tracer.accel.rows8`).

Indices are local to one geometry; the scene adds per-geometry offsets at traversal time, so the
packed store grows by appending and never rewrites what is there.

The same builder (:func:`build_bvh_range`) serves the top level over instance boxes.
:func:`build_meshes` builds a whole batch of geometries in one compiled, parallel call (a CAD
document has tens of thousands of small parts; a Python loop per part would dominate).
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit, prange

#: Bumped whenever the build or the layout changes: cache files of another version are rebuilt.
BUILDER_VERSION = "lumenlink-blas-3"
N_BINS = 16
#: Below this depth SAH decides; beyond it, splits halve the range so depth stays bounded
#: (traversal uses fixed stacks of :data:`STACK_SIZE`).
MAX_SAH_DEPTH = 64
STACK_SIZE = 128
TRAVERSAL_COST = 1.0
#: nodes with at least this many primitives try SAH splits on all three axes
ALL_AXES_MIN = 1024


@njit(cache=True, error_model="numpy")
def box_area(x0, y0, z0, x1, y1, z1):
    ex = x1 - x0
    ey = y1 - y0
    ez = z1 - z0
    if ex < 0.0:
        return 0.0
    return 2.0 * (ex * ey + ey * ez + ez * ex)


@njit(cache=True, error_model="numpy")
def build_bvh_range(bmin, bmax, order, p0, n, node_box, node_a, node_n, k0, max_leaf, isect_cost):
    """Build one BVH over the primitives ``order[p0:p0+n]`` (indices into ``bmin``/``bmax``).

    Parameters
    ----------
    bmin, bmax : (P, 3) float64
        Primitive bounds; the centroid is the box centre.
    order : (P,) int64 or int32
        Permuted in place within ``[p0, p0+n)`` into leaf order.
    node_box, node_a, node_n
        Output rows ``k0 .. k0 + count - 1`` (capacity ``2n - 1`` is always enough).
    max_leaf : int
        Largest leaf SAH may choose.
    isect_cost : float
        Cost of one primitive test relative to a node visit (SAH).

    Returns
    -------
    count : int
        Number of nodes written (0 when ``n == 0``).
    """
    if n == 0:
        return 0
    # pending second children: (start, end, parent, depth)
    ts = np.empty((n + 1, 4), np.int64)
    sp = 0
    start = 0
    end = n
    parent = -1
    depth = 0
    nxt = 0
    bin_box = np.empty((N_BINS, 6))
    bin_cnt = np.empty(N_BINS, np.int64)
    right_area = np.empty(N_BINS)
    right_cnt = np.empty(N_BINS, np.int64)
    while True:
        k = nxt
        nxt += 1
        if parent >= 0:
            node_a[k0 + parent] = k
        x0 = y0 = z0 = np.inf
        x1 = y1 = z1 = -np.inf
        cx0 = cy0 = cz0 = np.inf
        cx1 = cy1 = cz1 = -np.inf
        for q in range(p0 + start, p0 + end):
            p = order[q]
            x0 = min(x0, bmin[p, 0])
            y0 = min(y0, bmin[p, 1])
            z0 = min(z0, bmin[p, 2])
            x1 = max(x1, bmax[p, 0])
            y1 = max(y1, bmax[p, 1])
            z1 = max(z1, bmax[p, 2])
            cx = 0.5 * (bmin[p, 0] + bmax[p, 0])
            cy = 0.5 * (bmin[p, 1] + bmax[p, 1])
            cz = 0.5 * (bmin[p, 2] + bmax[p, 2])
            cx0 = min(cx0, cx)
            cy0 = min(cy0, cy)
            cz0 = min(cz0, cz)
            cx1 = max(cx1, cx)
            cy1 = max(cy1, cy)
            cz1 = max(cz1, cz)
        node_box[k0 + k, 0] = x0
        node_box[k0 + k, 1] = y0
        node_box[k0 + k, 2] = z0
        node_box[k0 + k, 3] = x1
        node_box[k0 + k, 4] = y1
        node_box[k0 + k, 5] = z1
        cnt = end - start
        leaf = cnt <= 1
        mid = start
        axis = 0
        if not leaf:
            ex = cx1 - cx0
            ey = cy1 - cy0
            ez = cz1 - cz0
            if ex >= ey and ex >= ez:
                axis = 0
                lo = cx0
                ext = ex
            elif ey >= ez:
                axis = 1
                lo = cy0
                ext = ey
            else:
                axis = 2
                lo = cz0
                ext = ez
            if ext <= 0.0 or depth >= MAX_SAH_DEPTH:
                # all centroids coincide (or pathological depth): halve the range
                if cnt <= max_leaf and depth < MAX_SAH_DEPTH:
                    leaf = True
                else:
                    mid = start + cnt // 2
            else:
                # binned SAH; every axis with extent for large nodes (tree quality where it matters),
                # the widest only for small ones; as many bins as primitives for small nodes, so the
                # per-node cost stays proportional to them
                nb = min(N_BINS, cnt)
                best = np.inf
                best_b = -1
                best_axis = axis
                best_lo = lo
                best_scale = 0.0
                for ax in range(3):
                    if cnt < ALL_AXES_MIN and ax != axis:
                        continue
                    a_lo = cx0 if ax == 0 else (cy0 if ax == 1 else cz0)
                    a_ext = (cx1 if ax == 0 else (cy1 if ax == 1 else cz1)) - a_lo
                    if not a_ext > 0.0:
                        continue
                    scale = nb / a_ext
                    for b in range(nb):
                        bin_cnt[b] = 0
                        bin_box[b, 0] = np.inf
                        bin_box[b, 1] = np.inf
                        bin_box[b, 2] = np.inf
                        bin_box[b, 3] = -np.inf
                        bin_box[b, 4] = -np.inf
                        bin_box[b, 5] = -np.inf
                    for q in range(p0 + start, p0 + end):
                        p = order[q]
                        c = 0.5 * (bmin[p, ax] + bmax[p, ax])
                        b = int((c - a_lo) * scale)
                        if b >= nb:
                            b = nb - 1
                        if b < 0:
                            b = 0
                        bin_cnt[b] += 1
                        for a in range(3):
                            if bmin[p, a] < bin_box[b, a]:
                                bin_box[b, a] = bmin[p, a]
                            if bmax[p, a] > bin_box[b, 3 + a]:
                                bin_box[b, 3 + a] = bmax[p, a]
                    # sweep from the right: area and count of bins b..nb-1
                    rx0 = ry0 = rz0 = np.inf
                    rx1 = ry1 = rz1 = -np.inf
                    rc = 0
                    for b in range(nb - 1, 0, -1):
                        rx0 = min(rx0, bin_box[b, 0])
                        ry0 = min(ry0, bin_box[b, 1])
                        rz0 = min(rz0, bin_box[b, 2])
                        rx1 = max(rx1, bin_box[b, 3])
                        ry1 = max(ry1, bin_box[b, 4])
                        rz1 = max(rz1, bin_box[b, 5])
                        rc += bin_cnt[b]
                        right_area[b] = box_area(rx0, ry0, rz0, rx1, ry1, rz1)
                        right_cnt[b] = rc
                    lx0 = ly0 = lz0 = np.inf
                    lx1 = ly1 = lz1 = -np.inf
                    lc = 0
                    for b in range(nb - 1):
                        lx0 = min(lx0, bin_box[b, 0])
                        ly0 = min(ly0, bin_box[b, 1])
                        lz0 = min(lz0, bin_box[b, 2])
                        lx1 = max(lx1, bin_box[b, 3])
                        ly1 = max(ly1, bin_box[b, 4])
                        lz1 = max(lz1, bin_box[b, 5])
                        lc += bin_cnt[b]
                        if lc == 0 or right_cnt[b + 1] == 0:
                            continue
                        c = lc * box_area(lx0, ly0, lz0, lx1, ly1, lz1) + right_cnt[b + 1] * right_area[b + 1]
                        if c < best:
                            best = c
                            best_b = b
                            best_axis = ax
                            best_lo = a_lo
                            best_scale = scale
                area = box_area(x0, y0, z0, x1, y1, z1)
                if area > 0.0:
                    split_cost = TRAVERSAL_COST + isect_cost * best / area
                else:
                    split_cost = TRAVERSAL_COST + isect_cost * cnt * 0.5
                axis = best_axis
                if best_b < 0:
                    mid = start + cnt // 2
                elif cnt <= max_leaf and split_cost >= isect_cost * cnt:
                    leaf = True
                else:
                    # partition: bins <= best_b first
                    i = p0 + start
                    j = p0 + end - 1
                    while i <= j:
                        p = order[i]
                        c = 0.5 * (bmin[p, axis] + bmax[p, axis])
                        b = int((c - best_lo) * best_scale)
                        if b >= nb:
                            b = nb - 1
                        if b < 0:
                            b = 0
                        if b <= best_b:
                            i += 1
                        else:
                            order[i] = order[j]
                            order[j] = p
                            j -= 1
                    mid = i - p0
                    if mid == start or mid == end:
                        mid = start + cnt // 2
        if leaf:
            node_a[k0 + k] = start
            node_n[k0 + k] = cnt
            if sp == 0:
                break
            sp -= 1
            start = ts[sp, 0]
            end = ts[sp, 1]
            parent = ts[sp, 2]
            depth = ts[sp, 3]
        else:
            node_n[k0 + k] = -(axis + 1)
            ts[sp, 0] = mid
            ts[sp, 1] = end
            ts[sp, 2] = k
            ts[sp, 3] = depth + 1
            sp += 1
            end = mid
            parent = -1
            depth += 1
    return nxt


@njit(cache=True, error_model="numpy")
def triangle_bounds(tri_v, bmin, bmax):
    """Bounds of each triangle row ``(v0, v1, v2)`` of ``tri_v`` (m, 9)."""
    for j in range(tri_v.shape[0]):
        for a in range(3):
            lo = min(tri_v[j, a], tri_v[j, 3 + a], tri_v[j, 6 + a])
            hi = max(tri_v[j, a], tri_v[j, 3 + a], tri_v[j, 6 + a])
            bmin[j, a] = lo
            bmax[j, a] = hi


@njit(cache=True, error_model="numpy")
def gather_triangles(verts, tris, tri_off, vert_off, tri_v):
    """``tri_v[j] = verts[vert_off[g] + tris[j]]`` for each geometry g of the batch (float64)."""
    for g in range(tri_off.shape[0] - 1):
        vo = vert_off[g]
        for j in range(tri_off[g], tri_off[g + 1]):
            for c in range(3):
                vi = vo + tris[j, c]
                tri_v[j, 3 * c] = verts[vi, 0]
                tri_v[j, 3 * c + 1] = verts[vi, 1]
                tri_v[j, 3 * c + 2] = verts[vi, 2]


@njit(parallel=True, cache=True, error_model="numpy")
def build_meshes(tri_v, tri_off, max_leaf, isect_cost):
    """Build the BLAS of every geometry of a batch.

    Parameters
    ----------
    tri_v : (M, 9) float64
        Triangles of all geometries, concatenated in geometry order.
    tri_off : (G + 1,) int64
        Geometry g owns rows ``tri_off[g]:tri_off[g+1]``.

    Returns
    -------
    order : (M,) int64
        Per geometry, the local triangle index at each leaf position.
    node_box, node_a, node_n
        Nodes; geometry g owns rows ``2 tri_off[g] : 2 tri_off[g] + node_cnt[g]`` (rest unused).
    node_cnt : (G,) int64
    """
    m = tri_v.shape[0]
    g_n = tri_off.shape[0] - 1
    bmin = np.empty((m, 3))
    bmax = np.empty((m, 3))
    triangle_bounds(tri_v, bmin, bmax)
    order = np.empty(m, np.int64)
    node_box = np.empty((2 * m, 6))
    node_a = np.zeros(2 * m, np.int32)
    node_n = np.zeros(2 * m, np.int32)
    node_cnt = np.zeros(g_n, np.int64)
    for g in prange(g_n):
        t0 = tri_off[g]
        n = tri_off[g + 1] - t0
        for q in range(n):
            order[t0 + q] = t0 + q
        node_cnt[g] = build_bvh_range(bmin, bmax, order, t0, n, node_box, node_a, node_n, 2 * t0,
                                      max_leaf, isect_cost)
        for q in range(n):
            order[t0 + q] -= t0
    return order, node_box, node_a, node_n, node_cnt


@njit(cache=True, error_model="numpy")
def check_topology(node_a, node_n, m):
    """True when ``(node_a, node_n)`` is a valid depth-first tree over ``m`` primitives.

    Used on BLAS topologies read from a cache file, which are never trusted: every index in range,
    first child next, second child after it, each node reached exactly once, each leaf position
    covered exactly once, depth within the traversal stack.
    """
    k = node_a.shape[0]
    if m == 0:
        return k == 0
    if k < 1 or k > 2 * m - 1 or node_n.shape[0] != k:
        return False
    seen = np.zeros(k, np.uint8)
    covered = np.zeros(m, np.uint8)
    stack = np.empty((k + 1, 2), np.int64)
    sp = 1
    stack[0, 0] = 0
    stack[0, 1] = 0
    while sp > 0:
        sp -= 1
        i = stack[sp, 0]
        d = stack[sp, 1]
        if d >= STACK_SIZE - 2 or seen[i]:
            return False
        seen[i] = 1
        c = node_n[i]
        a = node_a[i]
        if c > 0:
            if a < 0 or a + c > m or c >= 16:
                return False
            for q in range(a, a + c):
                if covered[q]:
                    return False
                covered[q] = 1
        else:
            if c < -3 or i + 1 >= k or a <= i + 1 or a >= k or sp + 2 > k + 1:
                return False
            stack[sp, 0] = i + 1
            stack[sp, 1] = d + 1
            stack[sp + 1, 0] = a
            stack[sp + 1, 1] = d + 1
            sp += 2
    for i in range(k):
        if not seen[i]:
            return False
    for q in range(m):
        if not covered[q]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def refit(node_a, node_n, tri_v_leaf, node_box):
    """Recompute every node box bottom-up from the triangles (children follow their parent)."""
    for i in range(node_a.shape[0] - 1, -1, -1):
        c = node_n[i]
        if c > 0:
            a = node_a[i]
            for ax in range(3):
                lo = np.inf
                hi = -np.inf
                for j in range(a, a + c):
                    lo = min(lo, tri_v_leaf[j, ax], tri_v_leaf[j, 3 + ax], tri_v_leaf[j, 6 + ax])
                    hi = max(hi, tri_v_leaf[j, ax], tri_v_leaf[j, 3 + ax], tri_v_leaf[j, 6 + ax])
                node_box[i, ax] = lo
                node_box[i, 3 + ax] = hi
        else:
            l_ = i + 1
            r = node_a[i]
            for ax in range(3):
                node_box[i, ax] = min(node_box[l_, ax], node_box[r, ax])
                node_box[i, 3 + ax] = max(node_box[l_, 3 + ax], node_box[r, 3 + ax])



@njit(cache=True)
def collapse(node_box, node_a, node_n, node_off, node_cnt):
    """Turn binary trees (one per geometry) into child-box rows: one row per interior node.

    A row holds both children's boxes, so traversal tests both from one 64-byte row and never
    fetches a child it misses (pbrt's layout fetches a node to test its own box). A single-leaf tree
    gets one row whose second child is an empty box.

    Returns
    -------
    boxes : (R, 12) float64
        left box (xmin, ymin, zmin, xmax, ymax, zmax), right box.
    refs : (R, 2) int64
        Child references: ``>= 0`` a row (local to the geometry), ``< 0`` a leaf
        ``-(first * 16 + count) - 1`` (count < 16).
    row_cnt : (G,) int64
        Rows per geometry, in geometry order.
    """
    g_n = node_cnt.shape[0]
    row_cnt = np.zeros(g_n, np.int64)
    for g in range(g_n):
        n = node_cnt[g]
        if n == 1:
            row_cnt[g] = 1
        else:
            c = 0
            for i in range(node_off[g], node_off[g] + n):
                if node_n[i] <= 0:
                    c += 1
            row_cnt[g] = c
    total = 0
    for g in range(g_n):
        total += row_cnt[g]
    boxes = np.empty((total, 12))
    refs = np.empty((total, 2), np.int64)
    row_of = np.zeros(node_a.shape[0], np.int64)
    r = 0
    for g in range(g_n):
        k0 = node_off[g]
        n = node_cnt[g]
        if n == 0:
            continue
        if n == 1:
            for a in range(6):
                boxes[r, a] = node_box[k0, a]
            for a in range(3):
                boxes[r, 6 + a] = np.inf
                boxes[r, 9 + a] = -np.inf
            refs[r, 0] = -(node_a[k0] * 16 + node_n[k0]) - 1
            refs[r, 1] = -1
            r += 1
            continue
        q = 0
        for i in range(k0, k0 + n):
            if node_n[i] <= 0:
                row_of[i] = q
                q += 1
        for i in range(k0, k0 + n):
            if node_n[i] > 0:
                continue
            left = i + 1
            right = k0 + node_a[i]
            for a in range(6):
                boxes[r, a] = node_box[left, a]
                boxes[r, 6 + a] = node_box[right, a]
            refs[r, 0] = row_of[left] if node_n[left] <= 0 else -(node_a[left] * 16 + node_n[left]) - 1
            refs[r, 1] = row_of[right] if node_n[right] <= 0 else -(node_a[right] * 16 + node_n[right]) - 1
            r += 1
    return boxes, refs, row_cnt
