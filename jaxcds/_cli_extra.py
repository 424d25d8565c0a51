"""CLI sub-commands of the codec and Polylla modules (encode, decode, polylla)."""

from __future__ import annotations


def add_commands(sub) -> None:
    """Add the sub-commands whose modules are present (nothing for now)."""
    return None
