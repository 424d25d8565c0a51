"""Linear-time numba kernels behind :mod:`jaxcds.mesh` (validation and the topology report).

Why a module of its own: validation runs before every build, so at 10M vertices it must cost a
few linear passes, not ``np.unique`` on 60M keys (a sort) and scipy's graph components on 60M
corners. Everything here is O(F + V) except where a comment says otherwise:

* darts are grouped by undirected edge with one counting sort by the smaller end and, inside
  each bucket (a vertex's few edges, in cache), a sort by ``(larger end, dart)``, which yields
  exactly the order of ``np.unique(lo * V + hi)`` (a vertex of degree k costs k log k);
* fans of faces around a vertex, and connected components, are union-find with the smallest id as
  the root, so labels come out in the order a graph search from id 0 upward would give them;
* the fast path of validation (:func:`manifold_twins`) checks a mesh without building the edge
  table: on a mesh without defects the darts pair off directly into twins, which the builders
  reuse; on any defect the full checks above name it.

Dart ``d = 3f + k`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 3]``; corner ``3f + k`` is
the corner of face ``f`` at ``faces[f, k]``.
"""

from __future__ import annotations

import numba
import numpy as np


_SMALL_BUCKET = 24  # insertion sort up to this bucket size, np.sort above (a high-degree vertex)


