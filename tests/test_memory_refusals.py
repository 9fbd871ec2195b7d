"""Constructors refuse what cannot fit, before allocating (jaxmdp._memory).

One subprocess runs every refusal: each family's ``make`` at a size far beyond memory, ``custom_mdp``, ``stack``,
``pad``, ``emission_table`` and ``block_mdp``. It caps its own address space (``RLIMIT_AS``: 2 GiB above what the
import holds, then 1 GiB above what its set-up holds) and stops a case after 20 s, so that a constructor that failed
to refuse fails there (``MemoryError``, ``TimeoutError``) instead of taking the machine's memory. Every refusal must
be a ``ValueError`` naming the sizes, the bytes needed and the bytes available, raised within a second, with the
process's peak resident memory under 1 GiB. The same process measures the peak of one real construction against its
estimate. In-process tests check that the estimates bound the arrays actually built (so a check cannot be a
constant) and that ordinary sizes pass. The child also has the measures of many MDPs refuse their compiled program.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import jaxmdp
from conftest import REPO
from jaxmdp import _memory
from jaxmdp.batching import stack_bytes
from jaxmdp.blockmdp.emission_maps import emission_bytes
from jaxmdp.mdp import custom_dense_bytes, mdp_array_bytes
from jaxmdp.mdp_families import BUILTIN_FAMILIES
from jaxmdp.mdp_families import construction

GiB = 2**30

#: Every built-in family at a size far beyond any machine's memory, with the parameter the message must name.
FAR_BEYOND = {
    "DeepSea": (dict(size=100_000), "size=100000"),
    "RiverSwim": (dict(size=10**7), "size=10000000"),
    "SimpleGrid": (dict(size=10**4), "size=10000"),
    "FrozenLake": (dict(size=10**4, p_frozen=0.8), "size=10000"),
    "MiniGridEmpty": (dict(size=10**4), "size=10000"),
    "MiniGridRooms": (dict(room_size=10**3, n_rooms=9), "room_size=1000"),
    "MiniGridDoorKey": (dict(size=10**4), "size=10000"),
    "Taxi": (dict(size=10**3, n_locations=4), "size=1000"),
}

_CHILD = textwrap.dedent(
    """
    import json, os, resource, signal, sys, time
    t0 = time.perf_counter()
    import numpy as np
    import jaxmdp
    from jaxmdp import _memory
    from jaxmdp.mdp_families import construction

    out = {"import_s": time.perf_counter() - t0, "cases": {}}
    far = json.loads(sys.argv[1])

    # Peak resident memory is the address space's high-water mark (VmHWM), not getrusage's ru_maxrss: Linux carries
    # ru_maxrss across exec, so a child started from a large pytest worker would report the worker's peak.
    def status(key):
        for line in open("/proc/self/status"):
            k, _, v = line.partition(":")
            if k == key:
                return int(v.split()[0]) * 1024

    def cap(headroom):
        # A constructor that does not refuse dies of MemoryError here instead of taking the machine's memory.
        limit = status("VmSize") + headroom
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))

    cap(2 * 2**30)  # room for the backend to start (its threads reserve address space) and the set-up below

    def too_long(signum, frame):
        raise TimeoutError("still running after 20 s")

    signal.signal(signal.SIGALRM, too_long)

    def attempt(name, fn):
        t = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, 20.0)  # a construction that does not refuse may crawl rather than fail
        try:
            fn()
        except Exception as e:
            out["cases"][name] = dict(
                type=type(e).__name__, value_error=isinstance(e, ValueError), message=str(e)[:2000],
                needed=getattr(e, "needed", None), available=getattr(e, "available", None),
                seconds=time.perf_counter() - t)
        else:
            out["cases"][name] = dict(type=None, seconds=time.perf_counter() - t)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)

    # The issue's case, first thing in a fresh process (the backend starts inside the call).
    attempt("first make DeepSea", lambda: jaxmdp.make("DeepSea", episodic=True, seed=0, size=100000))
    out["first_s"] = time.perf_counter() - t0

    # One real construction: its peak resident memory against its estimate.
    need = {}
    check = construction.Family.check_memory
    def spy(self):
        need["bytes"] = construction.construction_bytes(self.max_states(), self.n_actions)
        return check(self)
    construction.Family.check_memory = spy
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current resident size: the peak below is this construction's
    before = status("VmRSS")
    deep = jaxmdp.make("DeepSea", episodic=True, seed=0, size=45)
    out["calibration"] = dict(peak=status("VmHWM") - before,
                              estimate=need["bytes"])
    construction.Family.check_memory = check

    small = jaxmdp.make("DeepSea", episodic=False, seed=0, size=10)
    long = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=200, H=10**6)

    # The measures of many MDPs compile first (under the first cap: compiling needs room), then check the program:
    # with a billion steps its [H, S] arrays need hundreds of GiB while the MDP and its stack are small.
    import hardness
    longer = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=50, H=10**9)
    attempt("measures_many", lambda: hardness.measures_many([longer]))

    cap(2**30)
    out["available_under_cap"] = _memory.host_available_bytes()

    for name, params in far.items():
        attempt(f"make {name}", lambda: jaxmdp.make(name, episodic=True, seed=0, **params))
    S = 10**5
    huge_T = np.broadcast_to(np.float32(1.0 / S), (S, 4, S))  # a view: the input itself costs nothing
    attempt("custom_mdp", lambda: jaxmdp.custom_mdp(huge_T, np.zeros((S, 4))))
    S = 3000
    given_T = np.broadcast_to(np.float32(1.0 / S), (S, 4, S))
    attempt("custom_mdp derived arrays", lambda: jaxmdp.custom_mdp(given_T, np.zeros((S, 4))))
    attempt("stack", lambda: jaxmdp.stack([deep] * 10**4))
    attempt("pad", lambda: jaxmdp.pad(small, 10**5, 2, 1))
    attempt("emission_table", lambda: jaxmdp.emission_table(long, "one_hot"))
    attempt("block_mdp", lambda: jaxmdp.block_mdp(long, "one_hot"))
    # Ordinary sizes still build under the cap.
    attempt("ok make", lambda: jaxmdp.make("MiniGridEmpty", episodic=True, seed=0, size=6))
    attempt("ok stack", lambda: jaxmdp.stack([small, small]))
    attempt("ok emission_table", lambda: jaxmdp.emission_table(small, "one_hot"))
    out["maxrss"] = status("VmHWM")
    print(json.dumps(out), flush=True)
    # Leave without the interpreter's teardown: under the address-space cap, a backend thread that allocates while
    # shutting down can crash the process after its results are out (seen as SIGSEGV on a loaded machine).
    os._exit(0)
    """
)

REFUSALS = {
    "first make DeepSea": "size=100000",
    **{f"make {name}": named for name, (_, named) in FAR_BEYOND.items()},
    "custom_mdp": "S=100000",
    "custom_mdp derived arrays": "S=3000",
    "stack": "members=10000",
    "pad": "S=100000",
    "emission_table": "H=1000000",
    "block_mdp": "H=1000000",
}


@pytest.fixture(scope="module")
def child() -> dict:
    far = {name: params for name, (params, _) in FAR_BEYOND.items()}
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, json.dumps(far)], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_every_built_in_family_is_covered():
    assert set(FAR_BEYOND) == set(BUILTIN_FAMILIES)


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_refused_before_allocating_with_a_clear_message(child, case):
    r = child["cases"][case]
    assert r["type"] == "NotEnoughMemory" and r["value_error"], r
    assert r["seconds"] < 1.0, r
    message = r["message"]
    assert REFUSALS[case] in message, message
    assert r["needed"] > r["available"] > 0
    assert f"({r['needed']} bytes)" in message and f"({r['available']} bytes) is available" in message, message
    assert "machine with more memory" in message, message


def test_measures_many_checks_its_compiled_program_before_running_it(child):
    r = child["cases"]["measures_many"]
    assert r["type"] == "NotEnoughMemory", r
    assert "hardness.measures_many with members=1, S=50, A=2, H=1000000000" in r["message"]
    assert r["needed"] > r["available"]


def test_the_issue_case_raises_within_a_second_of_a_fresh_process_under_1_gib(child):
    assert child["cases"]["first make DeepSea"]["seconds"] < 1.0
    assert child["maxrss"] < GiB


def test_ordinary_sizes_build_under_the_cap(child):
    for case in ("ok make", "ok stack", "ok emission_table"):
        assert child["cases"][case]["type"] is None, child["cases"][case]
    # The address-space limit counts as memory available.
    assert child["available_under_cap"] <= GiB


def test_the_make_estimate_tracks_the_real_peak(child):
    # DeepSea size=45: 1035 states, 2 actions; the estimate is the peak of the dense arrays, not a constant or a
    # multiple of it.
    peak, estimate = child["calibration"]["peak"], child["calibration"]["estimate"]
    assert 0 < peak <= 1.25 * estimate
    assert estimate <= 3 * peak


def _nbytes(tree) -> int:
    return sum(x.nbytes for x in jax.tree.leaves(tree))


SMALL = {
    "DeepSea": [dict(size=6), dict(size=12)],
    "RiverSwim": [dict(size=5), dict(size=11)],
    "SimpleGrid": [dict(size=4), dict(size=7)],
    "FrozenLake": [dict(size=4, p_frozen=0.8), dict(size=6, p_frozen=0.8)],
    "MiniGridEmpty": [dict(size=4), dict(size=6)],
    "MiniGridRooms": [dict(room_size=3, n_rooms=4), dict(room_size=4, n_rooms=4)],
    "MiniGridDoorKey": [dict(size=4), dict(size=6)],
    "Taxi": [dict(size=5, n_locations=3), dict(size=7, n_locations=4)],
}


def test_family_estimates_bound_the_states_and_the_arrays(monkeypatch):
    assert set(SMALL) == set(BUILTIN_FAMILIES)
    seen = []
    check = construction.Family.check_memory

    def spy(self):
        seen.append((self.max_states(), construction.construction_bytes(self.max_states(), self.n_actions)))
        return check(self)

    monkeypatch.setattr(construction.Family, "check_memory", spy)
    for name, sizes in SMALL.items():
        estimates = []
        for episodic in (False, True):
            for params in sizes:
                seen.clear()
                mdp = jaxmdp.make(name, episodic=episodic, seed=1, **params)
                assert seen, f"{name} never checked its memory"
                S_max, estimate = seen[0]
                assert mdp.n_states <= S_max, (name, params)
                assert estimate >= _nbytes(mdp), (name, params)
                estimates.append(estimate)
        assert estimates[1] > estimates[0], name  # grows with the size: not a constant


def test_custom_stack_and_emission_estimates_bound_the_arrays():
    rng = np.random.default_rng(0)
    for S, A in ((2, 1), (7, 3), (20, 4)):
        T = rng.random((S, A, S))
        T /= T.sum(-1, keepdims=True)
        for dtype in (np.float32, np.float16):
            mdp = jaxmdp.custom_mdp(T, rng.random((S, A)), dtype=dtype)
            b = np.dtype(dtype).itemsize
            assert custom_dense_bytes(S, A, b) >= _nbytes(mdp) - mdp.succ.nbytes - mdp.succ_p.nbytes
            assert mdp_array_bytes(S, A, mdp.max_successors, b) >= _nbytes(mdp)
    small = jaxmdp.make("DeepSea", episodic=True, seed=0, size=5)
    big = jaxmdp.make("DeepSea", episodic=True, seed=0, size=8)
    batch = jaxmdp.stack([small, big, small])
    S, A, K = batch.n_states, batch.n_actions, batch.max_successors
    assert stack_bytes(3, S, A, K, 4, batch.max_starts) >= _nbytes(batch)
    assert stack_bytes(3, S, A, K, 4) > stack_bytes(2, S, A, K, 4) > stack_bytes(2, S - 1, A, K, 4)
    for kind in ("one_hot", "state_info", "image", "tensor"):
        for mdp in (small, big, jaxmdp.make("DeepSea", episodic=False, seed=0, size=6)):
            table = jaxmdp.emission_table(mdp, kind)
            assert emission_bytes(mdp, kind) >= table.nbytes, kind


def test_check_memory_names_the_sizes_the_bytes_and_the_remedy():
    _memory.check_memory(100, "thing", {"size": 3}, available=100)  # fits exactly
    with pytest.raises(_memory.NotEnoughMemory) as err:
        _memory.check_memory(101, "thing", {"size": 3}, detail="9 states", available=100, remedy="try less")
    assert str(err.value) == (
        "thing with size=3 (9 states) needs about 101 bytes (101 bytes) of host memory but 100 bytes (100 bytes) is "
        "available; try less"
    )
    assert isinstance(err.value, ValueError) and isinstance(err.value, MemoryError)
    assert (err.value.needed, err.value.available) == (101, 100)
    assert jaxmdp.NotEnoughMemory is _memory.NotEnoughMemory
    assert _memory.format_bytes(3 * 2**30 // 2) == "1.50 GiB"


def test_an_accelerator_compares_the_device_part_with_its_free_bytes(monkeypatch):
    class Device:
        platform = "gpu"

        def memory_stats(self):
            return {"bytes_limit": 1000, "bytes_in_use": 100}

    monkeypatch.setattr(_memory, "_default_device", Device)
    monkeypatch.setattr(_memory, "host_available_bytes", lambda: 1500)
    _memory.check_memory(2000, "thing", device_bytes=900)  # host part 1100 <= 1500, device part 900 <= 900
    with pytest.raises(_memory.NotEnoughMemory, match=r"needs about 901 bytes .* of gpu device memory but 900") as err:
        _memory.check_memory(2000, "thing", device_bytes=901)
    assert err.value.where == "gpu"
    with pytest.raises(_memory.NotEnoughMemory, match="of host memory") as err:
        _memory.check_memory(2000, "thing", device_bytes=499)  # host part 1501 > 1500
    assert err.value.where == "host"


def test_host_available_bytes_is_positive_and_below_physical_memory():
    import os

    avail = _memory.host_available_bytes()
    assert avail is not None and 0 < avail <= os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")

