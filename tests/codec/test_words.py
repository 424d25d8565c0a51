"""The words of Sec. 3.1 / 3.3 on the paper's worked example (Fig. 9) and their error paths."""

import numpy as np
import pytest

from jaxcds import errors
from jaxcds.codec import words as W
from jaxcds.codec.decode import decode_faces, decode_paper6n, faces_from_paper6n

from codec_helpers import FIG9_BLACK, FIG9_MIXED, FIG9_RED_PLAIN, fig9


def test_fig9_lengths_and_degrees():
    w = fig9()
    assert FIG9_RED_PLAIN == "(()()()()((()()))())"
    assert w.num_vertices == 10 and w.num_bits == 4 * 10 - 3 == 37
    assert W.red_string(w) == FIG9_RED_PLAIN and W.black_string(w) == FIG9_BLACK
    # "the black word encodes the in-black-degrees ... 0,0,0,0,0,0,2,1,1,3"
    blocks = FIG9_BLACK.split("0")[:-1]
    assert [len(b) for b in blocks] == [0, 0, 0, 0, 0, 0, 2, 1, 1, 3]


def test_fig9_mixed_word_is_the_papers():
    w = fig9()
    assert W.mixed_string(w) == FIG9_MIXED
    m = W.to_mixed(w)
    assert m.mixed and W.to_separate(m) == w


def test_paper_undecorated_red_word_is_rejected():
    # the undecorated string has 11 vertices: its black word would need 19 bits
    with pytest.raises(errors.EncodingError, match="2n-3 = 19"):
        W.from_strings("(() () () () () ((() ())) ())", FIG9_BLACK)


