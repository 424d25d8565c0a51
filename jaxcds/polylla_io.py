"""Polylla input and output: Triangle's ``.node`` / ``.ele`` / ``.neigh``, 2D OFF, point sets.

Everything here is numpy on the host. The readers return a :class:`Triangulation2D` (2D points
and counter-clockwise triangles, input vertex numbering kept: no welding, no dropping), the
writer puts a polygon mesh (CSR ``offsets`` / ``indices``) in an OFF file atomically.

Formats (Shewchuk's Triangle, https://www.cs.cmu.edu/~quake/triangle.html):

- ``.node``: header ``N dim n_attributes n_boundary_markers``, then ``id x y [attrs] [marker]``;
  ids start at 0 or 1 (the first id decides), ``#`` starts a comment.
- ``.ele``: header ``T nodes_per_triangle n_attributes``, then ``id a b c [...]`` (only the three
  corners are used, also for 6-node triangles).
- ``.neigh``: header ``T 3``, then ``id n0 n1 n2`` with ``-1`` for "no neighbour"; ``n_k`` is the
  triangle opposite corner ``k``. Optional: when given it is checked against the faces.
"""

from __future__ import annotations

import dataclasses
import os
import re
import warnings
from typing import Callable, Optional

import numpy as np

from jaxcds import errors

#: the registered structures that keep a triangulation's border as it is (Polylla's input);
#: here, beside the inputs, so that the CLI's parser reads it without loading the mesher
BORDER_STRUCTURES = ("halfedge", "pemb", "lr", "lr-bits")

__all__ = ["Triangulation2D", "read_triangle", "read_off_2d", "from_points", "read_input",
           "write_polygon_off", "read_polygon_off", "orient_ccw", "twice_signed_areas",
           "orientation_signs", "length_scale"]


@dataclasses.dataclass(frozen=True)
class Triangulation2D:
    """A planar triangulation on the host.

    Attributes:
      points: ``(V, 2)`` float64 coordinates.
      faces: ``(F, 3)`` int32 vertex ids, counter-clockwise.
      source: where it came from (file name, ``"points"``, ``"arrays"``).
      flipped: how many input triangles were clockwise and were re-oriented.
      clockwise: ``(F,)`` bool, which ones (None: none, or not known).
      duplicates: how many points repeat an earlier one exactly and are in no triangle
        (:func:`from_points`).
      notes: facts about the input worth telling the user (duplicates left out, a lone
        ``.node`` triangulated as a point set), one sentence each.

    Made by hand, ``points`` may be any real ``(V, 2)`` array or nested lists (``(V, 3)`` with
    every z = 0 too: a planar :class:`~jaxcds.mesh.TriMesh`'s vertices) and ``faces`` any
    integer ``(F, 3)`` ones (floats of integral value too): they are kept as C-contiguous native
    float64 / int32 (no copy when they are already). Other dtypes or shapes, and ids beyond
    int32, raise :class:`~jaxcds.errors.PolyllaError` here; other ids outside ``[0, V)`` are
    named when the triangulation is checked.
    """

    points: np.ndarray
    faces: np.ndarray
    source: str = "arrays"
    flipped: int = 0
    clockwise: Optional[np.ndarray] = None
    duplicates: int = 0
    notes: tuple = ()

    def __post_init__(self) -> None:
        # big-endian, float, unsigned or list arrays failed untyped in the numba kernels: made
        # the one kind they take once, here, as jaxcds.mesh.TriMesh does (typed PolyllaError)
        from jaxcds.mesh import _canonical, _int32_faces, _real_rows

        if _canonical(self.points, np.float64, 2) and _canonical(self.faces, np.int32, 3):
            return

        p = self.points
        if not _canonical(p, np.float64, 2):
            p = _real_rows(p, (2, 3), self.source, "points", "(N, 2)", errors.PolyllaError)
            if p.shape[1] == 3:  # a planar TriMesh's vertices: z = 0 is dropped, not a z != 0
                lifted = np.flatnonzero(p[:, 2] != 0)
                if lifted.size:
                    raise errors.PolyllaError(
                        f"{self.source}: points must have shape (N, 2), got {p.shape} with "
                        f"z = {float(p[lifted[0], 2])!r} at point {int(lifted[0])}; Polylla is planar")
                p = np.ascontiguousarray(p[:, :2])
            object.__setattr__(self, "points", p)
        if not _canonical(self.faces, np.int32, 3):
            object.__setattr__(self, "faces", _int32_faces(
                self.faces, p.shape[0], self.source, error=errors.PolyllaError,
                shape_error=errors.PolyllaError, what="triangle"))

    @property
    def input_faces(self) -> np.ndarray:
        """The triangles as the input listed them (corner order and orientation): ``faces`` with
        the re-oriented rows turned back. Polylla breaks ties between equally long edges by this
        corner order, as the reference does (:func:`jaxcds.algorithms.polylla.polylla`)."""
        if self.clockwise is None or not self.flipped:
            return self.faces
        return np.where(np.asarray(self.clockwise, bool)[:, None], self.faces[:, ::-1], self.faces)

    @property
    def all_clockwise(self) -> bool:
        """Every input triangle was clockwise (the reference's polygons are then clockwise)."""
        return self.flipped == self.num_faces > 0

    @property
    def num_vertices(self) -> int:
        return int(self.points.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self.faces.shape[0])