@numba.njit(cache=True)
def _lo_bucket_sizes(fl, num_vertices):
    """``start[v + 1]``: number of darts whose smaller endpoint is ``v``, prefix-summed (int32:
    fewer than 2^31 darts, checked by the callers)."""
    start = np.zeros(num_vertices + 1, dtype=np.int32)
    for f in range(fl.size // 3):
        a, b, c = fl[3 * f], fl[3 * f + 1], fl[3 * f + 2]
        start[min(a, b) + 1] += 1
        start[min(b, c) + 1] += 1
        start[min(c, a) + 1] += 1
    for v in range(num_vertices):
        start[v + 1] += start[v]
    return start


@numba.njit(cache=True)
def _scatter_by_lo(fl, start):
    """One counting sort of the darts by their smaller endpoint ``lo`` (``start``: the prefix
    sums of :func:`_lo_bucket_sizes`; on return ``start[v]`` is the end of bucket ``v``). Each
    dart is the key ``hi << 32 | dart << 1 | backward`` (``backward``: it runs high -> low), so
    sorting a bucket's keys orders its darts by ``(hi, dart)`` and whoever pairs them needs no
    second read of the faces."""
    nc = fl.size
    keys = np.empty(nc, dtype=np.int64)
    for d in range(nc):
        a = fl[d]
        b = fl[d + 1] if d % 3 != 2 else fl[d - 2]
        if a < b:
            keys[start[a]] = (np.int64(b) << 32) | (np.int64(d) << 1)
            start[a] += 1
        else:
            keys[start[b]] = (np.int64(a) << 32) | (np.int64(d) << 1) | 1
            start[b] += 1
    return keys


@numba.njit(cache=True)
def _sort_bucket(keys, s, t):
    """Sort ``keys[s:t]`` in place: insertion sort for the few edges of a typical vertex (in
    cache), ``np.sort`` for a high-degree one (so a hub of degree k costs k log k, not k^2)."""
    if t - s > _SMALL_BUCKET:
        keys[s:t] = np.sort(keys[s:t])
        return
    for i in range(s + 1, t):
        k = keys[i]
        j = i - 1
        while j >= s and keys[j] > k:
            keys[j + 1] = keys[j]
            j -= 1
        keys[j + 1] = k


@numba.njit(cache=True)
def edge_groups(faces, num_vertices):
    """Darts grouped by undirected edge, edges in lexicographic ``(lo, hi)`` order.

    Returns ``(order, starts, dart_edge, forward, edges)``: ``order[starts[e]:starts[e+1]]`` are
    the darts on edge ``e`` in increasing id; ``dart_edge[d]`` is ``e``; ``forward[e]`` counts
    the darts of ``e`` that run low -> high; ``edges[e]`` is ``(lo, hi)``. Needs fewer than 2^31
    darts. One counting sort by ``lo`` (:func:`_scatter_by_lo`), each bucket sorted by
    ``(hi, dart)`` in cache: the order of ``np.unique(lo * V + hi)``, darts increasing.
    """
    nd = faces.shape[0] * 3
    fl = faces.reshape(-1)
    start = _lo_bucket_sizes(fl, num_vertices)
    keys = _scatter_by_lo(fl, start)
    order = np.empty(nd, dtype=np.int64)
    dart_edge = np.empty(nd, dtype=np.int64)
    starts = np.empty(nd + 1, dtype=np.int64)
    ends = np.empty(nd, dtype=np.int32)
    his = np.empty(nd, dtype=np.int32)
    fwd = np.zeros(nd, dtype=np.int32)
    ne = 0
    s = 0
    for v in range(num_vertices):
        t = start[v]
        _sort_bucket(keys, s, t)
        phi = -1
        for i in range(s, t):
            k = keys[i]
            hi = k >> 32
            d = (k & 0xFFFFFFFF) >> 1
            if hi != phi:
                starts[ne] = i
                ends[ne] = v
                his[ne] = hi
                ne += 1
                phi = hi
            order[i] = d
            dart_edge[d] = ne - 1
            if k & 1 == 0:
                fwd[ne - 1] += 1
        s = t
    starts[ne] = nd
    edges = np.empty((ne, 2), dtype=np.int64)
    edges[:, 0] = ends[:ne]
    edges[:, 1] = his[:ne]
    return order, starts[: ne + 1].copy(), dart_edge, fwd[:ne].astype(np.int64), edges


@numba.njit(cache=True)
def match_twins(faces, num_vertices):
    """``opp[d]``: the twin of dart ``d`` among the face darts, or -1 (a border side), int32.
    The darts of each undirected edge, in increasing id, are paired two by two (the first with
    the second, the third with the fourth...; an odd last one stays -1): what the half-edge's
    first-unpaired-dart matching gives, without its scan, quadratic in a vertex's degree."""
    nc = faces.shape[0] * 3
    fl = faces.reshape(-1)
    start = _lo_bucket_sizes(fl, num_vertices)
    keys = _scatter_by_lo(fl, start)
    opp = np.empty(nc, dtype=np.int32)
    s = 0
    for v in range(num_vertices):
        t = start[v]
        _sort_bucket(keys, s, t)
        i = s
        while i < t:
            d1 = np.int32((keys[i] & 0xFFFFFFFF) >> 1)
            if i + 1 < t and (keys[i + 1] >> 32) == (keys[i] >> 32):
                d2 = np.int32((keys[i + 1] & 0xFFFFFFFF) >> 1)
                opp[d1] = d2
                opp[d2] = d1
                i += 2
            else:
                opp[d1] = -1
                i += 1
        s = t
    return opp


@numba.njit(cache=True)
def _sorted3(faces, f):
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    if a > b:
        a, b = b, a
    if b > c:
        b, c = c, b
    if a > b:
        a, b = b, a
    return a, b, c


@numba.njit(cache=True)
def duplicate_faces(faces, order, starts, max_group):
    """``partner[f]``: the smallest other face on the same vertex set as ``f``, or -1.

    Two duplicate faces share all their edges, so comparing the faces around each edge finds them
    all. Pairs are compared within an edge's group: O(sum of squared edge counts). Returns
    ``ok = False`` (and gives up) if a group is larger than ``max_group``, so a pathological
    non-manifold edge cannot make this quadratic; the caller then sorts instead.
    """
    nf = faces.shape[0]
    partner = np.full(nf, -1, dtype=np.int64)
    for e in range(starts.size - 1):
        s, t = starts[e], starts[e + 1]
        if t - s < 2:
            continue
        if t - s > max_group:
            return partner, False
        for i in range(s, t):
            fa = order[i] // 3
            a0, a1, a2 = _sorted3(faces, fa)
            for j in range(i + 1, t):
                fb = order[j] // 3
                if fa == fb:
                    continue
                b0, b1, b2 = _sorted3(faces, fb)
                if a0 == b0 and a1 == b1 and a2 == b2:
                    if partner[fa] < 0 or fb < partner[fa]:
                        partner[fa] = fb
                    if partner[fb] < 0 or fa < partner[fb]:
                        partner[fb] = fa
    return partner, True


@numba.njit(cache=True)
def _root(parent, x):
    r = x
    while parent[r] != r:
        r = parent[r]
    while parent[x] != r:  # path compression
        nxt = parent[x]
        parent[x] = r
        x = nxt
    return r


@numba.njit(cache=True)
def _union_min(parent, x, y):
    """Join the sets of x and y; the smaller root stays the root."""
    rx, ry = _root(parent, x), _root(parent, y)
    if rx < ry:
        parent[ry] = rx
    elif ry < rx:
        parent[rx] = ry


@numba.njit(cache=True)
def corner_fans(faces, order, starts):
    """``label[c]``: the smallest corner of the edge-connected fan of faces around corner ``c``'s
    vertex that holds ``c`` (one label per fan; a manifold vertex has one fan)."""
    nc = faces.shape[0] * 3
    parent = np.arange(nc)
    for e in range(starts.size - 1):
        for i in range(starts[e], starts[e + 1] - 1):
            d1, d2 = order[i], order[i + 1]
            # corners at the two ends of each dart: origin 3f+k, target 3f+(k+1)%3
            c1o, c1t = d1, 3 * (d1 // 3) + (d1 % 3 + 1) % 3
            c2o, c2t = d2, 3 * (d2 // 3) + (d2 % 3 + 1) % 3
            v1o = faces[d1 // 3, d1 % 3]
            v2o = faces[d2 // 3, d2 % 3]
            if v1o == v2o:  # same direction (an orientation defect): origins meet
                _union_min(parent, c1o, c2o)
                _union_min(parent, c1t, c2t)
            else:
                _union_min(parent, c1o, c2t)
                _union_min(parent, c1t, c2o)
    for c in range(nc):
        parent[c] = _root(parent, c)
    return parent


@numba.njit(cache=True)
def fans_per_vertex(faces, label, num_vertices):
    fans = np.zeros(num_vertices, dtype=np.int64)
    for c in range(label.size):
        if label[c] == c:
            fans[faces[c // 3, c % 3]] += 1
    return fans


@numba.njit(cache=True)
def face_components(faces, num_vertices):
    """Components of faces joined through shared vertices: ``(count, label)``, labels numbered in
    order of each component's smallest face."""
    parent = np.arange(num_vertices)
    nf = faces.shape[0]
    for f in range(nf):
        _union_min(parent, faces[f, 0], faces[f, 1])
        _union_min(parent, faces[f, 0], faces[f, 2])
    comp = np.full(num_vertices, -1, dtype=np.int64)
    label = np.empty(nf, dtype=np.int64)
    k = 0
    for f in range(nf):
        r = _root(parent, faces[f, 0])
        if comp[r] < 0:
            comp[r] = k
            k += 1
        label[f] = comp[r]
    return k, label


@numba.njit(cache=True)
def cycles(nxt):
    """Cycles of a permutation given by successors: ``(items, offsets)``, each cycle from its
    smallest element in successor order."""
    n = nxt.size
    seen = np.zeros(n, dtype=np.bool_)
    items = np.empty(n, dtype=np.int64)
    offsets = np.empty(n + 1, dtype=np.int64)
    k, pos = 0, 0
    for s in range(n):
        if seen[s]:
            continue
        offsets[k] = pos
        k += 1
        e = s
        while e >= 0 and not seen[e]:  # -1: an open chain ends
            seen[e] = True
            items[pos] = e
            pos += 1
            e = nxt[e]
    offsets[k] = pos
    return items, offsets[: k + 1].copy()


# ------------------------------------------------------------------ fast path: clean meshes
# Status codes of :func:`manifold_twins` (0: no defect). Any other code only says *that* the fast
# path stopped; the caller then runs the full checks, which find and name the defect.
(CLEAN, BAD_INDEX, DEGENERATE, NON_MANIFOLD_EDGE, SAME_DIRECTION, DUPLICATE,
 NON_MANIFOLD_VERTEX) = range(7)


@numba.njit(cache=True)
def manifold_twins(faces, num_vertices, components):
    """One-shot check of a face list for every defect :func:`jaxcds.mesh.find_defects` looks at
    (except coordinates), building the twin of every dart on the way.

    Returns ``(status, opp, vertex_corner, num_edges, num_components)``: ``opp[d]`` is the dart
    on the other side of ``d``'s edge (-1 on a border), ``vertex_corner[v]`` the smallest corner
    of ``v`` (-1 if unreferenced), ``num_components`` the components of faces through shared
    vertices. ``status`` is :data:`CLEAN` or the first kind of defect met, in which case the
    other outputs are meaningless.

    Why it is cheaper than the edge table: one counting sort of the darts by their smaller
    endpoint (not two), each bucket (the edges of one vertex, average size 6) sorted by the
    other endpoint in cache, and on a manifold each edge group has one or two darts, which are
    the twins directly. Then one walk around every vertex (swing ``c -> opp[c.p]``) counts its
    fan; components are a union-find over the edges while pairing. Every check is exact for
    detection: a vertex has one fan iff the swing from its first corner reaches all its
    corners, i.e. iff the fans reached sum to ``3F`` corners; a face and its duplicate share
    their three edges, so either an edge has more than two darts, or the two darts of one edge
    run the same way, or (the copy reversed) the two faces close a fan of two faces around
    each of their vertices -- which only a duplicate pair can do (``(v, a, b)`` followed by
    ``(v, b, a)``) -- or a vertex of theirs has a second fan.
    """
    nf = faces.shape[0]
    nc = 3 * nf
    nv = num_vertices
    fl = faces.reshape(-1)
    opp = np.empty(nc, dtype=np.int32)  # every entry written in pass 3
    vc = np.full(nv, -1, dtype=np.int32)
    # pass 1: indices, degenerate faces, first corner of each vertex
    for f in range(nf):
        a, b, c = fl[3 * f], fl[3 * f + 1], fl[3 * f + 2]
        if a < 0 or b < 0 or c < 0 or a >= nv or b >= nv or c >= nv:
            return BAD_INDEX, opp, vc, 0, 0
        if a == b or b == c or a == c:
            return DEGENERATE, opp, vc, 0, 0
        if vc[a] < 0:
            vc[a] = 3 * f
        if vc[b] < 0:
            vc[b] = 3 * f + 1
        if vc[c] < 0:
            vc[c] = 3 * f + 2
    # pass 2: one counting sort of the darts by smaller endpoint (3F < 2^31: the caller checks)
    start = _lo_bucket_sizes(fl, nv)
    keys = _scatter_by_lo(fl, start)
    # pass 3: per bucket, sort by (hi, dart) and pair the darts of each edge;
    # components of vertices joined by edges (union-find while the bucket is in cache)
    parent = np.arange(nv if components else 0).astype(np.int32)
    ne = 0
    s = 0
    for v in range(nv):
        t = start[v]
        _sort_bucket(keys, s, t)
        rv = _root(parent, v) if components else 0  # kept current: one find per edge, not two
        i = s
        while i < t:
            hi = keys[i] >> 32
            if i + 1 < t and (keys[i + 1] >> 32) == hi:
                if i + 2 < t and (keys[i + 2] >> 32) == hi:
                    return NON_MANIFOLD_EDGE, opp, vc, 0, 0
                if (keys[i] ^ keys[i + 1]) & 1 == 0:  # both darts run the same way
                    return SAME_DIRECTION, opp, vc, 0, 0
                d1 = np.int32((keys[i] & 0xFFFFFFFF) >> 1)
                d2 = np.int32((keys[i + 1] & 0xFFFFFFFF) >> 1)
                opp[d1] = d2
                opp[d2] = d1
                i += 2
            else:
                opp[np.int32((keys[i] & 0xFFFFFFFF) >> 1)] = -1  # a border side
                i += 1
            ne += 1
            if components:
                rh = _root(parent, hi)
                if rh < rv:
                    parent[rv] = rh
                    rv = rh
                elif rv < rh:
                    parent[rh] = rv
        s = t
    # pass 4: one fan per vertex: walk around each vertex in id order (vertex order keeps the
    # walks in cache; a breadth-first order was 5x slower at 10M vertices)
    walked = 0
    for v in range(nv):
        c0 = vc[v]
        if c0 < 0:
            continue
        c = c0
        border = False
        n = 0
        while True:  # ccw swing: c -> twin of c.p (terminates: the swing is injective)
            n += 1
            t = opp[3 * (c // 3) + (c % 3 + 2) % 3]
            if t < 0:
                border = True
                break
            c = t
            if c == c0:
                break
        walked += n
        if n == 2 and not border:  # two faces closing around v are on one vertex set
            return DUPLICATE, opp, vc, ne, 0
        if border:  # an open fan: also walk cw from the first corner
            c = c0
            while True:
                t = opp[c]
                if t < 0:
                    break
                c = 3 * (t // 3) + (t % 3 + 1) % 3
                walked += 1
    if walked != nc:
        return NON_MANIFOLD_VERTEX, opp, vc, ne, 0
    ncomp = 0
    if components:
        for v in range(nv):
            if vc[v] >= 0 and parent[v] == v:
                ncomp += 1
    return CLEAN, opp, vc, ne, ncomp


@numba.njit(cache=True)
def match_triangles(a, b, num_vertices):
    """``(perm, where)``: ``perm[i]`` the row of ``b`` with the vertex set of row ``i`` of ``a``
    (two ``(F, 3)`` arrays of ids below ``num_vertices``, each row's ids distinct), each row of
    ``b`` used once; ``where = -1`` when every row matched, else the first row of ``a`` without
    a partner (``perm`` then incomplete).

    Why not ``argsort`` of packed keys (what it replaces): two sorts of ``F`` int64 keys took
    0.4 s at 2M triangles; this is one counting sort of ``b`` by smallest id and a scan of each
    of ``a``'s rows' bucket (a vertex's few triangles, in cache), and a first pass that stops at
    the first row out of place, so rows already in order cost one read."""
    nf = a.shape[0]
    perm = np.empty(nf, dtype=np.int64)
    same = True
    for i in range(nf):
        a0, a1, a2 = _sorted3(a, i)
        b0, b1, b2 = _sorted3(b, i)
        if a0 != b0 or a1 != b1 or a2 != b2:
            same = False
            break
        perm[i] = i
    if same:
        return perm, -1
    start = np.zeros(num_vertices + 1, dtype=np.int64)
    for j in range(nf):
        b0, b1, b2 = _sorted3(b, j)
        start[b0 + 1] += 1
    for v in range(num_vertices):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    mid = np.empty(nf, dtype=np.int64)  # (mid, hi) packed, and the row, per bucket slot
    row = np.empty(nf, dtype=np.int64)
    for j in range(nf):
        b0, b1, b2 = _sorted3(b, j)
        k = fill[b0]
        mid[k] = (np.int64(b1) << 32) | b2
        row[k] = j
        fill[b0] = k + 1
    for i in range(nf):
        a0, a1, a2 = _sorted3(a, i)
        key = (np.int64(a1) << 32) | a2
        found = -1
        for k in range(start[a0], start[a0 + 1]):
            if mid[k] == key:
                found = k
                break
        if found < 0:
            return perm, i
        perm[i] = row[found]
        mid[found] = -1  # used: a repeated row of ``a`` must find a second copy in ``b``
    return perm, -1


@numba.njit(cache=True)
def all_clockwise(points, faces):
    """Every triangle of ``faces`` turns clockwise in the 2-D ``points`` (twice its signed area
    ``(p1 - p0) x (p2 - p0)`` negative, computed as :func:`jaxcds.polylla_io.twice_signed_areas`
    does); False for no triangles. Stops at the first one that does not: a counter-clockwise
    input (the usual one) costs one row."""
    nf = faces.shape[0]
    if nf == 0:
        return False
    for f in range(nf):
        i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
        x0, y0 = points[i, 0], points[i, 1]
        area = ((points[j, 0] - x0) * (points[k, 1] - y0)
                - (points[j, 1] - y0) * (points[k, 0] - x0))
        if not area < 0:
            return False
    return True
