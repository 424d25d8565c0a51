"""The 4n-bit compressed format of Castelli Aleardi & Devillers (CDS paper, Sec. 3).

Public API:
  * words (:mod:`jaxcds.codec.words`): :class:`Words`, :func:`from_strings`, :func:`to_mixed`,
    :func:`to_separate`, :func:`red_string`, :func:`black_string`, :func:`mixed_string`.
  * encoding (Sec. 3.1): :func:`encode_mesh` (-> :class:`EncodedMesh`), :func:`encode_faces`
    (faces -> words, Schnyder wood included, no validation), :func:`encode_schnyder`,
    :func:`encode_wood`.
  * decoding (Sec. 3.2, Fig. 10-12): :func:`decode`, :func:`decode_faces`, :func:`decode_paper6n`.
  * files (``docs/cds-format.md``): :func:`write_cds`, :func:`read_cds`, :func:`cds_info`,
    :func:`encode_file`, :func:`decode_file`, :func:`write_mesh_atomic`.
"""

from jaxcds.codec.words import (Words, black_string, from_strings, mixed_string, num_bits,
                                red_string, to_mixed, to_separate)
from jaxcds.codec.decode import Paper6n, decode_faces, decode_paper6n, faces_from_paper6n
from jaxcds.codec.encode import dart_twins, encode_faces, encode_schnyder, encode_wood
from jaxcds.codec.api import (EncodedMesh, cds_info, decode, decode_file, encode_file, encode_mesh,
                              read_cds, write_cds, write_mesh_atomic)

__all__ = [
    "Words", "black_string", "from_strings", "mixed_string", "num_bits", "red_string",
    "to_mixed", "to_separate",
    "Paper6n", "decode_faces", "decode_paper6n", "faces_from_paper6n",
    "dart_twins", "encode_faces", "encode_schnyder", "encode_wood",
    "EncodedMesh", "cds_info", "decode", "decode_file", "encode_file", "encode_mesh", "read_cds",
    "write_cds", "write_mesh_atomic",
]
