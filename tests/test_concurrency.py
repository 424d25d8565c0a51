"""jaxcds inside a concurrent program: process-wide state that a call changes for a moment (the
warning filters, the umask) must come back as it was however the calls of several threads
interleave (sweep 55a)."""

from __future__ import annotations

import os
import stat
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from jaxcds.codec import fileformat as ff
from jaxcds import mesh as mesh_module

THREADS = 4


def _together(fn, count: int, timeout: float = 60.0) -> list:
    """``fn(i)`` for ``i < count`` on :data:`THREADS` threads that start at one barrier; the
    results in order (a hung call fails the test instead of hanging it)."""
    start = threading.Barrier(THREADS, timeout=timeout)

    def first(i):
        if i < THREADS:
            start.wait()
        return fn(i)

    with ThreadPoolExecutor(THREADS) as pool:
        futures = [pool.submit(first, i) for i in range(count)]
        return [f.result(timeout=timeout) for f in futures]


def test_parsing_numbers_from_threads_leaves_the_warning_filters_as_they_were(monkeypatch):
    # the OFF / OBJ face lines and Polylla's Triangle files are parsed by _plain_numbers, under
    # catch_warnings + simplefilter("error"): one list of filters per process, saved and
    # restored by each call, so interleaved calls left "error" installed for good (every later
    # warning of the program raised). A widened window: numpy's parser sleeps first, as a
    # thread parsing a large file would be switched out
    real_fromstring = np.fromstring

    def slow_fromstring(*args, **kwargs):
        time.sleep(0.002)
        return real_fromstring(*args, **kwargs)

    monkeypatch.setattr(np, "fromstring", slow_fromstring)
    good, bad = "1 2 3 " * 100, "1 2 3 " * 100 + "x 5"
    before = list(warnings.filters)

    def parse(i):
        try:
            return mesh_module._plain_numbers(bad if i % 2 else good, float).size
        except ValueError:
            return "refused"

    got = _together(parse, 100)
    assert list(warnings.filters) == before
    assert got == [("refused" if i % 2 else 300) for i in range(100)]


def test_new_files_from_threads_keep_the_umask(tmp_path, monkeypatch):
    # the mode of a new output file is 0666 & ~umask; reading the umask by setting it to 0 and
    # back, from two threads at once, left the process with umask 0 (a widened window: os.umask
    # sleeps after each change, as a busy thread would be switched out)
    real_umask = os.umask

    def slow_umask(mask):
        old = real_umask(mask)
        time.sleep(0.02)
        return old

    previous = real_umask(0o022)
    try:
        monkeypatch.setattr(os, "umask", slow_umask)
        _together(lambda i: ff.atomic_write_bytes(tmp_path / f"out{i}.cds", b"data"), THREADS)
        monkeypatch.setattr(os, "umask", real_umask)
        assert real_umask(0o022) == 0o022
        for i in range(THREADS):
            assert stat.S_IMODE(os.stat(tmp_path / f"out{i}.cds").st_mode) == 0o644
    finally:
        real_umask(previous)


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="Linux /proc only")
def test_the_umask_is_read_without_changing_it(monkeypatch):
    previous = os.umask(0o027)
    try:
        monkeypatch.setattr(os, "umask", lambda mask: pytest.fail("os.umask changed the umask"))
        assert ff._current_umask() == 0o027
    finally:
        monkeypatch.undo()
        os.umask(previous)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cds5n", "lr"])
def test_eager_and_jitted_operators_from_threads_answer_as_one_thread(name):
    # eager calls of these classes run bucketed (base._bucketed: one jitted program per power of
    # two, made on first use and kept on the operator's wrapper), so the threads race to make and
    # compile the same programs, while one more thread clears JAX's caches under them (a guard:
    # this passed when written, sweep 55a)
    import jax

    from jaxcds.generators import icosphere
    from jaxcds.structures import registry

    s = registry.build(name, icosphere(1))
    darts = s.all_darts()
    ops = ("next", "target", "face", "right_front")
    batches = [darts[(np.arange(3 + 5 * i) * 7 + i) % len(darts)] for i in range(8)]
    stop = threading.Event()

    def clear():
        while not stop.wait(0.5):
            jax.clear_caches()

    def ask(i):
        ids = batches[i % len(batches)]
        op = ops[i % len(ops)]
        eager = np.asarray(getattr(s, op)(ids))
        jitted = np.asarray(jax.jit(lambda t, d: getattr(t, op)(d))(s, ids))
        return eager, jitted

    clearer = threading.Thread(target=clear, daemon=True)
    clearer.start()
    try:
        got = _together(ask, 16, timeout=300)
    finally:
        stop.set()
        clearer.join(10)
    for i, (eager, jitted) in enumerate(got):
        want = np.asarray(jax.jit(lambda t, d: getattr(t, ops[i % len(ops)])(d))(s, batches[i % len(batches)]))
        assert np.array_equal(eager, want) and np.array_equal(jitted, want), (i, ops[i % len(ops)])
