"""Linear-time (numba) builders: Schnyder woods (CDS paper, Appendix A) and friends."""

from jaxcds.construct.schnyder import (BLACK, BLUE, RED, SchnyderWood, check_schnyder_wood,
                                       schnyder_wood)

__all__ = ["SchnyderWood", "schnyder_wood", "check_schnyder_wood", "RED", "BLUE", "BLACK"]
