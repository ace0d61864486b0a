"""SimulatorBatch: one parallel numba call gives exactly the single-simulator results."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys

import numpy as np
import pytest

from drill_env.physics.batch import SimulatorBatch
from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.layout import READ, Status
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM


def make(length: float, rpm: float) -> Simulator:
    sim = Simulator(replace(SimulationConfig(), **{"string.drill_pipe.length": length}))
    sim.reset(OperatingPoint(rpm * RPM, 60e3))
    return sim


def drive(sims, batch, rounds: int, active=None):
    out = []
    for k in range(rounds):
        speeds = [(50.0 + 10 * i + k) * RPM for i in range(len(sims))]
        hooks = [sim.hook_load_for(60e3 + 1e3 * k) for sim in sims]
        if batch is None:
            out.append([sim.advance(50, w, h, 10) if (active is None or active[i]) else
                        np.zeros((0, 16)) for i, (sim, w, h) in
                        enumerate(zip(sims, speeds, hooks, strict=True))])
        else:
            out.append(batch.advance(sims, [50] * len(sims), speeds, hooks, [10] * len(sims),
                                     active))
    return out


def test_batch_is_bit_identical_to_one_by_one_with_different_meshes_and_inactive_slots():
    lengths = (500.0, 1000.0, 1500.0, 800.0)
    active = [True, False, True, True]
    alone = [make(length, 60.0) for length in lengths]
    together = [make(length, 60.0) for length in lengths]
    batch = SimulatorBatch(len(together))
    expected = drive(alone, None, 4, active)
    actual = drive(together, batch, 4, active)
    for rows_a, rows_e in zip(actual, expected, strict=True):
        for a, e in zip(rows_a, rows_e, strict=True):
            np.testing.assert_array_equal(a, e)
    for a, e in zip(together, alone, strict=True):
        np.testing.assert_array_equal(a.state, e.state)
        np.testing.assert_array_equal(a.ul, e.ul)
        np.testing.assert_array_equal(a.vt, e.vt)
        np.testing.assert_array_equal(a.readings, e.read())  # refreshed in the kernel


def test_a_replaced_simulator_is_picked_up_and_the_batch_pickles():
    sims = [make(1000.0, 60.0), make(1000.0, 80.0)]
    batch = SimulatorBatch(2)
    drive(sims, batch, 1)
    sims[1] = make(700.0, 80.0)  # e.g. a randomised scenario's new episode
    reference = [make(1000.0, 60.0), make(700.0, 80.0)]
    drive(reference[:1], None, 1)
    drive(sims, pickle.loads(pickle.dumps(batch)), 2)
    drive(reference, None, 2)
    for sim, ref in zip(sims, reference, strict=True):
        np.testing.assert_array_equal(sim.state, ref.state)


@pytest.mark.parametrize("active", [None, [True, True]])
def test_a_simulator_stopped_before_the_kernel_has_fresh_readings_too(active):
    """``SimulatorBatch.advance``: every active simulator has fresh readings afterwards,
    stopped ones included (its docstring), as ``sim.advance(..., read=True)`` leaves them:
    a hook load of 0 puts the whole string's weight on the bit, beyond what the mesh
    resolves, and stops the simulator in its prepare, before the kernel."""
    alone = [make(1000.0, 60.0) for _ in range(2)]
    together = [make(1000.0, 60.0) for _ in range(2)]
    hooks = [alone[0].hook_load_for(60e3), 0.0]
    for sim, hook in zip(alone, hooks, strict=True):
        sim.advance(50, 60.0 * RPM, hook, 10, read=True)
    SimulatorBatch(2).advance(together, [50, 50], [60.0 * RPM] * 2, hooks, [10, 10], active)
    assert alone[1].readings[READ.STATUS] == Status.MESH_BUCKLING
    for a, e in zip(together, alone, strict=True):
        np.testing.assert_array_equal(a.readings, e.readings)


def test_batch_size_is_checked():
    with pytest.raises(ValueError, match="size"):
        SimulatorBatch(0)
    with pytest.raises(ValueError, match="sims"):
        SimulatorBatch(2).advance([make(1000.0, 60.0)], [1], [1.0], [1.0], [1])


def test_claim_hands_out_every_item_once_across_threads():
    """The atomic counter behind the batch's dynamic scheduling: threads that take items
    from it concurrently take each exactly once, and the counter ends at items + lanes
    (each lane's last claim finds nothing left)."""
    import numba
    from numba import njit, prange

    from drill_env.physics.jit import claim

    @njit(parallel=True)
    def take(counter, owner, lanes):
        n = owner.shape[0]
        counter[0] = 0
        for _ in prange(lanes):
            e = claim(counter)
            while e < n:
                owner[e] += 1  # 0 if never taken, 2 if taken twice
                x = 0.0
                for k in range(2000):  # some work, so that the lanes overlap
                    x += np.sqrt(k + e)
                owner[e] += 0 if x >= 0.0 else 1
                e = claim(counter)

    lanes = numba.get_num_threads()
    if lanes < 2:
        pytest.skip("one numba thread: no concurrent claims to test")
    for n in (1, 7, 500):
        counter = np.zeros(1, dtype=np.int64)
        owner = np.zeros(n, dtype=np.int64)
        take(counter, owner, lanes)
        assert (owner == 1).all()
        assert counter[0] == n + lanes


def test_claim_takes_a_writable_int64_counter_only():
    """``claim``'s contract (a writable one-dimensional int64 array): a read-only or a
    float counter is refused when the kernel is typed, not incremented in place; its
    plain-Python twin (NUMBA_DISABLE_JIT=1) hands out 0, 1, 2 as the intrinsic does."""
    from numba import njit
    from numba.core.errors import TypingError

    from drill_env.physics.jit import _claim_uncompiled, claim

    @njit
    def take(counter):
        return claim(counter)

    counter = np.zeros(1, dtype=np.int64)
    assert [take(counter) for _ in range(3)] == [0, 1, 2] and counter[0] == 3
    plain = np.zeros(1, dtype=np.int64)
    assert [_claim_uncompiled(plain) for _ in range(3)] == [0, 1, 2] and plain[0] == 3
    read_only = np.zeros(1, dtype=np.int64)
    read_only.setflags(write=False)
    for refused in (read_only, np.zeros(1)):
        with pytest.raises(TypingError):
            take(refused)


#: Builds a batch's slots and re-points one (what an env batch does at a reset), then
#: prints the typed-list helpers' numba cache hits and misses.
SLOTS_IN_A_FRESH_PROCESS = """
import json
from drill_env.physics import batch
from drill_env.physics.simulator import Simulator
sims = [Simulator() for _ in range(3)]
slots = batch.TupleSlots(2, batch.simulator_arrays, batch.simulator_key)
slots.of(sims[:2])
slots.of([sims[2], sims[1]])
helpers = (batch.typed_list, batch.typed_append, batch.typed_put)
print(json.dumps([(len(f.stats.cache_hits), len(f.stats.cache_misses)) for f in helpers]))
"""


def test_the_slots_typed_list_comes_from_numba_s_cache_in_a_new_process():
    """A typed list's own methods called from Python compile again in every process
    (~0.8 s each for these tuples); the slots call them inside cached functions, so a
    second process loads all three from the cache and compiles none."""
    for _ in range(2):  # the first may compile and write the cache
        out = subprocess.run([sys.executable, "-c", SLOTS_IN_A_FRESH_PROCESS],
                             capture_output=True, text=True, check=True)
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts == [[1, 0], [1, 0], [1, 0]]


def test_a_batch_steps_with_numba_switched_off(tmp_path):
    """NUMBA_DISABLE_JIT=1 (debugging the kernels in plain Python): every batched env
    step failed, the atomic counter being a compiled intrinsic only (an outside check).
    Uncompiled, a batch of two steps as compiled code steps it (the same operations in
    Python's floats: equal within rounding)."""
    import os

    import gymnasium as gym

    code = """
import json
import gymnasium as gym, numpy as np, drill_env
e = gym.make_vec("DrillString-v0", num_envs=2, fidelity="fast", control_interval=0.02)
e.reset(seed=3)
o, r, te, tr, i = e.step(np.array([[0.2, -0.1], [-0.3, 0.4]], np.float32))
print(json.dumps({"obs": o.tolist(), "reward": r.tolist()}))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "NUMBA_DISABLE_JIT": "1"}, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    uncompiled = json.loads(done.stdout.splitlines()[-1])
    envs = gym.make_vec("DrillString-v0", num_envs=2, fidelity="fast", control_interval=0.02)
    envs.reset(seed=3)
    obs, reward, *_ = envs.step(np.array([[0.2, -0.1], [-0.3, 0.4]], np.float32))
    np.testing.assert_allclose(uncompiled["obs"], obs, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(uncompiled["reward"], reward, rtol=1e-9)
