"""The 4n-bit compressed format of Castelli Aleardi & Devillers (CDS paper, Sec. 3).

Public API:
  * :class:`Words` and word helpers (:mod:`jaxcds.codec.words`): red/black words, mixed word.
  * :func:`decode_paper6n`, :func:`decode_faces` (:mod:`jaxcds.codec.decode`): linear-time
    decoding (Sec. 3.2, Fig. 10-12).
"""

from jaxcds.codec.words import (Words, black_string, from_strings, mixed_string, num_bits,
                                red_string, to_mixed, to_separate)
from jaxcds.codec.decode import Paper6n, decode_faces, decode_paper6n, faces_from_paper6n

__all__ = [
    "Words", "black_string", "from_strings", "mixed_string", "num_bits", "red_string",
    "to_mixed", "to_separate",
    "Paper6n", "decode_faces", "decode_paper6n", "faces_from_paper6n",
]