# ------------------------------------------------------------------------------ helpers
def _input_file(path: str) -> bytes:
    """The bytes of ``path``, a regular file (not a directory, FIFO or device: a FIFO would
    block forever and ``/dev/zero`` fill memory), or :class:`PolyllaError` naming it."""
    from jaxcds.mesh import read_regular_file

    return read_regular_file(path, error=errors.PolyllaError)


def _text(path: str) -> str:
    """The text of ``path`` (a UTF-8 byte-order mark before the first line dropped)."""
    return _input_file(path).decode("utf-8-sig", errors="replace")


_LINE_END = re.compile(r"\r\n|\r|\n")


def _rows(path: str, text: Optional[str] = None) -> list[list[str]]:
    """Non-empty, non-comment lines of a text file (``text``: its :func:`_text`, when already
    read), split on whitespace."""
    text = _text(path) if text is None else text
    rows = []
    # lines end at LF, CRLF or CR only: str.splitlines also ends them at a vertical tab, a form
    # feed and other separators, which made "0.5 0.9<VT>0.3 0.3" two points (fuzzing, sweep
    # 54b); inside a line they are blanks, as load_mesh reads them
    for line in _LINE_END.split(text):
        line = line.split("#", 1)[0].strip()
        if line:
            rows.append(line.split())
    if not rows:
        raise errors.PolyllaError(f"{path}: empty file")
    return rows


def _regular_table(text: str, fields: Callable[[list[str]], int]):
    """``(header fields, (n, k) float64 rows)`` of a Triangle file's text parsed in one pass,
    when it is regular: no comment, ``n`` (its header's first field) data lines of ``k = fields(header)``
    numbers each, the first column counting them from 0 or 1. ``None`` for any other file: the
    line-by-line reader (:func:`_rows`, :func:`_table`) reads it then and names what is wrong.

    Why: that reader splits every line in Python, about 6 s for a 1M-triangle input (its
    ``.node``, ``.ele`` and ``.neigh``), where Polylla itself runs in a fraction of a second.
    numpy parses the numbers in C, as Python's ``float`` (correctly rounded); a line with a
    missing or an extra field shifts the first column off its count, so it is not taken."""
    from jaxcds.mesh import _plain_numbers

    if "#" in text:
        return None
    head, _, body = text.strip().partition("\n")
    header = head.split()
    try:
        n, k = int(header[0]), int(fields(header))
    except (ValueError, IndexError):
        return None
    body = body.strip()
    if n < 1 or k < 1 or body.count("\n") + 1 != n:
        return None
    try:
        values = _plain_numbers(body, np.float64)
    except ValueError:
        return None
    if values.size != n * k:
        return None
    table = values.reshape(n, k)
    first = table[0, 0]
    if first not in (0.0, 1.0) or not np.array_equal(table[:, 0], np.arange(n) + first):
        return None
    return header, table


def _integer_columns(table: np.ndarray, columns: slice) -> Optional[np.ndarray]:
    """``table[:, columns]`` as int64 when every entry is an integer of at most 2^31 in
    magnitude; else ``None`` (the line-by-line reader names the entry)."""
    x = table[:, columns]
    if not np.all((x == np.floor(x)) & (np.abs(x) <= 2.0 ** 31)):
        return None
    return x.astype(np.int64)


def _ints(row: list[str], path: str, lineno: int, what: str) -> list[int]:
    try:
        return [int(x) for x in row]
    except ValueError as exc:
        raise errors.PolyllaError(f"{path}: {what} {lineno}: expected integers, got {row}") from exc


def _count(row: list[str], k: int, path: str, what: str, default: Optional[int] = None,
           least: int = 0) -> int:
    """Header field ``k`` of ``row`` (the first line of ``path`` that is not a comment): an
    integer of at least ``least``."""
    if k >= len(row):
        if default is not None:
            return default
        raise errors.PolyllaError(f"{path}: the header line has no {what}")
    try:
        x = int(row[k])
    except ValueError as exc:
        raise errors.PolyllaError(f"{path}: header line: {what} {row[k]!r} is not an integer") from exc
    if x < least:
        raise errors.PolyllaError(f"{path}: header line: {what} {x}, expected at least {least}")
    return x


def _table(rows, n, ncols, path, what, dtype):
    """``n`` data rows of at least ``ncols`` columns after the header row, as an array (more
    rows than the header announces are refused too: one of the two is wrong)."""
    body = rows[1:1 + n]
    many = "vertices" if what == "vertex" else what + "s"  # (the messages said "vertexs")
    if len(body) < n:
        raise errors.PolyllaError(
            f"{path}: header announces {n} {many} but only {len(body)} are present")
    if len(rows) > 1 + n:
        raise errors.PolyllaError(
            f"{path}: header announces {n} {many} but {len(rows) - 1} rows follow it")
    short = [i for i, r in enumerate(body) if len(r) < ncols]
    if short:
        raise errors.PolyllaError(
            f"{path}: {what} {short[0]} has {len(body[short[0]])} fields, expected at least {ncols}")
    try:
        return np.array([r[:ncols] for r in body], dtype=dtype)
    except (ValueError, OverflowError, TypeError):
        for i, r in enumerate(body):  # name the first row that does not convert
            try:
                np.array(r[:ncols], dtype=dtype)
            except (ValueError, OverflowError, TypeError) as exc:
                raise errors.PolyllaError(
                    f"{path}: {what} {i} ({' '.join(r[:ncols])}) is not a row of "
                    f"{np.dtype(dtype).name} numbers: {exc}") from None
        raise


