"""Write (and optionally execute) the jaxcds notebooks from the Python source cells below.

The notebooks are generated, not edited by hand: change a cell here, then run ::

    .venv/bin/python notebooks/make_notebooks.py --execute          # all six, normal sizes
    .venv/bin/python notebooks/make_notebooks.py --execute 02 05    # only some
    JAXCDS_NB_SMALL=1 .venv/bin/python notebooks/make_notebooks.py --execute --no-write  # smoke run

Cells are ``("md", text)`` or ``("code", text)``. Executed notebooks keep their outputs (tables,
pictures as PNG), so a reader sees them on GitHub without running anything. Every notebook reads
``JAXCDS_NB_SMALL=1`` (set by ``tests/test_notebooks.py``) to run at small sizes.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Dict, List, Tuple

HERE = os.path.dirname(os.path.abspath(__file__))
SMALL_ENV = "JAXCDS_NB_SMALL"

Cell = Tuple[str, str]

# Shared first lines of every notebook: imports, the size switch, inline PNG figures.
_PRELUDE = '''\
import os, time
import numpy as np
import jax, jax.numpy as jnp
import matplotlib
import matplotlib.pyplot as plt
from IPython.display import Markdown, display
%matplotlib inline
plt.rcParams["figure.dpi"] = 80

SMALL = os.environ.get("JAXCDS_NB_SMALL") == "1"   # the test suite runs every notebook with SMALL
print("jax", jax.__version__, "| small sizes" if SMALL else "| normal sizes")

def render(ax, P, F, normals=None, face_colours=None, title="", elev=12, azim=-60):
    """Flat 3-D render of a y-up mesh (rotated to matplotlib's z-up): faces shaded by their mean
    vertex normal against a light near the viewer, or coloured by `face_colours`."""
    R = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])             # rotation: y-up -> z-up
    P = np.asarray(P) @ R.T
    coll = ax.plot_trisurf(P[:, 0], P[:, 1], P[:, 2], triangles=F, linewidth=0, antialiased=False)
    if normals is not None:
        e, a = np.radians(elev + 25), np.radians(azim + 20)
        light = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        shade = np.clip((np.asarray(normals) @ R.T)[F].mean(axis=1) @ light, 0, 1)
        face_colours = plt.cm.Greys_r(0.1 + 0.8 * shade)
    coll.set_facecolor(face_colours)
    ax.set_axis_off(); ax.set_box_aspect(np.ptp(P, axis=0), zoom=1.35); ax.view_init(elev, azim)
    ax.set_title(title)'''

# ----------------------------------------------------------------------------------- 01 tour
TOUR: List[Cell] = [
    ("md", """\
# 1. A tour of jaxcds

Load a mesh, build **every registered structure**, compare their memory, run batched queries
with `jax.jit`, check each structure operator by operator against the half-edge, and pack
many meshes into one batch.

With `JAXCDS_NB_SMALL=1` (the test suite sets it) the tour runs on a small random
triangulation instead of the bundled bunny."""),
    ("code", _PRELUDE + '''

import jaxcds
from jaxcds import batch as B
from jaxcds.algorithms import adjacent, vertex_degrees, vertex_normals
from jaxcds.cli import default_mesh_path
from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import registry
from jaxcds.verify import verify

mesh = random_planar_triangulation(300, seed=0) if SMALL else jaxcds.load_mesh(default_mesh_path())
print(os.path.basename(mesh.source), mesh.num_vertices, "vertices", mesh.num_faces, "faces")
print(jaxcds.topology(mesh))'''),
    ("md", """\
## Every structure of the registry
Each builder takes the validated mesh; compact structures may renumber vertices
(`vertex_order`). `references` is the papers' memory measure (integers stored), *bytes* counts
every array the structure holds (bit-packed structures hold fewer bytes than 4 per reference),
and `verify` compares every operator on every dart with the half-edge."""),
    ("code", '''\
from jaxcds.structures.halfedge import HalfEdge
reference = HalfEdge.from_faces(mesh.faces, mesh.num_vertices)   # one reference for every check
rows, structures = [], {}
for name in registry.names():
    t0 = time.perf_counter()
    try:
        s = registry.build(name, mesh)
    except jaxcds.errors.JaxcdsError as exc:
        rows.append(f"| {name} | refused: {type(exc).__name__} | | | | | |")
        continue
    t_build = time.perf_counter() - t0
    rep = verify(s, mesh, reference=reference, adjacency_samples=2000)
    assert rep.mismatches == 0, (name, str(rep))
    structures[name] = s
    rows.append(f"| {name} | {type(s).__name__} | {s.references:,} | {s.references_per_vertex:.2f} | "
                f"{s.nbytes / s.num_vertices:.1f} | {t_build * 1e3:.0f} ms | {rep.checked:,} / {rep.mismatches} |")
display(Markdown("| structure | class | references | refs / vertex | bytes / vertex | build | verify: checks / mismatches |\\n"
                 "|---|---|---|---|---|---|---|\\n" + "\\n".join(rows)))'''),
    ("code", '''\
names = list(structures)
refs = [structures[n].references_per_vertex for n in names]
nbytes = [structures[n].nbytes / structures[n].num_vertices for n in names]
fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), sharey=True)
axes[0].barh(names, refs, color="tab:blue"); axes[0].set_xlabel("references per vertex")
axes[1].barh(names, nbytes, color="tab:green"); axes[1].set_xlabel("bytes per vertex (all arrays)")
axes[0].invert_yaxis()
for ax, vals in zip(axes, (refs, nbytes)):
    for i, r in enumerate(vals):
        ax.text(r, i, f" {r:.2f}" if vals is refs else f" {r:.0f}", va="center")
fig.suptitle(f"memory on {os.path.basename(mesh.source)} ({mesh.num_vertices} vertices)")
plt.tight_layout(); plt.show()'''),
    ("md", """\
## Batched queries, jitted
Every operator takes arrays of dart ids: here a batch of random darts per structure and four
operators (Target, Twin, Next = LeftFront, Face_left) in one jitted call (timings on a shared
2-core CPU: indicative only, `benchmarks/` has the careful numbers). A batch this large (many
times the mesh's darts) reads tables of every dart's answer where one id costs more than a
gather (LR's opposite corners, pemb's parenthesis searches, the CDS Target walk): computed once
per call. The answers are compared with the half-edge's through `vertex_order`, as `verify` did
above for every operator on every dart (its per-operator counts include `adjacent` on vertex
pairs, and both routes where a structure has two)."""),
    ("code", '''\
he = structures["halfedge"]
rng = np.random.default_rng(0)
Q = 100_000 if SMALL else 400_000

@jax.jit
def queries(s, e):
    return s.origin(e), s.target(e), s.target(s.twin(e)), s.target(s.next(e)), s.face_left(e)

he_darts = he.all_darts()
he_o, he_t = (np.asarray(x) for x in jax.jit(lambda e: (he.origin(e), he.target(e)))(jnp.asarray(he_darts)))
he_next_target = {(a, b): c for a, b, c in zip(he_o, he_t, np.asarray(he.target(he.next(jnp.asarray(he_darts)))))}
timing = []
for name, s in structures.items():
    e = jnp.asarray(rng.choice(s.all_darts(), Q))
    jax.block_until_ready(queries(s, e))                 # compile + warm-up
    t0 = time.perf_counter(); out = jax.block_until_ready(queries(s, e)); t = time.perf_counter() - t0
    o, tg, tw, nx, _ = (np.asarray(x) for x in out)
    order = np.arange(mesh.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
    o, tg, tw, nx = order[o], order[tg], order[tw], order[nx]          # back to input vertex ids
    k = rng.integers(0, Q, 1000)
    ok = bool(np.all(tw == o)) and all(he_next_target[(a, b)] == c for a, b, c in zip(o[k], tg[k], nx[k]))
    assert ok, name
    timing.append(f"| {name} | {1e9 * t / Q:.1f} ns | {ok} |")
display(Markdown("| structure | 4 operators, per dart | agrees with the half-edge |\\n|---|---|---|\\n" + "\\n".join(timing)))
print("verify, per operator (mismatches), last structure:", rep.by_operator)'''),
    ("md", """\
## Degrees and normals on any structure
`vertex_degrees` and `vertex_normals` are generic: they only use the navigation protocol, so
they give the same answer on every structure (up to float rounding)."""),
    ("code", '''\
pos = jnp.asarray(mesh.vertices, jnp.float32)
n_ref = np.asarray(vertex_normals(he, pos))
d_ref = np.asarray(vertex_degrees(he))
for name, s in structures.items():
    order = s.vertex_order
    p = pos if order is None else pos[np.asarray(order)]
    n = np.asarray(vertex_normals(s, p))
    d = np.asarray(vertex_degrees(s))
    if order is not None:
        inv = np.argsort(np.asarray(order))
        n, d = n[inv], d[inv]
    print(f"{name:14s} max |normal - half-edge normal| = {np.abs(n - n_ref).max():.1e}, "
          f"degrees equal: {bool(np.array_equal(d, d_ref))}, degree sum = {d.sum()} (= 2E = {2 * (3 * mesh.num_vertices - 6)})")'''),
    ("code", '''\
fig = plt.figure(figsize=(6, 6))
render(fig.add_subplot(projection="3d"), mesh.vertices, mesh.faces, normals=n_ref,
       title="shaded by vertex normals (half-edge)")
plt.show()'''),
    ("md", """\
## Many meshes at once: a packed batch
`jaxcds.batch.pack` builds ONE structure over the disjoint union (jraph / PyTorch3D packed
layout: concatenated arrays, per-mesh counts and offsets). Normals of every mesh in one jitted
call, queries with mesh-local ids, per-mesh reductions, gradients to every mesh's positions."""),
    ("code", '''\
meshes = [random_planar_triangulation(int(n), seed=i)
          for i, n in enumerate(rng.integers(50, 500, 8 if SMALL else 64))]
b = B.pack(meshes, "corner-table")
print(b)
P = B.pack_positions(b, meshes)
normals = jax.jit(vertex_normals)(b, P)
mean_degree = np.asarray(b.per_mesh_mean(vertex_degrees(b).astype(jnp.float32)))
print("mean degree per mesh (6 - 12/n on a sphere):", np.round(mean_degree[:6], 3), "...")
assert np.allclose(mean_degree, [6 - 12 / m.num_vertices for m in meshes], atol=1e-4)
mesh_ids = jnp.asarray(rng.integers(0, b.num_meshes, 5))
local = jnp.zeros(5, jnp.int32)
print("Target of local dart 0 in meshes", np.asarray(mesh_ids), "->", np.asarray(b.query("target", mesh_ids, local)))
g = jax.grad(lambda p: jnp.sum(vertex_normals(b, p)[:, 2]))(P)
print("gradient reaches every mesh:", bool(np.all(np.asarray(b.per_mesh_sum(jnp.abs(g).sum(1))) > 0)))'''),
]

# ----------------------------------------------------------------------------------- 02 drawings
DRAWINGS: List[Cell] = [
    ("md", """\
# 2. Schnyder woods and the LR ring, drawn

**Schnyder woods** (CDS paper, Sec. 1.3, Fig. 1): the inner edges of a planar triangulation split
into three trees, red, blue and black, rooted at the outer vertices `V_red`, `V_blue`,
`V_black`; around every inner vertex the edges follow the local rule *out red, in black\\*, out
blue, in red\\*, out black, in blue\\** (ccw). `jaxcds.construct.schnyder.schnyder_wood` computes
the maximal wood (Appendix A, no cw cycle) by vertex conquest.

To draw a wood without any geometry we use **Schnyder's own barycentric grid drawing**
(Schnyder 1990): the three paths `P_red(v)`, `P_blue(v)`, `P_black(v)` from an inner vertex `v`
to the roots cut the inner faces into three regions; `R_i(v)` is the one opposite `V_i`. With
`r_i(v)` = the number of faces of `R_i(v)` (so `r_red + r_blue + r_black = 2n - 5`), placing `v`
at `(r_red A + r_blue B + r_black C) / (2n - 5)` for a triangle `A, B, C` gives a straight-line
planar drawing on a `(2n-5)` grid; the notebook checks that every inner face comes out with
positive area.

**The LR ring** (LR paper, Sec. 4, Fig. 1): RING-EXPANDER invades the mesh and its boundary, the
ring, visits (almost) every vertex; triangles with one ring edge are T1 (cream), two are T2
(blue warts), none are T0 (green); a T0 next to a T2 wart is stored in the wart's spare slot
(wart skipping, Sec. 5; gray)."""),
    ("code", _PRELUDE + '''

import collections
from matplotlib.patches import Polygon
import jaxcds
from jaxcds.construct.schnyder import BLACK, BLUE, RED, schnyder_wood, check_schnyder_wood
from jaxcds.generators import random_planar_triangulation

COLOURS = {RED: "tab:red", BLUE: "tab:blue", BLACK: "black"}'''),
    ("md", """\
## Regions and the barycentric drawing
`region_counts` is deliberately plain Python (a flood fill of the dual graph per vertex, `O(n^2)`):
the drawing is for small triangulations, and the code reads like the definition."""),
    ("code", '''\
def tree_path(wood, v, c):
    """Vertices of the path from v to the root of tree c (following outgoing c-edges)."""
    path = [v]
    while wood.out[path[-1], c] < wood.num_vertices:
        path.append(int(wood.out[path[-1], c]))
    return path

def region_counts(wood, faces):
    """(n, 3) number of inner faces in R_red(v), R_blue(v), R_black(v) for every vertex v."""
    n, F = wood.num_vertices, len(faces)
    key = lambda a, b: (min(a, b), max(a, b))
    edge_faces = collections.defaultdict(list)
    for f, (a, b, c) in enumerate(faces):
        for x, y in ((a, b), (b, c), (c, a)):
            edge_faces[key(x, y)].append(f)
    inner = [f for f in range(F) if f != wood.root_face]
    V = wood.outer                       # (V_red, V_blue, V_black)
    # R_i contains the outer edge opposite V_i, i.e. the inner face on that edge
    anchor = [next(f for f in edge_faces[key(V[(i + 1) % 3], V[(i + 2) % 3])] if f != wood.root_face)
              for i in range(3)]
    counts = np.zeros((n, 3), int)
    for i in range(3):
        counts[V[i], i] = len(inner)     # an outer vertex V_i: R_i is everything
    for v in range(n):
        if v in V:
            continue
        cut = set()
        for c in range(3):
            p = tree_path(wood, v, c)
            cut.update(key(a, b) for a, b in zip(p, p[1:]))
        comp = -np.ones(F, int)
        for i in range(3):               # flood fill from each anchor, never crossing a path edge
            stack = [anchor[i]]; comp[anchor[i]] = i
            while stack:
                f = stack.pop()
                a, b, c = faces[f]
                for x, y in ((a, b), (b, c), (c, a)):
                    if key(x, y) in cut:
                        continue
                    for g in edge_faces[key(x, y)]:
                        if g != wood.root_face and comp[g] < 0:
                            comp[g] = i; stack.append(g)
        assert (comp[inner] >= 0).all(), "the three regions must cover the inner faces"
        counts[v] = np.bincount(comp[inner], minlength=3)
    return counts

def schnyder_drawing(wood, faces):
    """Schnyder's barycentric drawing: (n, 2) positions, V_red, V_blue, V_black ccw."""
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])   # A (red), B (blue), C (black)
    r = region_counts(wood, faces)
    assert (r.sum(axis=1) == 2 * wood.num_vertices - 5).all()
    return r @ corners / (2 * wood.num_vertices - 5), r

def signed_areas(xy, faces):
    a, b, c = xy[faces[:, 0]], xy[faces[:, 1]], xy[faces[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))'''),
    ("code", '''\
def draw_wood(ax, wood, xy, labels=None, arrows=True, colours=(RED, BLUE, BLACK), dashed=(), size=30):
    """Outer triangle in gray, each coloured edge as an arrow source -> target (Fig. 1 b)."""
    V = wood.outer
    for i in range(3):
        a, b = V[i], V[(i + 1) % 3]
        ax.plot(*xy[[a, b]].T, color="0.6", lw=1.5, zorder=1)
    for u, t, c in wood.edges():
        if c not in colours:
            continue
        ls = "--" if c in dashed else "-"
        if arrows:
            ax.annotate("", xy=xy[t], xytext=xy[u], zorder=2,
                        arrowprops=dict(arrowstyle="-|>", color=COLOURS[c], lw=1.3, ls=ls,
                                        shrinkA=4, shrinkB=4, mutation_scale=10))
        else:
            ax.plot(*xy[[u, t]].T, color=COLOURS[c], lw=1.0, ls=ls, zorder=2)
    ax.scatter(*xy.T, s=size, c="white", edgecolors="k", zorder=3)
    for i, c in enumerate((RED, BLUE, BLACK)):
        ax.scatter(*xy[V[i]], s=3 * size, c=COLOURS[c], edgecolors="k", zorder=4)
    if labels is not None:
        for v, lab in enumerate(labels):
            ax.annotate(str(lab), xy[v], xytext=(4, 4), textcoords="offset points", fontsize=8, zorder=5)
    ax.set_aspect("equal"); ax.set_axis_off()'''),
    ("md", """\
## Fig. 1: a small triangulation and its maximal Schnyder wood
A uniform random planar triangulation (Poulalhon–Schaeffer sampler); root face = face 0.
`check_schnyder_wood` re-checks Definition 1 (local rule at every vertex) and maximality."""),
    ("code", '''\
n_small = 12
mesh = random_planar_triangulation(n_small, seed=3)
faces = mesh.faces
wood = schnyder_wood(faces, mesh.num_vertices, maximal=True)
print("outer vertices (V_red, V_blue, V_black):", wood.outer)
print("Definition-1 / maximality violations:", check_schnyder_wood(wood, faces) or "none")
xy, r = schnyder_drawing(wood, faces)
inner = np.arange(len(faces)) != wood.root_face
area = signed_areas(xy, faces)
print(f"inner faces with positive area: {int((area[inner] > 0).sum())} of {int(inner.sum())} (planar drawing)")
assert (area[inner] > 0).all()
print("grid coordinates (r_red, r_blue, r_black) of the first inner vertices:",
      [tuple(map(int, r[v])) for v in range(n_small) if v not in wood.outer][:4], "sum =", 2 * n_small - 5)

fig, axes = plt.subplots(1, 3, figsize=(15, 5))
# (a) the triangulation
for f in faces[inner]:
    axes[0].add_patch(Polygon(xy[f], closed=True, fc="0.95", ec="0.3", lw=0.8))
axes[0].scatter(*xy.T, s=30, c="white", edgecolors="k", zorder=3)
for v in range(n_small):
    axes[0].annotate(str(v), xy[v], xytext=(4, 4), textcoords="offset points", fontsize=8)
axes[0].set_aspect("equal"); axes[0].set_axis_off(); axes[0].set_title(f"(a) planar triangulation, n = {n_small}")
# (b) the wood
draw_wood(axes[1], wood, xy, labels=range(n_small))
axes[1].set_title("(b) maximal Schnyder wood (Schnyder drawing)")
# (c) the three regions of one inner vertex
v0 = next(v for v in range(n_small) if v not in wood.outer and min(r[v]) > 0)
draw_wood(axes[2], wood, xy, arrows=False, size=10)
for c in (RED, BLUE, BLACK):
    p = tree_path(wood, v0, c)
    axes[2].plot(*xy[p].T, color=COLOURS[c], lw=4, alpha=0.5)
for i, c in enumerate((RED, BLUE, BLACK)):
    A = xy[wood.outer[(i + 1) % 3]]; Bp = xy[wood.outer[(i + 2) % 3]]
    mid = (A + Bp + xy[v0]) / 3
    axes[2].text(*mid, f"R_{['red','blue','black'][i]}: {r[v0, i]}", color=COLOURS[c], ha="center", fontsize=10,
                 bbox=dict(fc="white", ec="none", alpha=0.7))
axes[2].set_title(f"(c) paths and region sizes of vertex {v0}")
plt.tight_layout(); plt.show()'''),
    ("md", """\
## Fig. 5: cwBFS labels of the red tree
CDS4n (Thm 5) renumbers the vertices by a **cw breadth-first traversal** of the red tree
`T_red` from `V_red`, so the children of every vertex get consecutive labels; the structure then
stores only one reference for red edges. Below: the maximal wood of a larger triangulation,
labelled by cwBFS (red children of a vertex in clockwise order, from the rotation the wood
stores), and the check that every vertex's red children have consecutive labels. We compare our
labels with the `vertex_order` of the registered `cds4n` structure built on the same mesh."""),
    ("code", '''\
def cw_bfs(wood):
    """cwBFS of T_red from V_red: label[v] for every vertex (children of v consecutive)."""
    n = wood.num_vertices
    label = np.full(n, -1); label[wood.v_red] = 0
    queue, nxt = collections.deque([wood.v_red]), 1
    while queue:
        u = queue.popleft()
        rot = wood.neighbors[wood.offsets[u]:wood.offsets[u + 1]]
        col = wood.colour[wood.offsets[u]:wood.offsets[u + 1]]
        og = wood.outgoing[wood.offsets[u]:wood.offsets[u + 1]]
        for w, c, o in zip(rot[::-1], col[::-1], og[::-1]):      # clockwise
            if c == RED and not o and label[w] < 0:               # incoming red edge: a child
                label[w] = nxt; nxt += 1; queue.append(w)
    for w in (wood.v_blue, wood.v_black):                        # the two other roots come last
        if label[w] < 0:
            label[w] = nxt; nxt += 1
    return label

n_mid = 20 if SMALL else 30
mesh5 = random_planar_triangulation(n_mid, seed=7)
wood5 = schnyder_wood(mesh5.faces, mesh5.num_vertices, maximal=True)
xy5, _ = schnyder_drawing(wood5, mesh5.faces)
lab = cw_bfs(wood5)
assert sorted(lab) == list(range(n_mid))
children = collections.defaultdict(list)
for u, t, c in wood5.edges():
    if c == RED:
        children[t].append(lab[u])
consecutive = all(max(ch) - min(ch) == len(ch) - 1 for ch in children.values())
print("red children have consecutive cwBFS labels at every vertex:", consecutive)
assert consecutive

s4 = jaxcds.build("cds4n", mesh5)
order = np.asarray(s4.vertex_order)      # order[i] = input vertex of structure vertex i
print("cds4n relabels the", n_mid, "vertices; identical to our cwBFS labels:",
      bool(np.array_equal(np.argsort(order), lab)))

fig, ax = plt.subplots(figsize=(7.5, 7))
draw_wood(ax, wood5, xy5, labels=lab, size=25)
ax.set_title(f"maximal Schnyder wood, n = {n_mid}, vertices labelled by cwBFS of the red tree")
plt.show()'''),
    ("md", """\
## Fig. 9: the 4n-bit encoding reads the red tree and the black in-degrees
The red word is the balanced-parenthesis word of a ccw DFS of `T_red` (2n bits); the black word
stores each vertex's black in-degree in unary (2n - 3 bits); the blue tree is implied by the local
Schnyder rule. Left: the red tree with black edges dashed (what the words describe); right:
the full wood after decoding, the decoded triangulation checked against the input."""),
    ("code", '''\
from jaxcds.codec.api import encode_mesh, decode

enc = encode_mesh(random_planar_triangulation(n_small, seed=3), mixed=False)
bits = "".join(map(str, enc.words.unpacked()))
red_w, black_w = bits[:2 * n_small], bits[2 * n_small:]
print("red word  :", red_w.replace("0", "(").replace("1", ")"))
print("black word:", black_w)
print(f"{len(bits)} bits = 4n - 3 = {4 * n_small - 3} for n = {n_small} ({enc.bits_per_vertex:.2f} bits per vertex)")
dec = decode(enc.words, structure="faces")
canon = lambda F: sorted(tuple(np.roll(f, -int(np.argmin(f)))) for f in F)
same = canon(np.asarray(enc.order)[dec]) == canon(enc.mesh.faces)
print("decoded faces (mapped back through `order`) equal the input faces:", same)
assert same

fig, axes = plt.subplots(1, 2, figsize=(11, 5))
draw_wood(axes[0], wood, xy, labels=range(n_small), colours=(RED, BLACK), dashed=(BLACK,))
axes[0].set_title("red tree + black edges (dashed): the two words")
draw_wood(axes[1], wood, xy, labels=range(n_small))
axes[1].set_title("blue edges recovered by the local rule")
plt.tight_layout(); plt.show()'''),
    ("md", """\
## The LR ring (LR paper Fig. 1)
A Delaunay triangulation of random points in the unit square, its convex hull closed by one
dummy vertex (LR Sec. 4.6: dummy vertices are never on the ring, dummy triangles never invaded).
RING-EXPANDER runs on the corner table (`V`, `O`) from a few seeds and keeps the ring with the
fewest isolated vertices; `lr_tables` classifies the triangles and applies wart skipping."""),
    ("code", '''\
from jaxcds.construct.ring_expander import best_ring, lr_tables
from jaxcds.generators import delaunay_square
from jaxcds.structures.corner_table import CornerTable
from jaxcds.verify import verify

square = delaunay_square(80 if SMALL else 200, seed=1, closed=True)
ct = CornerTable.from_mesh(square)
Vc, Oc = np.asarray(ct.V), np.asarray(ct.O)
tri = Vc.reshape(-1, 3)
ring = best_ring(Vc, Oc, square.num_vertices, seeds=4, dummy=square.dummy_vertices)
tables = lr_tables(Vc, Oc, ring, square.num_vertices)
real = ~square.dummy_faces
ring_edges = {frozenset(e) for e in zip(ring.order, np.roll(ring.order, -1))}
on_ring = np.array([sum(frozenset((t[i], t[(i + 1) % 3])) in ring_edges for i in range(3)) for t in tri])
t0_after = np.zeros(len(tri), bool); t0_after[np.asarray(tables.t0)] = True
kind = np.where(on_ring == 2, "T2", np.where(on_ring == 1, "T1", np.where(t0_after, "T0", "T0w")))
st = tables.stats(len(tri), int(real.sum()))
print(f"{square.num_vertices - 1} vertices: ring m_r = {st['m_r']}, isolated m_i = {st['m_i'] - 1} (+1 dummy)")
print({k: int(((kind == k) & real).sum()) for k in ("T1", "T2", "T0", "T0w")}, "real triangles;",
      f"T0 {st['pct_T0']:.1f}%, T0^w {st['pct_T0w']:.1f}%, T^i {st['pct_Ti']:.1f}% (Table 1 columns)")
# the same counts as lr_tables, which also classifies the dummy triangles of the hull fan
assert (kind == "T0w").sum() == st["T0w"] and (kind == "T0").sum() == st["T0"] and (kind == "T2").sum() == st["T2"]

open_square = delaunay_square(square.num_vertices - 1, seed=1)   # the same mesh with its border
s_lr = jaxcds.build("lr", open_square)     # closes the hull itself; shows the border as the half-edge does
rep = verify(s_lr, open_square)
print(f"LR structure: {s_lr.references / open_square.num_faces:.3f} references per triangle (rpt), "
      f"verify vs half-edge: {rep.checked:,} checks, {rep.mismatches} mismatches")

fill = {"T1": "#f6d7a7", "T2": "#7fb3e6", "T0": "#8fd18f", "T0w": "0.65"}
xy2 = square.vertices[:, :2]
fig, ax = plt.subplots(figsize=(8, 8))
for t, k, ok in zip(tri, kind, real):
    if ok:
        ax.add_patch(Polygon(xy2[t], closed=True, fc=fill[k], ec="0.45", lw=0.5))
loop = np.append(ring.order, ring.order[0])
ax.plot(*xy2[loop].T, color="k", lw=2.2)
iso = np.setdiff1d(np.nonzero(~square.dummy_vertices)[0], ring.order)
ax.scatter(*xy2[iso].T, s=60, c="tab:red", zorder=5, label=f"isolated vertices ({len(iso)})")
for k, c in fill.items():
    ax.add_patch(Polygon([[0, 0]], fc=c, label={"T1": "T1 (one ring edge)", "T2": "T2 wart (two)",
                                                 "T0": "T0 (none)", "T0w": "T0 stored by wart skipping"}[k]))
ax.legend(loc="upper left", bbox_to_anchor=(1, 1)); ax.set_aspect("equal"); ax.set_axis_off()
ax.set_title("LR ring (black loop) and triangle types")
plt.tight_layout(); plt.show()'''),
    ("md", """\
## The ring search (beyond the paper)
`jaxcds.construct.ring_search.improve_ring` anneals RING-EXPANDER's ring: it grows onto isolated
vertices and moves ears of either side to other ring edges at their tips, always keeping a disk
with every vertex on the ring. The LR reference count `2 m_r + 6 n0 + 3 n^i + m_i` is local, so
each move costs O(1). `LR.from_mesh(mesh, ring_sweeps=100)` (or `jaxcds build -s lr
--ring-sweeps 100`) runs it before the tables are built. Below, the same square: most T0
triangles (green) become T0^w (gray: stored in a T2 wart's spare slot), so fewer references."""),
    ("code", '''\
from jaxcds.construct.ring_expander import extract_ring
from jaxcds.construct.ring_search import improve_ring, ring_cost
from jaxcds.structures.lr import LR

tm, gain = improve_ring(Vc, Oc, ring.invaded, square.num_vertices, dummy=square.dummy_vertices, sweeps=100)
ring2 = extract_ring(Vc, Oc, tm, square.num_vertices)
tables2 = lr_tables(Vc, Oc, ring2, square.num_vertices)
assert ring_cost(Vc, Oc, tm, square.num_vertices, square.dummy_vertices) == (
    ring_cost(Vc, Oc, ring.invaded, square.num_vertices, square.dummy_vertices) + gain)
edges2 = {frozenset(e) for e in zip(ring2.order, np.roll(ring2.order, -1))}
on2 = np.array([sum(frozenset((t[i], t[(i + 1) % 3])) in edges2 for i in range(3)) for t in tri])
t0b = np.zeros(len(tri), bool); t0b[np.asarray(tables2.t0)] = True
kind2 = np.where(on2 == 2, "T2", np.where(on2 == 1, "T1", np.where(t0b, "T0", "T0w")))
s_search = LR.from_mesh(open_square, ring_sweeps=100)
print(f"this ring: {gain:+d} references; LR.from_mesh(ring_sweeps=100): {s_lr.references} -> "
      f"{s_search.references} references, rpt {s_lr.references / open_square.num_faces:.3f} -> "
      f"{s_search.references / open_square.num_faces:.3f}")
fig, axes = plt.subplots(1, 2, figsize=(12, 6))
for ax, kk, rr, title in ((axes[0], kind, ring, "RING-EXPANDER"), (axes[1], kind2, ring2, "after the ring search")):
    for t, k, ok in zip(tri, kk, real):
        if ok:
            ax.add_patch(Polygon(xy2[t], closed=True, fc=fill[k], ec="0.45", lw=0.5))
    lp = np.append(rr.order, rr.order[0])
    ax.plot(*xy2[lp].T, color="k", lw=1.8)
    ax.set_title(f"{title}: {int(((kk == 'T0') & real).sum())} T0, {int(((kk == 'T0w') & real).sum())} T0^w")
    ax.set_aspect("equal"); ax.set_axis_off()
plt.tight_layout(); plt.show()'''),
    ("md", """\
## Table 1 (right): a mesh colour-coded blue to red in ring order
Ring vertices coloured by their position along the ring, isolated vertices gray, on the bundled
bunny (a small sphere-like random mesh with `JAXCDS_NB_SMALL`)."""),
    ("code", '''\
from jaxcds.cli import default_mesh_path
from jaxcds.generators import icosphere

m3 = icosphere(2) if SMALL else jaxcds.load_mesh(default_mesh_path())
s3 = jaxcds.build("lr", m3)
order3 = np.asarray(s3.vertex_order)            # ring vertices first, in ring order
m_r = m3.num_vertices - s3.num_isolated
rank = np.full(m3.num_vertices, np.nan); rank[order3[:m_r]] = np.arange(m_r) / max(m_r - 1, 1)
face_rank = np.nanmean(rank[m3.faces], axis=1)
P3 = np.asarray(m3.vertices)
fig = plt.figure(figsize=(11, 5.5))
for k, (el, az) in enumerate(((12, -60), (12, 120))):
    ax = fig.add_subplot(1, 2, k + 1, projection="3d")
    colours = plt.cm.coolwarm(np.nan_to_num(face_rank, nan=0.5))
    colours[np.isnan(face_rank)] = (0.6, 0.6, 0.6, 1)
    render(ax, P3, m3.faces, face_colours=colours, elev=el, azim=az)
fig.suptitle(f"{os.path.basename(m3.source)}: {m3.num_vertices} vertices, ring of {m_r}, {s3.num_isolated} isolated, "
             f"{s3.references / m3.num_faces:.2f} rpt")
plt.tight_layout(); plt.show()'''),
]

# ----------------------------------------------------------------------------------- 03 differentiable
DIFF: List[Cell] = [
    ("md", """\
# 3. A differentiable pipeline on a compact structure

Vertex normals computed by `jaxcds.algorithms.vertex_normals` on a **compact** structure
(CDS5n, CDS paper Thm 4; references per vertex printed below, against 19 for the half-edge) are
differentiable with respect to the positions. We denoise a mesh by gradient descent on a
*normal smoothing* energy: neighbouring vertex normals should agree, while positions stay close
to the data. The gradient through the compact structure is compared with the gradient through
the plain face-list normals (`face_list_vertex_normals`)."""),
    ("code", _PRELUDE + '''

import jaxcds
from jaxcds.algorithms import vertex_normals
from jaxcds.algorithms.normals import face_list_vertex_normals
from jaxcds.cli import default_mesh_path
from jaxcds.generators import icosphere

try:
    import optax
except ImportError:   # not a dependency of jaxcds: fall back to a few lines of Adam
    optax = None
print("optimiser:", "optax.adam" if optax else "hand-written Adam (optax not installed)")'''),
    ("md", """\
## The data: a mesh with noise along the normals
CDS5n renumbers vertices (`vertex_order`), so positions are permuted once, up front; edges are
read from the structure itself (`origin`/`target` of every dart)."""),
    ("code", '''\
mesh = icosphere(3) if SMALL else jaxcds.load_mesh(default_mesh_path())
s = jaxcds.build("cds5n", mesh)
order = np.arange(s.num_vertices) if s.vertex_order is None else np.asarray(s.vertex_order)
P_clean = jnp.asarray(mesh.vertices[order], jnp.float32)
scale = float(np.median(np.linalg.norm(np.diff(mesh.vertices[mesh.faces[:, :2]], axis=1)[:, 0], axis=1)))
rng = np.random.default_rng(0)
N_clean = vertex_normals(s, P_clean)
P_noisy = P_clean + 0.35 * scale * rng.standard_normal((s.num_vertices, 1)).astype(np.float32) * N_clean

darts = jnp.asarray(s.all_darts())
U, W = s.origin(darts), s.target(darts)                   # every edge, both directions
F_s = np.asarray(s.face_vertices())                       # faces in the structure's numbering
print(f"{os.path.basename(mesh.source)}: {s.num_vertices} vertices, {len(F_s)} faces, {s.references_per_vertex:.2f} refs/vertex "
      f"({type(s).__name__}); median edge {scale:.3g}; {darts.size} darts")'''),
    ("md", """\
## Loss
`E(P) = mean over edges (u, w) of |n_u - n_w|^2  +  lam * mean |P - P_noisy|^2 / h^2`, with `n`
the unit area-weighted vertex normals of the structure and `h` the median edge length."""),
    ("code", '''\
lam = 0.2

def smoothing_loss(P, normals_fn):
    N = normals_fn(P)
    return jnp.mean(jnp.sum((N[U] - N[W]) ** 2, axis=1)) + lam * jnp.mean(jnp.sum((P - P_noisy) ** 2, axis=1)) / scale**2

loss_cds = lambda P: smoothing_loss(P, lambda P: vertex_normals(s, P))
# the face list of the input file, renumbered like the structure (not read back from it)
F_in = jnp.asarray(np.argsort(order)[mesh.faces].astype(np.int32))
loss_faces = lambda P: smoothing_loss(P, lambda P: face_list_vertex_normals(P, F_in))

g_cds = jax.jit(jax.grad(loss_cds))(P_noisy)
g_faces = jax.jit(jax.grad(loss_faces))(P_noisy)
rel = float(jnp.linalg.norm(g_cds - g_faces) / jnp.linalg.norm(g_faces))
print(f"loss: cds5n {float(loss_cds(P_noisy)):.6f}, face list {float(loss_faces(P_noisy)):.6f}")
print(f"gradient: max |cds5n - face list| = {float(jnp.abs(g_cds - g_faces).max()):.2e}, "
      f"relative L2 difference = {rel:.2e} (float32)")
assert rel < 1e-4

for name, fn in (("cds5n", loss_cds), ("face list", loss_faces)):
    vg = jax.jit(jax.value_and_grad(fn))
    jax.block_until_ready(vg(P_noisy))
    t0 = time.perf_counter()
    for _ in range(10):
        out = vg(P_noisy)
    jax.block_until_ready(out)
    print(f"value_and_grad through {name:9s}: {(time.perf_counter() - t0) / 10 * 1e3:.2f} ms per call")'''),
    ("md", "## Optimisation (Adam)"),
    ("code", '''\
steps, lr = (40, 0.02 * scale) if SMALL else (200, 0.02 * scale)
if optax is not None:
    opt = optax.adam(lr)
    init, update = opt.init, opt.update
    apply = optax.apply_updates
else:
    def init(P):
        return (jnp.zeros_like(P), jnp.zeros_like(P), jnp.zeros((), jnp.int32))
    def update(g, state, P=None, b1=0.9, b2=0.999, eps=1e-8):
        m, v, t = state
        t = t + 1
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        mh, vh = m / (1 - b1 ** t), v / (1 - b2 ** t)
        return -lr * mh / (jnp.sqrt(vh) + eps), (m, v, t)
    apply = lambda P, u: P + u

@jax.jit
def step(P, state):
    loss, g = jax.value_and_grad(loss_cds)(P)
    upd, state = update(g, state, P)
    return apply(P, upd), state, loss

P, state, losses = P_noisy, init(P_noisy), []
t0 = time.perf_counter()
for i in range(steps):
    P, state, loss = step(P, state)
    losses.append(float(loss))
print(f"{steps} steps in {time.perf_counter() - t0:.2f} s (first includes compilation); "
      f"loss {losses[0]:.4f} -> {losses[-1]:.4f}")
err = lambda Q: float(jnp.mean(jnp.linalg.norm(Q - P_clean, axis=1)) / scale)
ang = lambda Q: float(jnp.degrees(jnp.mean(jnp.arccos(jnp.clip(jnp.sum(vertex_normals(s, Q) * N_clean, 1), -1, 1)))))
print(f"mean distance to the clean mesh: {err(P_noisy):.3f} h -> {err(P):.3f} h; "
      f"mean normal error: {ang(P_noisy):.1f} deg -> {ang(P):.1f} deg")
assert losses[-1] < losses[0]'''),
    ("code", '''\
def shaded(ax, P, title):
    render(ax, P, F_s, normals=vertex_normals(s, jnp.asarray(P)), title=title)

fig = plt.figure(figsize=(18, 5))
shaded(fig.add_subplot(1, 4, 1, projection="3d"), P_clean, "clean")
shaded(fig.add_subplot(1, 4, 2, projection="3d"), P_noisy, "noisy (before)")
shaded(fig.add_subplot(1, 4, 3, projection="3d"), P, f"after {steps} Adam steps")
ax = fig.add_subplot(1, 4, 4)
ax.plot(losses); ax.set_yscale("log"); ax.set_xlabel("step"); ax.set_ylabel("loss"); ax.set_title("loss curve")
ax.grid(alpha=0.3)
plt.tight_layout(); plt.show()'''),
]

# ----------------------------------------------------------------------------------- 04 compression
COMPRESSION: List[Cell] = [
    ("md", """\
# 4. Compression: 4n bits and linear-time decoding

The CDS paper (Sec. 3) encodes the connectivity of a planar triangulation with a Schnyder wood in
`4n - 3` bits: the red tree as a balanced-parenthesis word (2n bits) and the black in-degrees in
unary (2n - 3 bits). `jaxcds.codec.api` encodes (`encode_mesh`) and decodes, either to a face
list or directly into the packed CDS structures (memory-free decoding, Fig. 10-13). Below:
bits per vertex and encode / decode speed against the mesh size, on uniform random planar
triangulations (Poulalhon–Schaeffer sampler). Timings are wall-clock on a shared machine."""),
    ("code", _PRELUDE + '''

from jaxcds.codec.api import decode, encode_mesh
from jaxcds.generators import random_planar_triangulation

sizes = [1_000, 10_000, 30_000] if SMALL else [1_000, 10_000, 100_000, 300_000, 1_000_000]'''),
    ("code", '''\
def best_of(fn, repeats):
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter(); out = fn(); ts.append(time.perf_counter() - t0)
    return out, min(ts)

canon = lambda F: np.sort(np.array([np.roll(f, -int(np.argmin(f))) for f in F]).view("i4,i4,i4"), axis=0)
rows = []
decode(encode_mesh(random_planar_triangulation(100, seed=0)).words, structure="cds5n")   # numba warm-up
for n in sizes:
    mesh = random_planar_triangulation(n, seed=1)
    repeats = 3 if n <= 100_000 else 1
    enc, t_enc = best_of(lambda: encode_mesh(mesh), repeats)
    faces, t_dec = best_of(lambda: decode(enc.words, structure="faces"), repeats)
    _, t_dec5 = best_of(lambda: decode(enc.words, structure="cds5n"), repeats)
    if n <= 100_000:   # the decoded triangulation is the input one, up to the vertex numbering
        assert np.array_equal(canon(np.asarray(enc.order)[faces]), canon(mesh.faces))
    rows.append(dict(n=n, bits=enc.words.num_bits, bpv=enc.bits_per_vertex, bytes=enc.words.bits.nbytes,
                     enc=t_enc, wood=enc.wood_seconds, words=enc.words_seconds, dec=t_dec, dec5=t_dec5))

display(Markdown("| n | bits | bits / vertex | bytes | encode (of which: wood, words) | decode to faces | decode to CDS5n |\\n"
                 "|---:|---:|---:|---:|---:|---:|---:|\\n" +
                 "\\n".join(f"| {r['n']:,} | {r['bits']:,} | {r['bpv']:.4f} | {r['bytes']:,} | {r['enc']*1e3:.1f} ms "
                           f"({r['wood']*1e3:.1f}, {r['words']*1e3:.1f}) | {r['dec']*1e3:.1f} ms | {r['dec5']*1e3:.1f} ms |"
                           for r in rows)))'''),
    ("md", """\
For scale: a face list stores `2n` triangles of three 32-bit ints, **192 bits per vertex**; the
navigable structures hold 32-bit references (counts measured below on a 10,000-vertex mesh). The
code uses `4 - 3/n` bits per vertex, but is not navigable: decode it into a structure first."""),
    ("code", '''\
import jaxcds
m10k = random_planar_triangulation(10_000, seed=2)
refs = {name: jaxcds.build(name, m10k).references_per_vertex for name in ("halfedge", "corner-table", "cds5n", "lr")}
print({k: round(v, 2) for k, v in refs.items()}, "references per vertex")
ns = np.array([r["n"] for r in rows])
fig, axes = plt.subplots(1, 2, figsize=(12, 4))
ax = axes[0]
ax.plot(ns, [r["bpv"] for r in rows], "o-", label="4n-bit code (measured)")
ax.axhline(192, ls="--", color="tab:gray", label="face list, int32")
for (name, r), c in zip(refs.items(), ("tab:red", "tab:orange", "tab:green", "tab:purple")):
    ax.axhline(32 * r, ls=":", color=c, label=f"{name}, {r:.2f} refs x 32 bits")
ax.set_xscale("log"); ax.set_yscale("log"); ax.set_xlabel("vertices n"); ax.set_ylabel("bits per vertex")
ax.set_title("size"); ax.legend(fontsize=8); ax.grid(alpha=0.3, which="both")
ax = axes[1]
for key, lab in (("enc", "encode (wood + words)"), ("dec", "decode to faces"), ("dec5", "decode into CDS5n")):
    ax.plot(ns, [r["n"] / r[key] / 1e6 for r in rows], "o-", label=lab)
ax.set_xscale("log"); ax.set_yscale("log"); ax.set_xlabel("vertices n"); ax.set_ylabel("million vertices per second")
ax.set_title("throughput (a flat curve = linear time)"); ax.legend(fontsize=8); ax.grid(alpha=0.3, which="both")
plt.tight_layout(); plt.show()'''),
]

# ----------------------------------------------------------------------------------- 05 polylla
POLYLLA: List[Cell] = [
    ("md", """\
# 5. Polylla: polygonal meshes from a Delaunay triangulation

Polylla (Salinas-Fernández, Fuentes-Sepúlveda, Hitschfeld-Kahler, IMR 2023) merges the triangles
of a triangulation into polygons in three phases: **label** (each triangle's longest edge; an
edge that is the longest of neither of its triangles is a *frontier* edge), **traversal** (walk
the frontier edges of each terminal-edge region into one polygon) and **repair** (split
non-simple polygons at *barrier-edge tips*). `jaxcds.algorithms.polylla` runs the phases as
jitted array programs on any structure with borders: the array half-edge, or **pemb**, the
succinct planar embedding wrapped as a half-edge (Ferres et al., WADS 2017)."""),
    ("code", _PRELUDE + '''

from matplotlib.collections import LineCollection
from matplotlib.patches import Polygon
from jaxcds import polylla_io
from jaxcds.algorithms.polylla import build_structure, polygons_as_cycles, polylla, run'''),
    ("code", '''\
n_points = 300 if SMALL else 2000
rng = np.random.default_rng(4)
# half uniform, half clustered around two centres: polygons of very different sizes
pts = np.concatenate([rng.random((n_points // 2, 2)),
                      np.clip(0.5 + 0.12 * rng.standard_normal((n_points // 4, 2)) + [0.2, 0.1], 0, 1),
                      np.clip(0.5 + 0.05 * rng.standard_normal((n_points - 3 * (n_points // 4), 2)) - [0.2, 0.2], 0, 1)])
pts = np.unique(pts, axis=0)
tri = polylla_io.from_points(pts)
print(f"{tri.num_vertices} points, {tri.num_faces} Delaunay triangles")

results = {}
for structure in ("halfedge", "pemb"):
    s = build_structure(tri, structure)
    results[structure] = polylla(s, tri.points)
pm = results["halfedge"]
same = polygons_as_cycles(pm.polygons()) == polygons_as_cycles(results["pemb"].polygons())
print("half-edge and pemb give the same polygons:", same)
assert same
display(Markdown("| | " + " | ".join(pm.summary()) + " |\\n|---|" + "---:|" * len(pm.summary()) + "\\n| value | " +
                 " | ".join(f"{v:,}" for v in pm.summary().values()) + " |"))
# the two modes: canonical (above: order-free, every tip repaired) and reference (the
# reference implementation's own sequential walk and repair on the input's numbering; the
# default of run() and of `jaxcds polylla`)
ref = polylla(build_structure(tri, "halfedge"), tri.points, corners=tri.input_faces, mode="reference")
apart = set(polygons_as_cycles(ref.polygons())) ^ set(polygons_as_cycles(pm.polygons()))
print(f"reference mode: {ref.num_polygons} polygons, canonical mode: {pm.num_polygons}; "
      f"{len(apart)} polygons are in one output only")
print("summary from polylla.run (the `jaxcds polylla` command):", {k: v for k, v in run(pts).items() if k != "timings"})'''),
    ("code", '''\
polys = pm.polygons()
sizes = np.array([len(p) for p in polys])
P = tri.points
fig, axes = plt.subplots(1, 3, figsize=(17, 5.8), gridspec_kw=dict(width_ratios=[1, 1, 0.7]))
ax = axes[0]
ax.triplot(P[:, 0], P[:, 1], tri.faces, color="0.4", lw=0.5)
ax.plot(*P.T, ".", ms=2, color="k")
ax.set_title(f"Delaunay triangulation: {tri.num_faces} triangles")
ax = axes[1]
cmap = plt.cm.tab20
for i, p in enumerate(polys):
    ax.add_patch(Polygon(P[p], closed=True, fc=cmap(i % 20), ec="none", alpha=0.55))
ax.triplot(P[:, 0], P[:, 1], tri.faces, color="0.75", lw=0.3)
segs = [P[[p[j], p[(j + 1) % len(p)]]] for p in polys for j in range(len(p))]
ax.add_collection(LineCollection(segs, colors="k", lw=0.9))
ax.set_title(f"Polylla: {pm.num_polygons} polygons ({pm.barrier_edge_tips} barrier-edge tips, "
             f"{pm.repaired_polygons} repaired)")
for a in axes[:2]:
    a.set_aspect("equal"); a.set_xlim(-0.02, 1.02); a.set_ylim(-0.02, 1.02); a.set_axis_off()
ax = axes[2]
ax.hist(sizes, bins=np.arange(2.5, sizes.max() + 1.5), color="tab:blue")
ax.set_xlabel("vertices per polygon"); ax.set_ylabel("polygons"); ax.set_title("polygon sizes")
plt.tight_layout(); plt.show()
print(f"triangles per polygon: {tri.num_faces / pm.num_polygons:.2f}")'''),
]

# ----------------------------------------------------------------------------------- 06 benchmarks
BENCH: List[Cell] = [
    ("md", """\
# 6. Benchmarks: the plots behind `benchmarks/RESULTS.md`

`jaxcds bench` (`benchmarks/harness.py`) times every registered structure and the peers
(plain-JAX face list, a numba loop, trimesh, libigl when installed) and writes `RESULTS.md` with
PNG plots. This notebook reads the saved results (`benchmarks/*.json`, written by
`jaxcds bench --json > benchmarks/results.json`) when there are some, and otherwise runs the
harness itself at tiny sizes. Timings on a shared 2-core CPU are indicative only."""),
    ("code", _PRELUDE + '''

import glob, json, sys, tempfile
ROOT = os.path.abspath("..") if os.path.basename(os.getcwd()) == "notebooks" else os.getcwd()
sys.path.insert(0, ROOT)                       # `benchmarks` is a package at the repository root
from benchmarks import harness, report

saved = [] if SMALL else sorted(glob.glob(os.path.join(ROOT, "benchmarks", "*.json")))
res = None
for path in saved:
    with open(path) as fh:
        cand = json.load(fh)
    if isinstance(cand, dict) and {"timings", "memory", "meshes"} <= set(cand):
        res, source = cand, os.path.relpath(path, ROOT)
if res is None:
    # Structures with the scatter normals, targets and faces; then the peers (face list, numba) and the
    # face-list formulations in a second run, as `--ops` prefixes cannot keep the peers' `vertex_normals`
    # without the structures' slow `vertex_normals[gather]`. Every structure x op is one XLA compilation:
    # pemb and lr-bits (the slowest to compile) are left to `jaxcds bench`, and SMALL keeps two structures.
    mesh_spec = ["random:1000"] if SMALL else ["random:10000"]
    structs = ["halfedge", "cds5n"] if SMALL else ["halfedge", "corner-table", "cds6n", "cds5n", "cds4n", "cds5n-o1", "lr"]
    common = dict(repeats=3, queries=4096 if SMALL else 1 << 18, rss="inprocess", budget_s=2.0,
                  command="harness.run (notebook 06)")
    res = harness.run(mesh_spec, structures=structs, peers=[],
                      ops=["vertex_degrees", "vertex_normals[scatter]", "target", "face_left"], **common)
    peers = harness.run(mesh_spec, structures=[], peers=["plain-jax", "numba-loop"],
                        ops=["vertex_degrees", "vertex_normals"], **common)
    res["timings"] += [r for r in peers["timings"] if r["kind"] == "peer"]   # formulations: already in res
    res["summary"] = harness.summarize(res)
    source = f"harness.run({mesh_spec}) in this notebook"
print("results from:", source)
print("machine:", {k: res["machine"].get(k) for k in ("cpu", "cores", "jax") if k in res["machine"]})
print("meshes:", [(m["name"], m["vertices"]) for m in res["meshes"]])'''),
    ("md", "## The plots of `RESULTS.md` (`benchmarks.report.write_report`)"),
    ("code", '''\
from IPython.display import Image
out_dir = tempfile.mkdtemp(prefix="jaxcds-bench-")
written = report.write_report(res, out_dir)
for p in written:
    if p.endswith(".png"):
        print(os.path.basename(p)); display(Image(filename=p))'''),
    ("md", "## Time per vertex of normals and degrees, memory against time"),
    ("code", '''\
T = res["timings"]
meshes = [m["name"] for m in res["meshes"]]
mem = {}
for r in res["memory"]:
    mem.setdefault(r["structure"], r["references_per_vertex"])
fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
ax = axes[0]
impls = list(dict.fromkeys(r["impl"] for r in T if r["op"] in ("vertex_normals[scatter]", "vertex_normals")))
w = 0.8 / max(len(meshes), 1)
for j, name in enumerate(meshes):
    vals = [next((r["ns_per_item"] for r in T if r["mesh"] == name and r["impl"] == im
                  and r["op"] in ("vertex_normals[scatter]", "vertex_normals")), np.nan) for im in impls]
    ax.barh(np.arange(len(impls)) + j * w, vals, height=w, label=name)
ax.set_yticks(np.arange(len(impls)) + w * (len(meshes) - 1) / 2); ax.set_yticklabels(impls); ax.invert_yaxis()
ax.set_xscale("log"); ax.set_xlabel("vertex normals, ns per vertex (log)"); ax.legend(fontsize=8)
ax.set_title("normals: structures (scatter) and peers")
ax = axes[1]
name = meshes[-1]
for st, refs in mem.items():
    t = next((r["ns_per_item"] for r in T if r["mesh"] == name and r["impl"] == st and r["op"] == "target"), None)
    if t is not None:
        ax.scatter(refs, t, s=40); ax.annotate(st, (refs, t), xytext=(4, 3), textcoords="offset points", fontsize=9)
ax.set_xlabel("references per vertex"); ax.set_ylabel("Target, ns per query")
ax.set_title(f"memory vs Target time ({name})"); ax.grid(alpha=0.3)
plt.tight_layout()
display(fig); plt.close(fig)   # report.write_report switched matplotlib to Agg: display explicitly'''),
    ("code", '''\
display(Markdown(report.markdown(res)))'''),
]

# Last cell of every notebook: its cost (the machine is shared, so CPU time says more than wall time).
_FOOTER: Cell = ("code", '''\
print(f"CPU time of this kernel: {time.process_time():.1f} s (all threads; includes XLA compilation)")''')

NOTEBOOKS: Dict[str, List[Cell]] = {
    "01_tour": TOUR,
    "02_drawings": DRAWINGS,
    "03_differentiable": DIFF,
    "04_compression": COMPRESSION,
    "05_polylla": POLYLLA,
    "06_benchmarks": BENCH,
}


def make(name: str):
    """The notebook ``name`` (without outputs) as an ``nbformat`` node."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    for i, (kind, src) in enumerate(NOTEBOOKS[name] + [_FOOTER]):
        cell = nbformat.v4.new_markdown_cell(src) if kind == "md" else nbformat.v4.new_code_cell(src)
        cell["id"] = f"{name[:2]}-{i:02d}"   # stable ids: regenerating gives the same file
        nb.cells.append(cell)
    return nb


def execute(nb, timeout: int = 600, cwd: str = HERE):
    """Run ``nb`` top to bottom in a ``python3`` kernel of this interpreter (outputs kept).
    Raises ``nbclient.exceptions.CellExecutionError`` on the first failing cell."""
    from nbclient import NotebookClient

    NotebookClient(nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": cwd}}).execute()
    return nb


def source_cells(nb) -> List[Cell]:
    """``(kind, source)`` of every cell of a notebook node (to compare with :data:`NOTEBOOKS`)."""
    return [("md" if c.cell_type == "markdown" else "code", c.source) for c in nb.cells]


def main(argv=None) -> int:
    import nbformat

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("only", nargs="*", help="notebook name prefixes (default: all)")
    p.add_argument("--execute", action="store_true", help="run each notebook and keep the outputs")
    p.add_argument("--no-write", action="store_true", help="do not write the .ipynb files")
    p.add_argument("--out", default=HERE, help="directory of the .ipynb files (default: notebooks/)")
    a = p.parse_args(argv)
    names = [n for n in NOTEBOOKS if not a.only or any(n.startswith(o) for o in a.only)]
    for name in names:
        nb = make(name)
        if a.execute:
            t0 = time.perf_counter()
            execute(nb)
            print(f"{name}: executed in {time.perf_counter() - t0:.1f} s"
                  f"{' (JAXCDS_NB_SMALL=1)' if os.environ.get(SMALL_ENV) == '1' else ''}", flush=True)
        if not a.no_write:
            os.makedirs(a.out, exist_ok=True)
            path = os.path.join(a.out, name + ".ipynb")
            nbformat.write(nb, path)
            print("wrote", os.path.relpath(path), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
