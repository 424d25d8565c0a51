"""Clean exits for the benchmark scripts' bad arguments: the library's rule (a one-line message
naming the problem, exit status 2, as argparse's own errors) held for the scripts too.

A typo'd structure name or a mesh file that does not exist reaches the scripts as a typed
:class:`jaxcds.errors.JaxcdsError` from the registry or the mesh reader, and a zero round count
as an empty list of times (``statistics.median`` of nothing): both printed tracebacks before.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys

from jaxcds.errors import JaxcdsError


def at_least_one(text: str) -> int:
    """argparse type of a count that must be positive (``--rounds``, ``--repeat(s)``): a race of
    no rounds has no median, so 0 is refused before any mesh is built."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def clean_exit(main):
    """Wrap a script's ``main(argv)``: a :class:`JaxcdsError` (unknown structure, unreadable
    mesh, ...) becomes ``<script>: error: <message>`` on stderr and the return value 2."""

    @functools.wraps(main)
    def wrapped(argv=None):
        try:
            return main(argv)
        except JaxcdsError as exc:
            script = os.path.basename(sys.modules[main.__module__].__file__ or main.__module__)
            print(f"{script}: error: {exc}", file=sys.stderr)
            return 2

    return wrapped
