"""Eager pemb operators over many batch sizes: time and memory held (stop 43).

    PYTHONPATH=. python benchmarks/probe_eager_pemb.py            # as shipped: jitted buckets
    OFF=1 PYTHONPATH=. python benchmarks/probe_eager_pemb.py      # eager, every primitive per size
    NOJIT=1 PYTHONPATH=. python benchmarks/probe_eager_pemb.py    # padded buckets, run eagerly

Two rounds of 16 eager calls (Target and Face_left) of new random sizes in [100, 5000) on a
2,000-vertex random pemb, then a warm call of a size seen before; RSS growth from after the
first call. Stop 43, Zen 3 host: OFF 113 s / 88 s, +3.2 GB, warm 4.2 s; NOJIT 76 / 72 s, +2.1
GB, warm 6.8 s; shipped 91 / 7.2 s, +0.8 GB, warm 41 ms (benchmarks/RESULTS.md, "stop 43").
"""
import os, time, numpy as np, jax
from jaxcds.generators import random_planar_triangulation
from jaxcds.structures import registry, base
if os.environ.get("NOJIT"):
    def _b(run, structure, ids):
        shape = ids[0].shape; size = int(np.prod(shape)); cap = 1 << (size - 1).bit_length()
        padded = [base.to_device(np.concatenate([np.asarray(x).reshape(-1), np.full(cap - size, np.asarray(x).reshape(-1)[0], np.int32)])) for x in ids]
        return run.__wrapped__(structure, *padded)[:size].reshape(shape)
    base._bucketed = _b
if os.environ.get("OFF"):
    base._eager = lambda s, ids: False
m = random_planar_triangulation(2000, seed=0)
s = registry.build("pemb", m)
rng = np.random.default_rng(0)
def rss(): return int(open('/proc/self/statm').read().split()[1]) * 4096 / 2**20
s.target(np.arange(10)); r0 = rss()
for rnd in range(2):
    t0 = time.perf_counter()
    for k in range(8):
        n = int(rng.integers(100, 5000))
        a = np.asarray(s.target(rng.integers(0, s.num_darts, n)))
        b = np.asarray(s.face_left(rng.integers(0, s.num_darts, n)))
    print(f"round {rnd}: 16 eager calls of new sizes: {time.perf_counter()-t0:.1f} s, RSS +{rss()-r0:.0f} MiB", flush=True)
t0 = time.perf_counter(); e = rng.integers(0, s.num_darts, 3000)
for k in range(5): np.asarray(s.target(e))
print(f"warm same-size call: {(time.perf_counter()-t0)/5*1e3:.1f} ms")
