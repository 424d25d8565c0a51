"""The polygons of canonical-mode Polylla as CSR arrays, on the host: the numba twin of
:func:`jaxcds.algorithms.polylla.cycles_to_csr`.

Why a second route: ``cycles_to_csr`` finds every cycle's head (its smallest directed edge) and
every lane's rank by pointer doubling, ``O(N log L)`` work in int64 keys, which suits a GPU; on
XLA:CPU with two cores it was the slowest phase of a canonical run (0.99 s of 1.78 s at 1M
points, 2.6M frontier darts). Following each cycle once is ``O(N)``: two walks over the frontier
darts (heads first, then the lists in head order), 0.1-0.2 s at 1M. :func:`polylla` takes this
route when the successor map lives on a CPU device; both give the same arrays (tested).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["cycles_csr_host"]


@numba.njit(cache=True)
def _cycles(succ, vo):
    """``(status, offsets, indices, polygon_of_dart)`` for the cycles of ``succ`` over the darts
    with ``succ[d] < E`` (status 0; 1: a frontier dart's successor is not one, or two darts
    share a successor: not a permutation). Each cycle starts at its head, the dart ``d`` with
    the smallest ``(vo[d], vo[succ[d]])``, and cycles come in increasing head id, as
    ``cycles_to_csr`` lists them. ``polygon_of_dart``: -1 off the frontier."""
    E = succ.size
    pod = np.full(E, -1, np.int32)  # first pass: the cycle's first-met dart; then polygon ids
    head = np.zeros(E, np.bool_)
    total = 0
    for s in range(E):
        if succ[s] >= E or pod[s] >= 0:
            continue
        best, h, d = np.int64(np.iinfo(np.int64).max), s, s
        while True:
            n = succ[d]
            if n < 0 or n >= E:  # a successor off the frontier
                return 1, np.zeros(1, np.int64), np.zeros(0, np.int32), pod
            key = (np.int64(vo[d]) << 32) | np.int64(vo[n])
            if key < best:
                best, h = key, d
            pod[d] = s
            total += 1
            if n == s:
                break
            if pod[n] >= 0:  # met an earlier cycle, or itself away from its start: a rho
                return 1, np.zeros(1, np.int64), np.zeros(0, np.int32), pod
            d = n
        head[h] = True
    offsets = np.zeros(E + 1, np.int64)
    indices = np.empty(total, np.int32)
    p = 0
    k = 0
    for h in range(E):
        if not head[h]:
            continue
        d = h
        while True:
            pod[d] = p
            indices[k] = vo[d]
            k += 1
            d = succ[d]
            if d == h:
                break
        p += 1
        offsets[p] = k
    return 0, offsets[: p + 1].copy(), indices, pod


def cycles_csr_host(succ, vertex_of_dart):
    """Canonical Polylla's polygon lists from the successor map (host arrays).

    Args:
      succ: ``(E,)`` the successor of every frontier dart (``>= E`` off the frontier).
      vertex_of_dart: ``(E,)`` input vertex id of every dart's origin.

    Returns ``(offsets, indices, polygon_of_dart, ok)`` as :func:`~jaxcds.algorithms.polylla.
    cycles_to_csr` gives them (offsets int64, indices int32 input vertex ids, each polygon from
    its smallest directed edge, polygons in increasing head-dart id); ``polygon_of_dart`` -1 off
    the frontier; ``ok`` False when ``succ`` is not a permutation of the frontier darts.
    """
    succ, vo = np.asarray(succ), np.asarray(vertex_of_dart)
    if succ.ndim != 1 or vo.shape != succ.shape or succ.dtype.kind not in "iu" or vo.dtype.kind not in "iu":
        # a short vertex_of_dart was read past its end by the kernel (garbage polygons)
        from jaxcds import errors

        raise errors.ArgumentError(f"cycles_csr_host: succ and vertex_of_dart must be 1-D integer arrays "
                                   f"of one length, got {succ.dtype} {succ.shape} and {vo.dtype} {vo.shape}")
    succ = np.ascontiguousarray(succ, np.int32)
    vo = np.ascontiguousarray(vo, np.int32)
    status, offsets, indices, pod = _cycles(succ, vo)
    return offsets, indices, pod, status == 0