def test_fig9_decodes_to_a_closed_triangulation():
    faces, table = decode_faces(fig9())
    n = 10
    assert faces.shape == (2 * n - 4, 3)
    # every dart exactly once, and its twin too: a closed oriented manifold
    darts = {(int(a), int(b)) for f in faces for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert len(darts) == 3 * len(faces)
    assert all((b, a) in darts for a, b in darts)
    assert n - len(darts) // 2 + len(faces) == 2
    # outer face (V_red, V_black, V_blue) and the trees of the paper's words
    assert {tuple(np.roll(f, -int(np.argmin(f)))) for f in faces} >= {(0, 9, 1)}
    T = table.T
    assert list(T[0]) == [10, 0, 0, 0, 0, 0, 5, 6, 6, 0]          # red parents (Fig. 9 red tree)
    assert np.bincount(T[2][T[2] < n], minlength=n).tolist() == [0, 0, 0, 0, 0, 0, 2, 1, 1, 3]
    # mixed word decodes to the same faces
    faces_m, _ = decode_faces(W.to_mixed(fig9()))
    assert np.array_equal(faces, faces_m)


@pytest.mark.parametrize("red,black,msg", [
    (")" + FIG9_RED_PLAIN[1:], FIG9_BLACK, "start with"),
    ("(()()()())(()()())()", FIG9_BLACK, "unbalanced"),           # the root closes at bit 9
    ("(()()()()((()()))(((", FIG9_BLACK, "more than n vertices"),  # never closes
    (FIG9_RED_PLAIN, "10000011010101110", "V_red and V_blue"),    # V_red with a black child
    (FIG9_RED_PLAIN, "00000111010101100", "wrong black count"),  # 3 black children for vertex 6: underflow
    (FIG9_RED_PLAIN, "00000011010101011", "black word"),          # unary block never ends
    ("(((()))()((()()))())", FIG9_BLACK, "V_blue must be"),      # V_blue has a red child
])
def test_invalid_words_raise_with_offsets(red, black, msg):
    w = W.from_strings(red, black)
    with pytest.raises(errors.EncodingError, match=msg) as exc:
        decode_faces(w)
    assert "bit" in str(exc.value) or "vertex" in str(exc.value)


def test_words_with_a_misshapen_buffer_are_refused():
    """Sweep: decode(Words(n, bits.reshape(1, -1))) raised numpy's ValueError; an int64 or
    float buffer was cut to bytes; n = -5 or 2**40 reached the decoder."""
    from jaxcds.codec import decode

    w = fig9()
    with pytest.raises(errors.EncodingError, match=r"bits must be a 1-d uint8 array .* = \(5,\) for n = 10; "
                                                   r"got dtype uint8, shape \(1, 5\)"):
        decode(W.Words(10, w.bits.reshape(1, -1)))
    for dtype in (np.int64, np.float64):
        with pytest.raises(errors.EncodingError, match=f"got dtype {np.dtype(dtype)}, shape \\(5,\\)"):
            W.Words(10, w.bits.astype(dtype))
    for n in (-5, 0, 2**31, 2**40):
        with pytest.raises(errors.EncodingError, match=f"num_vertices {n} out of range \\[1, 2147483647\\]"):
            W.Words(n, w.bits)
    with pytest.raises(errors.EncodingError, match="bits must be a 1-d uint8 array of packed bytes, got list"):
        W.Words(10, [[1], [1, 2]])
    assert decode(W.Words(10, list(w.bits))).shape == (16, 3)


@pytest.mark.parametrize("red,black,msg", [
    (FIG9_RED_PLAIN.replace("(", "[", 1), FIG9_BLACK, r"red word: symbol '\[' at bit 0 is not a parenthesis"),
    (FIG9_RED_PLAIN, "000001" + "2" + FIG9_BLACK[7:], r"black word: symbol '2' at bit 6 is not 0/1"),
    (FIG9_RED_PLAIN[:-1], FIG9_BLACK, r"red word: length 19 is not 2n"),
    ("(())", "0", r"red word: length 4 is not 2n for some n >= 3"),
])
def test_from_strings_names_the_bad_symbol_or_length(red, black, msg):
    with pytest.raises(errors.EncodingError, match=msg):
        W.from_strings(red, black)


@pytest.mark.parametrize("black,msg", [
    ("1" * 17, r"black word ends inside a unary block \(bit 17 of the black word\)"),
    # Fig. 9's 10 opening parentheses read one bit each: bits 10..16 are left over
    ("0" * 17, r"black word has 7 unused bits from bit 10 on .*read 10 of its 17 bits"),
])
def test_to_mixed_names_where_the_black_word_goes_wrong(black, msg):
    with pytest.raises(errors.EncodingError, match=msg):
        W.to_mixed(W.from_strings(FIG9_RED_PLAIN, black))


def _mixed(bits: str) -> W.Words:
    return W.Words((len(bits) + 3) // 4, W.pack(np.array([int(c) for c in bits], np.uint8)), mixed=True)


@pytest.mark.parametrize("bits,msg", [
    ("1" * 19 + "0" + "1" * 17, r"mixed word ends inside a black unary block \(bit 37\)"),
    ("1" * 37, r"more than 2n = 20 red symbols \(bit 20\)"),
    # 18 '(' each with an empty black block: the 18th block is past the 17 black bits
    ("0" * 37, r"black blocks run past the 2n - 3 = 17 bits of a black word \(bit 35\)"),
])
def test_to_separate_names_where_the_mixed_word_goes_wrong(bits, msg):
    """The third case said 'ends inside a black unary block' at bit 35 of 37: the word goes on;
    its black blocks are what is too long."""
    with pytest.raises(errors.EncodingError, match=msg):
        W.to_separate(_mixed(bits))


def _fig9_table_with(**arrays):
    from jaxcds.codec import Paper6n

    p = decode_paper6n(fig9())
    fields = {"S": p.S, "C": p.C, "I": p.I, "T": p.T}
    fields.update({k: f(fields[k]) for k, f in arrays.items()})
    return Paper6n(**fields)


def _set(index, value):
    def f(a):
        a = a.copy()
        a[index] = value
        return a
    return f


@pytest.mark.parametrize("table,error,msg", [
    (lambda: "S", errors.ArgumentError, "expected a Paper6n, got str"),
    (lambda: decode_paper6n(fig9(), targets=False),
     errors.ArgumentError, "needs a table decoded with targets=True"),
    (lambda: _fig9_table_with(S=lambda a: a[:, :, :3]), errors.EncodingError,
     r"must have shapes .* got \(3, 2, 3\), \(3, 2, 10\), \(3, 10\)"),
    (lambda: _fig9_table_with(S=lambda a: a.astype(float)), errors.EncodingError,
     "S and T must be integers and C booleans, got dtypes float64, bool"),
    (lambda: _fig9_table_with(S=_set((1, 0, 4), 10)), errors.EncodingError, r"S\[1, 0, 4\] = 10 is outside \[0, 9\]"),
    (lambda: _fig9_table_with(T=_set((2, 3), -1)), errors.EncodingError, r"T\[2, 3\] = -1 is outside \[0, 10\]"),
    (lambda: _fig9_table_with(T=np.zeros_like), errors.EncodingError,
     r"not a triangulation \(vertex 2, n = 10\)"),
    (lambda: _fig9_table_with(T=lambda a: np.full_like(a, 10)), errors.EncodingError,
     r"not a triangulation \(0 faces found, n = 10\)"),
])
def test_faces_from_paper6n_checks_a_table_it_did_not_decode(table, error, msg):
    with pytest.raises(error, match=msg):
        faces_from_paper6n(table())


@pytest.mark.parametrize("n,num_bytes,msg", [
    (3, 2, "a triangulation needs n >= 4 vertices, got n = 3"),
    (10, 3, r"word buffer holds 3 bytes, 5 needed for 4n-3 = 37 bits"),
])
def test_decode_refuses_words_too_small_for_a_triangulation(n, num_bytes, msg):
    from jaxcds.codec import decode

    with pytest.raises(errors.EncodingError, match=msg):
        decode(W.Words(n, np.zeros(num_bytes, np.uint8)))