def unit_scale(points: np.ndarray) -> np.ndarray:
    """``points`` times the power of two that brings the largest coordinate into ``[0.5, 1)``.

    Exact: every sum, product and comparison of the geometric tests scales by a power of two
    too, so they decide as on the input, but squared lengths no longer overflow (coordinates
    near 1e160) or fall into subnormals (near 1e-160), where ties changed the polygons."""
    p = np.asarray(points, dtype=np.float64)
    big = float(np.max(np.abs(p))) if p.size else 0.0
    if big == 0.0 or not np.isfinite(big):
        return p
    return np.ldexp(p, -int(np.frexp(big)[1]))


#: exponents of the largest coordinate between which Polylla's lengths are computed on the
#: coordinates as given (``2^LENGTH_EXPONENTS[0] <= max |x| < 2^LENGTH_EXPONENTS[1]``)
LENGTH_EXPONENTS = (-400, 510)


def length_scale(points: np.ndarray) -> np.ndarray:
    """``points`` for Polylla's edge lengths: as given while their squared differences cannot
    overflow (largest coordinate under ``2^510``, about 3.4e153: the sum of two squares of
    differences stays under ``2^1023``) and the largest coordinate is not tiny (``2^-400``,
    about 3.9e-121); else times a power of two (exact) that brings it just inside that range.

    As given, the lengths are the reference implementation's bit for bit (it computes
    ``sqrt(pow(dx, 2) + pow(dy, 2))`` on the input's doubles), so are its ties and polygons, also
    where a small feature's squares fall into subnormals (an input spanning 1e-10 to 1e150:
    scaling it to the unit box had made a rhombus's side longer than its diagonal, found
    against the compiled reference). Outside that range the reference's lengths overflow to
    infinity (coordinates past about 1.3e154) or underflow to zero (about 1e-162), so every
    triangle reads as a three-way tie there; these lengths do not, so the polygons differ from
    the reference's on such inputs (README, Polylla)."""
    p = np.asarray(points, dtype=np.float64)
    big = float(np.max(np.abs(p))) if p.size else 0.0
    if big == 0.0 or not np.isfinite(big):
        return p
    e = int(np.frexp(big)[1])  # big = m 2^e, m in [0.5, 1)
    lo, hi = LENGTH_EXPONENTS
    if e > hi:
        return np.ldexp(p, hi - e)  # scaled down as little as it takes: fewest subnormals
    if e <= lo:
        return np.ldexp(p, -e)  # scaled up: exact, and no square underflows any more
    return p


def orientation_signs(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(F,)`` int8: the exact sign of every triangle's area (1 counter-clockwise, -1 clockwise,
    0 collinear corners), for float64 ``points``.

    A floating-point determinant decides where it is clear of its rounding error (Shewchuk's
    ``ccwerrboundA`` on coordinates scaled to the unit box, which keeps its products normal);
    the rest (slivers, near-collinear corners far from the origin, features under the
    subnormal range) are decided in exact rational arithmetic on the coordinates as given: a
    triangle whose exact area is positive is never called flat (the compiled reference
    accepted one that a float area test had refused)."""
    q = unit_scale(points)
    t = q[faces]
    left = (t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
    right = (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0])
    det = left - right
    eps = 2.0 ** -53
    bound = (3.0 + 16.0 * eps) * eps * (np.abs(left) + np.abs(right))
    # below 2^-960 the products may have lost bits to subnormals: the bound no longer holds
    unsure = (np.abs(det) <= bound) | (np.abs(left) + np.abs(right) < 2.0 ** -960)
    sign = np.sign(det).astype(np.int8)
    for f in np.nonzero(unsure)[0]:
        sign[f] = _exact_orientation(points[faces[f]])
    return sign


def _exact_orientation(corners: np.ndarray) -> int:
    """The exact sign of a triangle's ``(3, 2)`` float64 corners: the exact Delaunay module's
    test (integers over one power-of-two denominator), one predicate for both."""
    from jaxcds._exact_delaunay import exact_orient

    return exact_orient(np.asarray(corners, dtype=np.float64), 0, 1, 2)


def orient_ccw(points: np.ndarray, faces: np.ndarray, source: str = "arrays"):
    """Faces turned counter-clockwise (by the sign of their area); ``(faces, n_flipped)``.

    Raises:
      PolyllaError: a triangle of zero area (collinear corners), naming it.
    """
    out, cw = _orient(points, faces, source)
    return out, int(cw.sum())


def twice_signed_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(F,)`` twice the signed area of every triangle of ``faces`` (2-D ``points``):
    positive counter-clockwise, negative clockwise, zero for collinear corners."""
    p = points[faces]
    return ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def _orient(points: np.ndarray, faces: np.ndarray, source: str):
    """:func:`orient_ccw`, returning which faces were clockwise (a bool mask)."""
    area2 = orientation_signs(points, faces)
    flat = np.nonzero(area2 == 0)[0]
    if flat.size:
        raise errors.PolyllaError(
            f"{source}: triangle {int(flat[0])} {faces[flat[0]].tolist()} has zero area "
            f"({flat.size} degenerate triangles)")
    cw = area2 < 0
    out = faces.copy()
    out[cw] = out[cw][:, ::-1]
    return np.ascontiguousarray(out, dtype=np.int32), cw


