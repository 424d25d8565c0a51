"""Shared helpers of the codec tests: random valid words, face canonical forms, brute-force
Thm 2 table."""

from __future__ import annotations

import numpy as np

from jaxcds.codec import words as W


def random_words(n: int, rng: np.random.Generator) -> W.Words:
    """Random words that pass the stack conditions of the decoder (Fig. 10, 11): a random red
    tree with V_blue = 1 its first and V_black = n-1 its last leaf child of the root, and black
    in-degrees drawn among the open black subtrees (V_black takes all that remain)."""
    m = n - 3  # vertices 2 .. n-2
    seq, opens, closes = [], 0, 0
    while opens < m or closes < m:
        if opens < m and (opens == closes or rng.random() < 0.5):
            seq.append(0)
            opens += 1
        else:
            seq.append(1)
            closes += 1
    red = [0, 0, 1] + seq + [0, 1, 1]
    deg, stack, vid, open_black = [], [], -1, 0
    for s in red:
        if s == 0:
            vid += 1
            stack.append(vid)
            if vid <= 1:
                d = 0
            elif vid == n - 1:
                d = open_black
            else:
                d = int(rng.integers(0, open_black + 1))
            open_black -= d
            deg.append(d)
        else:
            u = stack.pop()
            if u > 1:
                open_black += 1
    black = []
    for d in deg:
        black += [1] * d + [0]
    return W.Words(n, W.pack(np.array(red + black, dtype=np.uint8)))


def canon_faces(faces) -> list:
    """Faces as sorted tuples rotated to start at their smallest vertex (orientation kept)."""
    f = np.asarray(faces, dtype=np.int64)
    k = np.argmin(f, axis=1)
    rows = np.arange(f.shape[0])
    g = np.stack([f[rows, k], f[rows, (k + 1) % 3], f[rows, (k + 2) % 3]], axis=1)
    return sorted(map(tuple, g.tolist()))


def is_closed_sphere(faces, n: int) -> bool:
    darts = {}
    for a, b, c in np.asarray(faces).tolist():
        for x, y in ((a, b), (b, c), (c, a)):
            if (x, y) in darts or x == y:
                return False
            darts[(x, y)] = True
    if any((y, x) not in darts for (x, y) in darts):
        return False
    used = {x for (x, _) in darts}
    return len(used) == n and n - len(darts) // 2 + len(faces) == 2


def brute_table(faces, T, n):
    """The Thm 2 table (S, C, I) from its definitions (Sec. 2.1), given faces and targets."""
    third = {}
    for a, b, c in np.asarray(faces).tolist():
        third[(a, b)] = c
        third[(b, c)] = a
        third[(c, a)] = b

    def edge(a, b):  # (source, colour) of the edge {a, b}
        for c in range(3):
            if T[c, a] == b:
                return a, c
            if T[c, b] == a:
                return b, c
        raise AssertionError(f"edge {a}-{b} has no colour")

    S = np.zeros((3, 2, n), np.int64)
    C = np.zeros((3, 2, n), bool)
    I = np.zeros((3, n), bool)
    for c in range(3):
        for u in range(n):
            v = int(T[c, u])
            if v >= n:
                continue
            I[c, v] = True
            w = third[(u, v)]          # left face (u, v, w): LeftFront = {v, w}
            s, col = edge(v, w)
            S[c, 0, u], C[c, 0, u] = s, col == c
            z = third[(v, u)]          # right face (v, u, z): RightFront = {v, z}
            s, col = edge(v, z)
            S[c, 1, u], C[c, 1, u] = s, col == c
    return S, C, I


# Fig. 9 / Sec. 3.1. The paper prints the red word twice: undecorated as
# "(() () () () () ((() ())) ())" (22 symbols: 11 vertices, a typo) and decorated with vertex
# indices "(0 (1)1 (2)2 (3)3 (4)4 (5 (6 (7)7 (8)8 )6 )5 (9)9 )0" (20 symbols, n = 10). The
# 17-bit black word (2n - 3 = 17) and the mixed word of Sec. 3.3 both agree with n = 10.
FIG9_RED = "(0 (1)1 (2)2 (3)3 (4)4 (5 (6 (7)7 (8)8 )6 )5 (9)9 )0"
FIG9_RED_PLAIN = "".join(c for c in FIG9_RED if c in "()")
FIG9_BLACK = "00000011010101110"
# Sec. 3.3, subscripts dropped: 0_0 0_0 0_1 0_1 1_1 0_2 0_2 1_2 ... 0_9 1110_9 1_9 1_0
FIG9_MIXED = ("0 0 0 0 1 0 0 1 0 0 1 0 0 1 0 0 0 110 0 10 1 0 10 1 1 1 0 1110 1 1").replace(" ", "")


def fig9() -> W.Words:
    return W.from_strings(FIG9_RED_PLAIN, FIG9_BLACK)
