"""Concurrency through the Python package (issue 16, docs/reliability.md).

- The package loads liblacquer with ``ctypes.CDLL``, whose foreign calls release the GIL for
  their duration (``ctypes.PyDLL`` would keep it): tested below by a pure-Python thread that
  must make progress *while* one long batch call runs.
- 8 threads x N evaluations and N samples on shared materials, bit-identical to one thread;
  materials created and destroyed from 8 threads at once. N is LACQUER_THREADS_N (default
  200000, the CI size; the full size is 10000000, see docs/reliability.md).
"""

import os
import threading
import time

import numpy as np

import lacquer

N = int(os.environ.get("LACQUER_THREADS_N", "200000"))
CHUNK = 50_000
MATERIALS = [
    {"preset": "gold_flake_8"},
    {"preset": "solid_red"},
    {"model": "rough_conductor", "alpha_u": 0.05, "alpha_v": 0.2},
    {"model": "coated_paint"},
]


def _inputs(start, n):
    rng = np.random.default_rng(start)
    wi = rng.normal(size=(n, 3)).astype(np.float32)
    wo = rng.normal(size=(n, 3)).astype(np.float32)
    wi[:, 2] = np.abs(wi[:, 2]) + 0.05
    wo[:, 2] = np.abs(wo[:, 2]) + 0.05
    u = rng.random((n, 3), dtype=np.float32)
    return wi, wo, u


def _chunk_bytes(m, start, n):
    wi, wo, u = _inputs(start, n)
    f, p = m.eval_pdf(wi, wo)
    s = m.sample(wo, u)
    return f.tobytes() + p.tobytes() + s.wi.tobytes() + s.weight.tobytes() + s.pdf.tobytes()


def test_batch_calls_release_the_gil():
    # By construction: CDLL functions lack FUNCFLAG_PYTHONAPI, and ctypes then releases the GIL.
    import ctypes

    lib = lacquer._native.lib
    assert isinstance(lib, ctypes.CDLL) and not isinstance(lib, ctypes.PyDLL)
    assert lib.lq_eval._flags_ & ctypes._FUNCFLAG_PYTHONAPI == 0
    # By behaviour: a pure-Python thread keeps running during one long lq_eval call. Measured
    # on the 2-core CI machine (4e6 elements, ~0.6 s): largest gap between the thread's ticks
    # 0.05-0.06 of the call with CDLL; 0.93-0.94 with ctypes.PyDLL (GIL held). Bound: 0.5.
    m = lacquer.Material({"model": "coated_paint"})
    wi, wo, _ = _inputs(1, 4_000_000)
    lacquer.set_thread_count(1)  # one library thread: the other core is free for Python
    try:
        ticks = []
        stop = threading.Event()

        def spin():
            while not stop.is_set():
                ticks.append(time.perf_counter())

        t = threading.Thread(target=spin)
        t.start()
        time.sleep(0.05)
        t0 = time.perf_counter()
        m.eval(wi, wo)  # one ctypes call (lq_eval)
        t1 = time.perf_counter()
        stop.set()
        t.join()
    finally:
        lacquer.set_thread_count(0)
    inside = [t0] + [x for x in ticks if t0 < x < t1] + [t1]
    gap = max(b - a for a, b in zip(inside, inside[1:]))
    assert t1 - t0 > 0.05, f"call too short to tell ({t1 - t0:.3f} s)"
    assert gap < 0.5 * (t1 - t0), f"the Python thread stopped for {gap:.3f} s of a {t1 - t0:.3f} s call"


def test_eight_threads_on_shared_materials_match_one_thread():
    mats = [lacquer.Material(j) for j in MATERIALS]
    chunks = [(k, s, min(CHUNK, N - s)) for k, s in enumerate(range(0, N, CHUNK))]
    reference = [_chunk_bytes(mats[k % len(mats)], s, n) for k, s, n in chunks]
    mismatches = []

    def work(t):
        order = chunks[t:] + chunks[:t]  # threads work on different chunks at the same moment
        for k, s, n in order:
            if _chunk_bytes(mats[k % len(mats)], s, n) != reference[k]:
                mismatches.append((t, k))

    threads = [threading.Thread(target=work, args=(t,)) for t in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not mismatches, f"chunks differing from one thread (thread, chunk): {mismatches[:10]}"


def test_materials_created_and_destroyed_from_eight_threads():
    wi = np.array([[0.3, 0.2, 0.9]], np.float32)
    wo = np.array([[-0.4, 0.1, 0.8]], np.float32)
    expected = [lacquer.Material(j).eval(wi, wo).tobytes() for j in MATERIALS]
    errors = []

    def work(t):
        for r in range(40):
            k = (t + r) % len(MATERIALS)
            m = lacquer.Material(MATERIALS[k])
            if m.eval(wi, wo).tobytes() != expected[k]:
                errors.append((t, r, "value"))
            del m  # lq_material_free, while other threads create and evaluate
            try:
                lacquer.Material({"model": "lambert", "albedo": 7})
                errors.append((t, r, "no error"))
            except lacquer.InvalidMaterialError as e:
                if "albedo" not in str(e):  # the message of this thread's own call
                    errors.append((t, r, str(e)))

    threads = [threading.Thread(target=work, args=(t,)) for t in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors[:10]