def _check_faces(faces: np.ndarray, nv: int, source: str) -> None:
    bad = np.nonzero((faces < 0) | (faces >= nv))
    if bad[0].size:
        t = int(bad[0][0])
        raise errors.PolyllaError(
            f"{source}: triangle {t} refers to vertex {int(faces[t, bad[1][0]])}, "
            f"outside [0, {nv})")
    rep = np.nonzero((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                     | (faces[:, 0] == faces[:, 2]))[0]
    if rep.size:
        raise errors.PolyllaError(
            f"{source}: triangle {int(rep[0])} repeats a vertex {faces[rep[0]].tolist()}")


def _make(points, faces, source, ccw: bool = False) -> Triangulation2D:
    """A checked :class:`Triangulation2D`; ``ccw``: the faces are known to be counter-clockwise
    (Qhull's, which a floating-point area can contradict on a sliver), else oriented here."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if points.shape[0] == 0 or faces.shape[0] == 0:
        raise errors.PolyllaError(
            f"{source}: empty triangulation ({points.shape[0]} vertices, {faces.shape[0]} triangles)")
    bad = np.nonzero(~np.isfinite(points).all(axis=1))[0]
    if bad.size:
        raise errors.PolyllaError(
            f"{source}: vertex {int(bad[0])} has a non-finite coordinate {points[bad[0]].tolist()}")
    _check_faces(faces, points.shape[0], source)
    if ccw:
        return Triangulation2D(points=points, faces=np.ascontiguousarray(faces, dtype=np.int32),
                               source=source)
    faces, cw = _orient(points, faces, source)
    flipped = int(cw.sum())
    return Triangulation2D(points=points, faces=faces, source=source, flipped=flipped,
                           clockwise=cw if flipped else None)


# ------------------------------------------------------------------------------ readers
def read_triangle(node: str, ele: Optional[str] = None, neigh: Optional[str] = None) -> Triangulation2D:
    """Read Triangle's ``.node`` + ``.ele`` (``.neigh`` optional, checked when given).

    ``node`` may also be the common stem (``points50.1``) or any of the three file names; the
    siblings are found by suffix. Domains with holes are fine (no triangle covers a hole).
    A ``.node`` (or stem) with no ``.ele`` beside it is a point set, Delaunay-triangulated
    (:func:`_lone_node`); an ``.ele`` named but missing is refused.
    """
    named_ele = ele is not None or node.endswith((".ele", ".neigh"))
    stem = node
    for suf in (".node", ".ele", ".neigh"):
        if stem.endswith(suf):
            stem = stem[: -len(suf)]
    node = stem + ".node" if not node.endswith(".node") else node
    ele = ele or stem + ".ele"
    if neigh is None and os.path.exists(stem + ".neigh"):
        neigh = stem + ".neigh"
    # id, x, y, attributes, boundary marker; a regular file in one pass, else line by line
    text = _text(node)
    fast = _regular_table(text, lambda h: 1 + int(h[1]) + int(h[2]) + int(h[3]))
    if fast is not None and fast[0][1] == "2" and fast[1].shape[0] >= 3:
        tab = fast[1][:, :3]
        nv = tab.shape[0]
    else:
        rows = _rows(node, text)
        nv = _count(rows[0], 0, node, "vertex count", least=3)
        dim = _count(rows[0], 1, node, "dimension", default=2)
        if dim != 2:
            raise errors.PolyllaError(f"{node}: dimension {dim} in the header, Polylla needs 2")
        tab = _table(rows, nv, 3, node, "vertex", np.float64)
    # a float id was truncated to the next lower integer; inf, nan or one past int64 became
    # garbage in the cast below (a RuntimeWarning, then "line 3 has id -9223372036854775808")
    frac = np.flatnonzero(~(np.abs(tab[:, 0]) <= 2.0 ** 62) | (tab[:, 0] != np.floor(tab[:, 0])))
    if frac.size:
        raise errors.PolyllaError(f"{node}: vertex {int(frac[0])} has id {float(tab[frac[0], 0])!r}; "
                                  "ids are consecutive integers from 0 or 1")
    ids = tab[:, 0].astype(np.int64)
    base = int(ids[0]) if nv else 0
    if base not in (0, 1) or np.any(ids != np.arange(base, base + nv)):
        bad = int(np.nonzero(ids != np.arange(base, base + nv))[0][0]) if base in (0, 1) else 0
        raise errors.PolyllaError(
            f"{node}: vertex ids must run consecutively from 0 or 1; line {bad + 1} has id {int(ids[bad])}")
    points = tab[:, 1:3]
    if not named_ele and not os.path.lexists(ele):
        return _lone_node(points, node)
    _require_ele(node, ele)
    # id, the corners (3, or 6 for second-order triangles), attributes
    text = _text(ele)
    fast = _regular_table(text, lambda h: 1 + int(h[1]) + int(h[2]))
    et = None if fast is None or fast[0][1] not in ("3", "6") else _integer_columns(fast[1], slice(0, 4))
    if et is None:
        erows = _rows(ele, text)
        nt = _count(erows[0], 0, ele, "triangle count", least=1)
        per = _count(erows[0], 1, ele, "nodes per triangle", default=3)
        if per not in (3, 6):
            raise errors.PolyllaError(f"{ele}: {per} nodes per triangle in the header (expected 3 or 6)")
        # a row holds all ``per`` nodes (second-order triangles: 3 corners, then 3 midpoints); a
        # header of 6 over rows of 3 was taken as it came
        et = _table(erows, nt, 1 + per, ele, "triangle", np.int64)
    faces = et[:, 1:4] - base
    tri = _make(points, faces, os.path.basename(stem))
    if neigh is not None:
        _check_neigh(neigh, faces - 0, tri.num_faces, base)
    return tri


def _lone_node(points: np.ndarray, node: str) -> Triangulation2D:
    """A ``.node`` with no ``.ele`` beside it is a point set: Triangle's own program
    (``triangle pts.node``) writes its Delaunay triangulation, so it is triangulated here as an
    ``.xy`` list would be (:func:`from_points`); attributes and boundary markers are not used.
    Said in the result's ``notes``."""
    tri = from_points(points, os.path.basename(node))
    note = (f"{os.path.basename(node)} has no .ele beside it: its {points.shape[0]} points were "
            "Delaunay-triangulated as a point set (attributes and boundary markers ignored)")
    return dataclasses.replace(tri, notes=(note,) + tri.notes)


def _require_ele(node: str, ele: str) -> None:
    """An .ele named (as the input, or as ``ele``) but missing: "x.ele: no such file" alone did
    not say why an .ele is needed nor how to give a point set (sweep 53b). A .node given alone
    is a point set (:func:`_lone_node`)."""
    if not os.path.lexists(ele):
        raise errors.PolyllaError(
            f"{node}: its triangles file {os.path.basename(ele)} does not exist; Polylla meshes "
            "a triangulation (put Triangle's .ele beside the .node), or give the .node alone or "
            "the points as .xy/.txt/.csv/.npy to have them Delaunay-triangulated")


def _check_neigh(path: str, faces: np.ndarray, nf: int, base: int) -> None:
    """Every neighbour listed in ``.neigh`` shares the edge opposite the corner it is listed at."""
    text = _text(path)
    fast = _regular_table(text, lambda h: 4)
    tab = None if fast is None or fast[1].shape[0] != nf else _integer_columns(fast[1], slice(1, 4))
    if tab is None:
        rows = _rows(path, text)
        n = _count(rows[0], 0, path, "triangle count")
        if n != nf:
            raise errors.PolyllaError(f"{path}: {n} triangles in the header, the .ele file has {nf}")
        tab = _table(rows, n, 4, path, "triangle", np.int64)[:, 1:4]
    nb = np.where(tab < 0, -1, tab - base)
    if np.any(nb >= nf):
        t = int(np.nonzero((nb >= nf).any(axis=1))[0][0])
        raise errors.PolyllaError(f"{path}: triangle {t} lists a neighbour outside [0, {nf})")
    own = np.nonzero((nb == np.arange(nf)[:, None]).any(axis=1))[0]
    if own.size:
        raise errors.PolyllaError(f"{path}: triangle {int(own[0])} lists itself as its neighbour")
    t, k = np.nonzero(nb >= 0)
    if t.size:
        a = faces[t, (k + 1) % 3]
        b = faces[t, (k + 2) % 3]
        other = faces[nb[t, k]]
        shares = ((other == a[:, None]).any(axis=1)) & ((other == b[:, None]).any(axis=1))
        bad = np.nonzero(~shares)[0]
        if bad.size:
            i = int(bad[0])
            raise errors.PolyllaError(
                f"{path}: triangle {int(t[i])} lists triangle {int(nb[t[i], k[i]])} as neighbour "
                f"{int(k[i])}, but they do not share edge ({int(a[i])}, {int(b[i])})")
    _check_neigh_borders(path, faces, nb)


def _check_neigh_borders(path: str, faces: np.ndarray, nb: np.ndarray) -> None:
    """Every ``-1`` in ``.neigh`` stands for a border edge. The reference trusts the file: an
    edge two triangles share but listed without a neighbour is a cut in its domain, while the
    triangles here are paired by their corners, so the polygons differed without a word."""
    border = np.flatnonzero(nb.ravel() < 0)
    if not border.size:
        return
    a = faces[:, [1, 2, 0]].astype(np.int64).ravel()  # the edge opposite corner k
    b = faces[:, [2, 0, 1]].astype(np.int64).ravel()
    key = np.minimum(a, b) * (int(faces.max()) + 1) + np.maximum(a, b)
    # every side looked up among the border sides' edges only (sorted: a few per cent of the
    # 3F sides): a sort of all 3F keys took about 0.4 s of a 6 s read at 1M triangles
    bkey = np.sort(key[border])
    at = np.minimum(np.searchsorted(bkey, key), bkey.size - 1)  # the first of equal keys
    sides = np.bincount(at[bkey[at] == key], minlength=bkey.size)  # sides on each border edge
    cut = border[sides[at[border]] > 1]  # a border side whose edge another side has too
    if cut.size:
        i = int(cut[0])
        t, k = divmod(i, 3)
        other = int(next(j for j in np.flatnonzero(key == key[i]) if j != i))
        raise errors.PolyllaError(
            f"{path}: triangle {t} lists no neighbour (-1) as neighbour {k}, but triangle "
            f"{other // 3} shares that edge ({int(a[i])}, {int(b[i])}): a .neigh lists "
            "every neighbour (the reference would cut the domain along that edge)")


def read_off_2d(path: str) -> Triangulation2D:
    """A 2D triangulation in OFF (``z`` ignored); every face must be a triangle."""
    rows = _rows(path)
    i = 0
    if rows[0][0].upper() in ("OFF", "COFF", "NOFF", "STOFF"):
        i = 1
    elif rows[0][0] == "{":  # geomview LIST wrapper as written by the reference Polylla
        while i < len(rows) and rows[i][0].upper() != "OFF":
            i += 1
        i += 1
    if i > 0 and i <= len(rows) and len(rows[i - 1]) > 1:
        # the counts on the keyword's line ("OFF 4 2 0"): the vertices start on the next one
        rows = rows[:i - 1] + [rows[i - 1][:1], rows[i - 1][1:]] + rows[i:]
    if i >= len(rows):
        raise errors.PolyllaError(f"{path}: no OFF header")
    try:
        nv, nf = int(rows[i][0]), int(rows[i][1])
    except (ValueError, IndexError) as exc:
        raise errors.PolyllaError(f"{path}: bad OFF counts line {rows[i]}") from exc
    if nv < 3 or nf < 1:
        raise errors.PolyllaError(f"{path}: OFF counts line {rows[i]}: {nv} vertices and {nf} "
                                  "faces (a triangulation needs at least 3 and 1)")
    vrows = rows[i + 1: i + 1 + nv]
    frows = rows[i + 1 + nv: i + 1 + nv + nf]
    if len(vrows) < nv or len(frows) < nf:
        raise errors.PolyllaError(
            f"{path}: header announces {nv} vertices and {nf} faces, the file is shorter")
    # rows past the declared faces (the "}" closing a geomview wrapper aside): the faces after
    # the count were dropped without a word ("4 1 0" over two triangles meshed one)
    rest = [r for r in rows[i + 1 + nv + nf:] if not (r == ["}"] and rows[0][0] == "{")]
    if rest:
        raise errors.PolyllaError(
            f"{path}: data past the last face the OFF header declares ({nv} vertices, {nf} "
            f"faces): {len(rest)} more line(s), the first {' '.join(rest[0])[:60]!r} (a wrong "
            "count in the header?)")
    short = [j for j, r in enumerate(vrows) if len(r) < 2]
    if short:
        raise errors.PolyllaError(f"{path}: vertex {short[0]} has {len(vrows[short[0]])} coordinate(s) "
                                  f"{vrows[short[0]]}, expected x y (z)")
    try:
        pts = np.array([r[:2] for r in vrows], dtype=np.float64)
    except ValueError as exc:
        raise errors.PolyllaError(f"{path}: a vertex line is not numeric: {exc}") from exc
    faces = np.empty((nf, 3), dtype=np.int64)
    for j, r in enumerate(frows):
        k = _ints(r[:1], path, j, "face")[0]
        if k != 3:
            raise errors.PolyllaError(
                f"{path}: face {j} has {k} vertices; Polylla needs a triangulation")
        idx = _ints(r[1:4], path, j, "face")
        if len(idx) < 3:
            raise errors.PolyllaError(f"{path}: face {j} lists {len(idx)} of its 3 vertices: {r}")
        if any(not 0 <= x < nv for x in idx):
            raise errors.PolyllaError(f"{path}: face {j} {idx} refers to a vertex outside [0, {nv})")
        faces[j] = idx
    return _make(pts, faces, os.path.basename(path))


def qhull_failure_reason(exc: Exception, pts: np.ndarray) -> str:
    """One line for a Qhull failure (its message is a 50-line diagnostic): the cause when it is
    a flat point set, else Qhull's first line."""
    q = unit_scale(pts)  # no overflow in the mean and the rank below (points near 1e308)
    centred = q - q.mean(axis=0)
    spread = float(np.abs(centred).max()) if centred.size else 0.0
    try:
        flat = spread == 0.0 or np.linalg.matrix_rank(centred / spread, tol=1e-12) < 2
    except np.linalg.LinAlgError:
        flat = False
    if flat:
        return "every point lies on one line (or they coincide); a triangulation needs area"
    first = str(exc).strip().splitlines()[:1]
    return first[0] if first else type(exc).__name__


def from_points(points, source: str = "points") -> Triangulation2D:
    """The Delaunay triangulation of a 2D point set, exactly (every orientation and in-circle
    test decided as in exact arithmetic, as Shewchuk's Triangle decides them): Qhull's
    (``scipy.spatial.Delaunay``) repaired by :mod:`jaxcds._exact_delaunay`. Where four points
    are exactly cocircular either diagonal is Delaunay; Qhull's is kept.

    Every distinct point is a vertex; a point repeating an earlier one exactly is left in no
    triangle (ids unchanged, as Triangle leaves it), with a :class:`~jaxcds.errors.PolyllaWarning`
    naming how many and the first pair (also in the result's ``notes``).

    Raises:
      PolyllaError: points not an ``(N, 2)`` real array, fewer than 3, a non-finite one, or all
        on one line (exactly).
    """
    try:
        raw = np.asarray(points)
        if raw.dtype.fields is not None or np.iscomplexobj(raw) or raw.dtype.kind in "USOVMm":
            raise TypeError(f"dtype {raw.dtype}")
        pts = raw.astype(np.float64)
    except (TypeError, ValueError) as exc:
        raise errors.PolyllaError(f"{source}: points must be real numbers, got {exc}") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise errors.PolyllaError(f"{source}: points must have shape (N, 2), got {pts.shape}")
    if pts.shape[0] < 3:
        raise errors.PolyllaError(f"{source}: {pts.shape[0]} points, at least 3 are needed")
    bad = np.nonzero(~np.isfinite(pts).all(axis=1))[0]
    if bad.size:
        raise errors.PolyllaError(f"{source}: point {int(bad[0])} is not finite")
    keep, repeats = _first_copies(pts)
    faces = _exact_delaunay_faces(pts[keep], source)
    faces = keep[faces]
    notes = ()
    if repeats.size:
        later, first = (int(x) for x in repeats[0])
        note = (f"{repeats.shape[0]} of the {pts.shape[0]} points repeat an earlier point and are "
                f"left in no triangle, as Triangle leaves them (point {later} repeats point "
                f"{first} {pts[first].tolist()})")
        warnings.warn(errors.PolyllaWarning(f"{source}: {note}"), stacklevel=2)
        notes = (note,)
    # counter-clockwise by construction (every orientation decided exactly)
    return Triangulation2D(points=pts, faces=np.ascontiguousarray(faces, dtype=np.int32),
                           source=source, duplicates=int(repeats.shape[0]), notes=notes)


def _first_copies(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(keep, repeats)``: the ids of the first copy of every distinct point, ascending, and a
    ``(R, 2)`` array of ``(later copy, first copy)`` pairs, ascending by the later copy. Exact
    comparison (``-0.0`` equals ``0.0``), as Triangle's duplicate test."""
    order = np.lexsort((pts[:, 1], pts[:, 0]))  # stable: a group's first copy comes first
    s = pts[order]
    same = np.zeros(order.size, bool)
    same[1:] = (s[1:] == s[:-1]).all(axis=1)
    if not same.any():
        return np.arange(pts.shape[0]), np.empty((0, 2), np.int64)
    group = np.cumsum(~same) - 1
    first = order[~same][group]  # the first copy of every sorted point's group
    later = np.sort(order[same])
    owner = np.empty(pts.shape[0], np.int64)
    owner[order] = first
    return np.sort(order[~same]), np.stack([later, owner[later]], axis=1)


def _exact_delaunay_faces(pts: np.ndarray, source: str) -> np.ndarray:
    """Counter-clockwise triangles (ids into ``pts``, distinct points) of the exact Delaunay
    triangulation (:func:`jaxcds._exact_delaunay.triangulate`), or :class:`PolyllaError` when
    every point lies on one line."""
    from jaxcds import _exact_delaunay as ed

    try:
        return ed.triangulate(pts)
    except ed.Collinear:
        raise errors.PolyllaError(
            f"{source}: Delaunay triangulation failed: every point lies on one line (or they "
            "coincide); a triangulation needs area") from None
    except ed._Broken:  # never seen: the build from scratch lost its own mesh
        raise errors.PolyllaError(
            f"{source}: Delaunay triangulation failed: the exact build lost its mesh (a jaxcds "
            "bug: please report it with the points)") from None


def _npy_array(data: bytes, path: str) -> np.ndarray:
    """The array in a ``.npy`` file's bytes, its header checked before ``np.load`` reads the
    data: numpy allocates the shape its header declares first (a header cut or flipped to
    4294967295 rows asked for 64 GB before it found the data short), and a garbled header
    raised what its parser raises (tokenize's ``TokenError``, ``OverflowError``, ``SyntaxError``)."""
    import io
    import math

    from numpy.lib import format as npy

    fh = io.BytesIO(data)
    try:
        version = npy.read_magic(fh)
        # version 3.0 only allows a UTF-8 header, whose fields 2.0's reader parses alike
        read = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
        shape, _, dtype = read(fh)
    except Exception as exc:  # what numpy's header parser raises is not one kind
        raise errors.PolyllaError(f"{path}: not a numeric .npy array: its header (bytes 0-"
                                  f"{max(fh.tell() - 1, 0)}) does not parse: {exc}") from None
    need = math.prod(shape) * dtype.itemsize
    if not dtype.hasobject and need > len(data) - fh.tell():
        raise errors.PolyllaError(
            f"{path}: the .npy header declares a {dtype} array of shape {shape} ({need} bytes "
            f"from byte {fh.tell()}), the file holds {len(data) - fh.tell()} bytes there (truncated?)")
    try:
        return np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise errors.PolyllaError(f"{path}: not a numeric .npy array: {exc}") from exc


def read_input(path: str) -> Triangulation2D:
    """Any Polylla input by suffix: ``.node``/``.ele``/``.neigh`` (or their stem), ``.off``,
    or a point list (``.xy``, ``.txt``, ``.csv``, ``.npy``: one ``x y`` per line, Delaunay)."""
    low = path.lower()
    if low.endswith((".node", ".ele", ".neigh")) or (
            not os.path.exists(path) and os.path.exists(path + ".node")):
        return read_triangle(path)
    if low.endswith(".off"):
        return read_off_2d(path)
    if low.endswith(".npy"):
        return from_points(_npy_array(_input_file(path), path), os.path.basename(path))
    if low.endswith((".xy", ".txt", ".csv", ".pts")):
        rows = [[c for c in ",".join(r).split(",") if c] for r in _rows(path)]
        short = [j for j, r in enumerate(rows) if len(r) < 2]
        if short:
            raise errors.PolyllaError(f"{path}: point {short[0]} has {len(rows[short[0]])} "
                                      f"coordinate(s) {rows[short[0]]}, expected x y")
        try:
            pts = np.array([[float(x) for x in r[:2]] for r in rows])
        except ValueError as exc:
            raise errors.PolyllaError(f"{path}: a point line is not numeric: {exc}") from exc
        return from_points(pts, os.path.basename(path))
    raise errors.PolyllaError(
        f"{path}: unknown Polylla input (expected .node/.ele/.neigh, .off, or a point list "
        ".xy/.txt/.csv/.npy)")


# ------------------------------------------------------------------------------ OFF output
def write_polygon_off(path: str, points: np.ndarray, offsets: np.ndarray, indices: np.ndarray) -> None:
    """Write a polygon mesh as OFF (``z = 0``), atomically (temporary file + ``os.replace``:
    :func:`jaxcds.codec.fileformat.atomic_write_bytes`, :class:`OutputError` naming ``path``)."""
    from jaxcds.codec.fileformat import atomic_write_bytes, rows_text

    points = np.asarray(points, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    npoly = offsets.shape[0] - 1
    xyz = np.column_stack([points[:, :2], np.zeros(points.shape[0])])
    text = (f"OFF\n{points.shape[0]} {npoly} 0\n" + rows_text("%.17g %.17g %.17g\n", xyz)
            + _polygon_lines(offsets, indices))
    atomic_write_bytes(path, text.encode())


def _polygon_lines(offsets: np.ndarray, indices: np.ndarray, chunk: int = 1 << 16) -> str:
    """``"k i_1 ... i_k\\n"`` per polygon, in order: one ``%`` per chunk of polygons over the
    concatenation of their size's row format (the polygons' vertices are contiguous in
    ``indices``, so the chunk's arguments are one slice of it)."""
    sizes = np.diff(offsets)
    row = {int(k): f"{k}" + " %d" * int(k) + "\n" for k in np.unique(sizes)}
    return "".join(
        "".join(row[k] for k in sizes[a:a + chunk].tolist())
        % tuple(indices[offsets[a]:offsets[min(a + chunk, sizes.size)]].tolist())
        for a in range(0, sizes.size, chunk))


def read_polygon_off(path: str) -> tuple[np.ndarray, list[list[int]]]:
    """``(points (V, 2), polygons)`` of a polygon OFF file (the reference's geomview ``LIST``
    wrapper ``{ ... }`` is accepted)."""
    rows = _rows(path)
    i = 0
    while i < len(rows) and rows[i][0].upper() != "OFF":
        i += 1
    if i == len(rows):
        raise errors.PolyllaError(f"{path}: no OFF header")
    nv, nf = int(rows[i + 1][0]), int(rows[i + 1][1])
    pts = np.array([r[:2] for r in rows[i + 2: i + 2 + nv]], dtype=np.float64)
    polys = []
    for j, r in enumerate(rows[i + 2 + nv: i + 2 + nv + nf]):
        k = int(r[0])
        if len(r) < k + 1:
            raise errors.PolyllaError(f"{path}: polygon {j} announces {k} vertices, has {len(r) - 1}")
        polys.append([int(x) for x in r[1: k + 1]])
    if len(polys) != nf:
        raise errors.PolyllaError(f"{path}: header announces {nf} polygons, found {len(polys)}")
    return pts, polys
