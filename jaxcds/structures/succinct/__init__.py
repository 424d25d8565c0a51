"""Succinct building blocks: bit vectors with rank/select and balanced parentheses with a range
min-max tree, as ``jnp`` pytrees whose queries are branch-free, batched and jittable.

These back :mod:`jaxcds.structures.pemb` (Ferres, Fuentes-Sepúlveda, Gagie, He, Navarro, *Fast
and Compact Planar Embeddings*, WADS 2017 / CGTA 2020), which stores a planar embedding in
``4m`` bits plus this support.
"""

from jaxcds.structures.succinct.bitvector import BLOCK_BITS, BitVector, pack_bits, popcount
from jaxcds.structures.succinct.bp import BalancedParens, excess_oracle

__all__ = ["BitVector", "BalancedParens", "BLOCK_BITS", "pack_bits", "popcount", "excess_oracle"]
