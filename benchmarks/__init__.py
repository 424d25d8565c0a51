"""jaxcds benchmarks: ``python -m benchmarks`` (or ``jaxcds bench``) times every registered
structure and the peers; see :mod:`benchmarks.harness`. Results: ``benchmarks/RESULTS.md``."""
