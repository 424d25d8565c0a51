"""Area-weighted vertex normals on any structure, differentiable w.r.t. positions.

Two formulations, same result:

* ``"scatter"`` — the face-list route: one cross product per face (its length is twice the area,
  so summing unnormalised face normals *is* area weighting), accumulated at the three corners
  (:func:`corner_sums`: one scatter-add per corner column). The structure only has to produce
  its faces, in any order (``face_vertices_padded()``, by default ``face_vertices()``).
* ``"gather"`` — the navigation route of the CDS paper's Table 3: every vertex turns around its
  one-ring (``ccw_vertex_edge``) and sums the cross products of consecutive neighbours, no
  scatter at all. Cost: (max degree) rounds of gathers over all vertices.

Scatter-add is the known slow spot of XLA:CPU (jax-ml/jax#39959); ``benchmarks/`` measures both
routes, and ``"scatter"`` (the default) measured faster on every mesh there (RESULTS.md).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxcds import errors
from jaxcds._arrays import native_order, to_device
from jaxcds._args import number_array, refuse_non_real

__all__ = ["vertex_normals", "face_normals", "normalize", "face_list_vertex_normals", "corner_sums",
           "surface_faces_padded", "faces_with_dummy_corner", "within_range"]


def normalize(x, axis: int = -1, eps: float = 0.0):
    """``x / |x|``; a vector whose largest component is at most ``eps`` in magnitude (a zero
    vector) maps to zero with a zero derivative instead of NaN (as optax's ``safe_norm``); a
    vector with a NaN component maps to NaN.

    ``x`` is first divided by its largest component: squared directly, float32 sums of face
    normals overflowed from coordinates near 1e10 (``|x|^2`` past 3e38: every normal came out
    zero) and flushed to zero near 1e-10. Scaled, ``|x|^2`` lies in ``[1, 3]``. The derivative
    is written out, ``(dx - u (u . dx)) / |x|`` (a custom JVP, so forward and reverse mode
    both work): differentiating through the scaling underflowed at small scales.

    ``x``: a JAX array (traced too), a numpy array or nested lists of real numbers.

    Raises:
      ArgumentError: ``x`` is not real numbers (a list raised JAX's TypeError 'absolute
        requires ndarray or scalar arguments', a string its 'Error interpreting argument')."""
    x = number_array(x, "normalize: x", error=errors.ArgumentError, bools=True)
    x = x if isinstance(x, jax.Array) else jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.inexact):
        # integers and bools in the default float dtype, as their promotion with the float
        # constants below gave them, but explicit: strict dtype promotion raised (sweep 52c)
        x = x.astype(jnp.result_type(float))
    return _normalize(x, axis, eps)


@functools.partial(jax.custom_jvp, nondiff_argnums=(1, 2))
def _normalize(x, axis: int = -1, eps: float = 0.0):
    return _unit(x, axis, eps)[0]


def _unit(x, axis, eps):
    """``(x / |x|, |x|, nonzero)``, computed on ``x`` scaled by its largest component."""
    big = _sum_or_max(jnp.abs(x), axis, jnp.maximum)
    # written so that NaN counts as nonzero: a NaN coordinate gives NaN normals (NaN in, NaN
    # out), not a zero normal that looks like a degenerate fan
    nonzero = ~(big <= eps)
    safe_big = jnp.where(nonzero, big, 1.0)
    y = x / safe_big
    root = jnp.sqrt(jnp.where(nonzero, _sum_or_max(y * y, axis, jnp.add), 1.0))
    return jnp.where(nonzero, y / root, 0.0), safe_big * root, nonzero


def _sum_or_max(v, axis, op):
    """``op`` over ``axis`` (keepdims); for three components (normals) written out element by
    element, which fuses into the surrounding elementwise kernel: a reduction is a kernel of its
    own on XLA:CPU (two of them cost 8-9 ns per vertex, 17% of face-list normals)."""
    if v.shape[axis] == 3:
        a, b, c = (jax.lax.index_in_dim(v, k, axis, keepdims=True) for k in range(3))
        return op(op(a, b), c)
    return (jnp.max if op is jnp.maximum else jnp.sum)(v, axis=axis, keepdims=True)


@_normalize.defjvp
def _normalize_jvp(axis, eps, primals, tangents):
    (x,), (dx,) = primals, tangents
    u, norm, nonzero = _unit(x, axis, eps)
    du = dx - u * jnp.sum(u * dx, axis=axis, keepdims=True)
    return u, jnp.where(nonzero, du / norm, 0.0)


def face_normals(positions, faces, valid=None):
    """Unnormalised face normals ``(p1 - p0) x (p2 - p0)``: length = twice the face area.

    ``valid`` (``(F,)`` bool, optional): rows where it is False (padding, the fans that closed
    holes, LR's border slots) come out zero, and so does their derivative. Their corners are
    masked before the cross product, not the products after it: ``where`` passes a masked row
    a zero cotangent, but the cross product's derivative multiplies it by the corners'
    positions, and ``0 * NaN`` is NaN. Masked afterwards, a NaN or inf position at a CDS
    dummy vertex made the gradients of its whole hole's border NaN, and a NaN vertex reached
    vertices across a hole through LR's border rows (sweep 15a), where the face list's
    gradients are finite."""
    p = positions[faces]
    if valid is not None:
        p = jnp.where(valid[:, None, None], p, 0)
    return jnp.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def corner_sums(face_values, faces, num_vertices: int, acc=None):
    """``(num_vertices, k)``: every face's value added at its three corners (to ``acc`` when
    given: the chunked sums of a packed batch add several row blocks into one accumulator).

    One scatter-add per corner column rather than one ``segment_sum`` over the values repeated
    three times: the repeat costs an extra ``(3F, k)`` buffer (168 against 72 bytes of scratch
    per vertex for normals: past glibc's 32 MiB reuse threshold from about 200K vertices, every
    call then pays fresh zeroed pages), and on XLA:CPU (jaxlib 0.10.2) the ``segment_sum`` ran
    2-4x slower when its indices are computed in the same program (any structure's faces) than
    when passed in. Measured in ``benchmarks/bench_cds_normals.py`` / ``bench_lr_normals.py``
    (column ``normals`` against ``dense`` / ``generic``, the ``segment_sum`` routes); the face-list baseline below sums the same way (same speed or
    faster for it too: armadillo 33 -> 27 ns/vertex, 200K and 1M equal)."""
    if acc is None:
        acc = jnp.zeros((num_vertices,) + face_values.shape[1:], face_values.dtype)
    for k in range(3):
        acc = acc.at[faces[:, k]].add(face_values)
    return acc


def within_range(positions):
    """``positions`` times a power of two (exact) when their largest finite magnitude is so large
    or so small that a face's cross product would overflow or underflow in their dtype (float32:
    beyond about 7e16 or under 1e-17; an icosphere at 1e20 gives NaN normals, at 1e-25 zero
    ones), bringing it just under 2^50 in float32 (2^498 in float64); unchanged otherwise. Unit
    normals do not depend on the scale, so ``vertex_normals(s, within_range(p))`` is the normals
    of ``p`` at any scale, and the factor carries no derivative. NaN and inf coordinates pass
    unchanged (NaN out at their one-ring) and do not decide the factor.

    Not applied inside :func:`vertex_normals`: the extra reduction in the same program cost the
    CDS normals 5-20% at 200K vertices (races of 2026-12-01), for inputs that float32 cannot
    hold well anyway; pass such positions through this function, or in float64.

    Integer, float16 and bfloat16 positions come back as float32 (as :func:`vertex_normals`
    takes them), host arrays in the dtype JAX computes in (float64 is float32 unless x64 is
    on); lists and big-endian arrays are read by value.

    Raises:
      MeshError: ``positions`` are not real numbers, or are a masked array."""
    # host values checked before the transfer (strings cannot be placed on a device)
    positions = number_array(positions, "within_range: positions", bools=True)
    if not isinstance(positions, jax.Array):
        # the dtype JAX computes in (float64 is float32 unless x64 is on): its range decides
        positions = to_device(positions)
    if not jnp.issubdtype(positions.dtype, jnp.floating) or jnp.finfo(positions.dtype).bits < 32:
        positions = positions.astype(jnp.float32)
    fi = jnp.finfo(positions.dtype)
    hi, lo = float(np.sqrt(fi.max)) / 256, float(np.sqrt(fi.tiny)) * 256
    # Where to: the largest coordinate just under 2^t, 64 times under `hi` (room for the
    # differences and the sums of cross products over a vertex's faces), so the mesh's small
    # features keep the most room above underflow. Brought into [0.5, 1) instead, a unit-size
    # face in a mesh whose largest coordinate is 1e20 or 1e30 underflowed: 36 of 42 normals
    # zero where the raw positions gave 6 non-finite ones (sweep 15a). float32: t = 50.
    t = int(np.round(np.log2(hi))) - 6
    # the largest *finite* magnitude: a NaN or inf coordinate (NaN normals at its one-ring
    # anyway) neither hides nor drives the rescaling of the others
    finite = jnp.where(jnp.isfinite(positions), jnp.abs(positions), 0)
    m = jax.lax.stop_gradient(jnp.max(finite, initial=0))  # no coordinates: unchanged
    far = (m > hi) | ((m < lo) & (m > 0))
    k = jnp.where(far, t - jnp.frexp(m)[1], 0)  # m * 2^k in [2^(t-1), 2^t)
    # a product by powers of two (1 when near), not ldexp (its derivative in x is not 2^k on
    # jax 0.10) nor a cond (its result is a buffer of its own: CDS normals ran 10-20% slower at
    # 200K); two factors, as 2^k alone overflows the dtype for the smallest inputs (k up to 198)
    one = jnp.ones((), positions.dtype)
    half = k // 2
    s1 = jax.lax.stop_gradient(jnp.ldexp(one, half))
    s2 = jax.lax.stop_gradient(jnp.ldexp(one, k - half))
    return positions * s1 * s2


def face_list_vertex_normals(positions, faces):
    """The plain-JAX baseline on an ``(F, 3)`` face list (the peer in every benchmark):
    ``(V, 3)`` unit area-weighted normals of ``positions`` ``(V, 3)``. Jitted; differentiable.

    Host arrays of either byte order are read by value (a big-endian array, after a native call
    of the same shape, was read by jit's cache as native bytes: wrong normals). Positions are
    summed in their own floating dtype, as plain JAX code would (float16 in, float16 out, with
    float16's range), where :func:`vertex_normals` takes narrow floats as float32.

    Raises:
      MeshError: ``positions`` are not real numbers, or are a masked array, or ``positions`` /
        ``faces`` are not ``(V, 3)`` / ``(F, 3)`` (a flat array gave JAX's untyped ValueError
        about the cross product; ``(V, 2)`` positions a ``(V,)`` answer, ``(F, 4)`` faces
        normals of their first three columns).
      InvalidIndexError: ``faces`` are not integers (a float index would be truncated), or host
        ``faces`` hold an id outside ``[0, V)`` (its faces added nothing: zero normals, or a
        negative id wrapped to another vertex). Ids of ``faces`` already on the device are not
        read back to be checked (as plain JAX, an id past ``V`` adds nothing there).
    """
    # nested lists as arrays (jit would take a list for a pytree of scalars)
    positions = number_array(positions, "face_list_vertex_normals: positions", bools=True)
    host = not isinstance(faces, jax.Array)
    faces = np.asarray(faces) if host else faces
    if not jnp.issubdtype(faces.dtype, jnp.integer):
        raise errors.InvalidIndexError(
            f"face_list_vertex_normals: faces must be integers, got dtype {faces.dtype}")
    for what, a, rows in (("positions", positions, "V"), ("faces", faces, "F")):
        if a.ndim != 2 or a.shape[1] != 3:
            raise errors.MeshError(f"face_list_vertex_normals: {what} must have shape ({rows}, 3), "
                                   f"got {tuple(a.shape)}")
    if host and faces.size:
        from jaxcds.mesh import _check_indices

        _check_indices(faces, positions.shape[0], "face_list_vertex_normals")
    return _face_list_normals(native_order(positions), native_order(faces))


@jax.jit
def _face_list_normals(positions, faces):
    fn = face_normals(positions, faces)
    return normalize(corner_sums(fn, faces, positions.shape[0]))


face_list_vertex_normals.__wrapped__ = _face_list_normals.__wrapped__  # the unjitted body


def vertex_normals(s, positions, method: str = "scatter"):
    """``(num_vertices, 3)`` unit area-weighted normals of structure ``s``.

    ``positions`` are in the structure's vertex order (``positions[s.vertex_order]`` when the
    structure permuted vertices). Border darts contribute nothing, nor do the fans that closed
    holes (``s.dummy_vertex_mask()``, the CDS family): a border vertex gets the open mesh's
    normal, a dummy vertex a zero one. Differentiable in forward and reverse mode, to any order
    (``jax.grad``, ``jvp``, ``jacfwd``, ``hessian``), by either method.

    Integer, float16 and bfloat16 positions are taken as float32. In float32, coordinates beyond about 1e17 or under
    1e-17 in magnitude overflow or underflow in the face cross products (NaN or zero normals):
    pass :func:`within_range` of them (an exact power-of-two rescaling; normals are scale
    invariant), or float64 positions.

    Jitted (the structure and positions are traced, ``method`` is static); the positions'
    element type is checked before the jitted call, so it also works on traced positions.

    Raises:
      MeshError: ``positions`` is not ``(num_vertices, 3)`` (checked at trace time), or not
        real numbers (strings, objects, complex numbers: the imaginary part would be dropped), or a
        masked array (the mask would be dropped).
      ArgumentError: an unknown ``method`` (also one that is not a string: JAX's untyped
        "non-hashable static arguments" before), or ``s`` is not a structure.
    """
    from jaxcds.structures.base import structure_arg

    structure_arg(s, "vertex_normals")
    if not isinstance(method, str) or method not in ("scatter", "gather"):
        raise errors.ArgumentError(f"unknown normals method {method!r}: 'scatter' or 'gather'")
    refuse_non_real(positions, "positions", bools=True)
    return _vertex_normals(s, native_order(positions), method=method)


@functools.partial(jax.jit, static_argnames=("method",))
def _vertex_normals(s, positions, method: str = "scatter"):
    if method not in ("scatter", "gather"):
        raise errors.ArgumentError(f"unknown normals method {method!r}: 'scatter' or 'gather'")
    positions = _check_positions(s, positions)
    if method == "scatter":
        return normalize(_scatter_sums(s, positions))
    return _gather_normals(s, positions)


vertex_normals.__wrapped__ = _vertex_normals.__wrapped__  # the unjitted body
vertex_normals._cache_size = _vertex_normals._cache_size  # compiled variants held


def _check_positions(s, positions):
    """``positions`` as a floating array of shape ``(num_vertices, 3)`` (a nested list and
    integer coordinates are converted; the gather route's loop needs a float carry)."""
    positions = to_device(positions, copy=True)  # the caller's array: no shared buffer
    if not jnp.issubdtype(positions.dtype, jnp.floating) or jnp.finfo(positions.dtype).bits < 32:
        # integers, and float16 / bfloat16: their cross products overflow at coordinates of a
        # few hundred (all-NaN normals at 1,000, found by a sweep)
        positions = positions.astype(jnp.float32)
    if positions.ndim != 2 or positions.shape != (s.num_vertices, 3):
        raise errors.MeshError(
            f"positions must have shape ({s.num_vertices}, 3) for this {s.name} "
            f"(structure vertex order), got {tuple(positions.shape)}")
    return positions


def _scatter_sums(s, positions):
    chunked = getattr(s, "normal_sums", None)  # packed batches: sums chunk by chunk
    if chunked is not None:
        sums = chunked(positions)
        if sums is not None:
            return sums
    # any order and padding rows will do for a sum: structures with slotted faces skip compaction
    fv, valid = surface_faces_padded(s)
    return corner_sums(face_normals(positions, fv, valid), fv, s.num_vertices)


def faces_with_dummy_corner(dummy, faces):
    """``(R,)`` bool: the rows of ``faces`` with a corner flagged in ``dummy`` (the fans that
    closed holes, CDS Sec. 4.5: each holds its hole's dummy vertex)."""
    return dummy[faces[:, 0]] | dummy[faces[:, 1]] | dummy[faces[:, 2]]


def surface_faces_padded(s):
    """``s.face_vertices_padded()`` with the faces of the hole-closing fans (a face with a
    vertex of ``s.dummy_vertex_mask()``) marked invalid too: the input mesh's own faces. A
    structure without dummy vertices costs nothing more (the mask is ``None``, a trace-time
    test)."""
    fv, valid = s.face_vertices_padded()
    dummy = s.dummy_vertex_mask()
    if dummy is None:
        return fv, valid
    own = ~faces_with_dummy_corner(dummy, fv)
    return fv, own if valid is None else valid & own


# The gather route turns around vertices with a while_loop (its trip count is the largest degree,
# known only at run time), and while_loop has no reverse-mode derivative. Both routes compute the
# same function of the positions, so its derivative is the scatter route's: given as a custom
# JVP (the scatter route's tangent), which JAX transposes for reverse mode. A custom VJP gave
# reverse mode only: jax.jvp / jacfwd / hessian of the gather normals raised JAX's TypeError
# "can't apply forward-mode autodiff (jvp) to a custom_vjp function" (sweep 14).
@jax.custom_jvp
def _gather_normals(s, positions):
    return normalize(_gather_sums(s, positions))


@_gather_normals.defjvp
def _gather_jvp(primals, tangents):
    s, positions = primals
    dp = tangents[1]  # the structure's integer arrays have no tangent (float0)
    _, dn = jax.jvp(lambda p: normalize(_scatter_sums(s, p)), (positions,), (dp,))
    # the primal through _gather_normals itself: a derivative of this rule (hessian) uses it again
    return _gather_normals(s, positions), dn


#: turns of the gather route's first stage, over every vertex at once (most meshes finish in it:
#: their largest degree is under this); the vertices still turning then go on compacted,
#: GATHER_CHUNK lanes at a time (:func:`_gather_turns`)
GATHER_FIRST_TURNS = 64
GATHER_CHUNK = 1024


def _gather_sums(s, positions):
    """Every vertex's sum of face cross products, turning around it (:func:`_gather_turns`)."""
    return _gather_turns(s, positions)[0]


def _gather_turns(s, positions):
    """``(sums, lane turns)``: every vertex's sum of face cross products, turning around it
    (``ccw_vertex_edge``) from ``edge_of_vertex``; the lane turns (over the first stage's lanes
    and the compacted vertices') are the route's work, returned for the tests.

    Why in two stages: the lanes of one loop advance together, so one loop over every vertex
    ran as many turns as the largest degree, O(n d): quadratic around a hub (sweep 17b: a
    bipyramid whose poles have degree 16K took 6.1 s on the half-edge). After
    :data:`GATHER_FIRST_TURNS` turns, the vertices still turning (at most ``num_darts / 64``)
    go on compacted, :data:`GATHER_CHUNK` at a time (:func:`~jaxcds.structures.succinct.
    bitvector.finish_pending`; a batch of at most 4,096 vertices goes on whole), each chunk as long as
    its own largest degree. Each vertex adds its faces in the same order either way (the same
    sums, bit for bit). A mesh whose degrees are all under the first stage's turns skips the
    compaction. Stages of doubling turns over buffers of ``num_darts / turns``
    lanes did less work around a hub, but compiled the turn once per stage (CI: 3 minutes)."""
    from jaxcds.structures.succinct.bitvector import finish_pending

    n = s.num_vertices
    s = s.for_queries(s.num_darts)  # every dart is turned to once
    v = jnp.arange(n, dtype=jnp.int32)
    start = s.edge_of_vertex(v)
    dummy = s.dummy_vertex_mask()
    # a structure whose Target walks a fan (CDS6n/5n/4n, Thm 2: O(d)) hands out every dart's
    # target at once (O(n log d)): asked in this loop, the walk made the route O(n d^2) (a
    # bipyramid with poles of degree 800 took 6 s, of degree 2,000 did not finish)
    table = s.target_table() if getattr(s, "target_table", None) is not None else None
    target = s.target if table is None else (lambda e: table[e])

    def turns(vid, e, first, acc, done, limit):
        """Up to ``limit`` turns of the lanes ``vid`` (vertex ids; ``None``: every vertex) until
        all are done, and the turns run."""
        p0 = positions if vid is None else positions[vid]

        def cond(state):
            _, _, done, k = state
            return jnp.any(~done) & (k < limit)

        def body(state):
            e, acc, done, k = state
            e2 = s.ccw_vertex_edge(e)
            # the face (v, target(e), target(e2)) is the left face of e: skip border darts
            t1, t2 = target(e), target(e2)
            inner = ~s.is_border(e)
            if dummy is not None:  # and the faces of the hole-closing fans
                inner = inner & ~dummy[t1] & ~dummy[t2]
            a = positions[t1] - p0
            b = positions[t2] - p0
            contrib = jnp.where((inner & ~done)[:, None], jnp.cross(a, b), 0.0)
            return e2, acc + contrib, done | (e2 == first), k + 1

        return jax.lax.while_loop(cond, body, (e, acc, done, jnp.int32(0)))

    alone = ~s.dart_valid(start)  # a vertex in no face: no turn, a zero sum
    if dummy is not None:  # a dummy vertex: every face around it is a fan face
        alone = alone | dummy
    e, acc, done, k0 = turns(None, start, start, jnp.zeros_like(positions), alone, GATHER_FIRST_TURNS)
    work = k0.astype(jnp.float32) * n  # float: n d overflows int32

    def rest(vid, e, first, acc, done):  # the compacted lanes, to the end; their turns as a 4th column
        _, acc, _, k = turns(vid, e, first, acc, done, n + 1)
        return jnp.concatenate([acc, jnp.broadcast_to(k.astype(acc.dtype), (acc.shape[0], 1))], axis=1)

    whole = jnp.concatenate([acc, jnp.zeros((n, 1), acc.dtype)], axis=1)
    out = finish_pending(rest, ~done, whole, (v, e, start, acc, done), GATHER_CHUNK)
    return out[:, :3], work + jnp.sum(out[:, 3].astype(jnp.float32))
