"""What ``DrillString-v0`` puts in its ``info``, and its step's finish for many envs at once.

The info layout (which readings and window metrics, in which order) is defined here
once, for the env's own step (:meth:`~drill_env.env.DrillStringEnv._info`) and for its
batch form. :class:`BatchFinish`, a base of :class:`~drill_env.env.DrillStringEnv`,
finishes the step of many envs after a batch advanced them in one parallel call
(:mod:`drill_env.batching`): termination, reward, observation and info for all envs in
one compiled call (:func:`finish_rows`), with the same floats as each env's own
``finish_metrics``. The per-env Python it replaces was most of what a batch spent
outside its parallel physics call (docs/performance.md).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from enum import IntEnum
from itertools import chain
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from drill_env.metrics import STEP_FINITE, WINDOW_FINITE, Metric
from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.layout import N_READINGS, READ, READINGS

#: Observations are clipped to +-OBS_BOUND (normalised units).
OBS_BOUND = 10.0

#: The window metrics in ``info`` (zero while the window is empty or not finite).
INFO_WINDOW_METRICS = ("ssi", "stuck_fraction", "whirl_ratio", "radial_ratio", "lateral_force",
                       "mse")
#: (info key, :class:`~drill_env.metrics.Metric` index) of each of them.
INFO_METRICS = tuple((name, int(Metric[name.upper()])) for name in INFO_WINDOW_METRICS)
#: Readings that ``info`` does not carry as they are: the bit position goes in as the
#: vector ``bit_lateral``, the bit velocity only feeds the observation, the status is the
#: simulator's (``termination_reason`` says it in words). Every other reading of
#: :data:`~drill_env.physics.layout.READINGS` is an info key of the same name.
INFO_HIDDEN_READINGS = frozenset({"bit_x", "bit_y", "bit_vx", "bit_vy", "status"})
INFO_READINGS = tuple((name, k) for k, name in enumerate(READINGS)
                      if name not in INFO_HIDDEN_READINGS)  # (info key, reading index)
#: Reading indices as plain ints (env.py indexes its readings list with them too).
_TIME, _BIT_X, _BIT_Y, _STATUS, _SURFACE_TORQUE = (
    int(READ.TIME), int(READ.BIT_X), int(READ.BIT_Y), int(READ.STATUS),
    int(READ.SURFACE_TORQUE))

_INFO_READING_INDEX = np.array([k for _, k in INFO_READINGS], dtype=np.int64)
_N_INFO_READINGS = len(INFO_READINGS)
_INFO_METRIC_INDEX = np.array([k for _, k in INFO_METRICS], dtype=np.int64)
#: The float ``info`` values, in the order of :data:`INFO_KEYS`: a batch computes each as
#: one array over its envs (:meth:`BatchFinish.finish_batch`).
_BATCH_FLOAT_INFO = (*(name for name, _ in INFO_READINGS), "speed_setpoint",
                     "weight_on_bit_setpoint", "weight_on_bit_limit", "episode_time",
                     "top_drive_energy", "bit_inclination", *INFO_WINDOW_METRICS)
#: The ``info`` keys of a step, in order (``DrillStringEnv._info``, then the reward terms
#: and the termination reason).
INFO_KEYS = (*_BATCH_FLOAT_INFO[:_N_INFO_READINGS], "bit_lateral", "rock_share",
             *_BATCH_FLOAT_INFO[_N_INFO_READINGS:], "reward_terms", "termination_reason")
#: ``info["reward_terms"]``'s keys, in order (``DrillStringEnv._reward_terms``).
RewardTerm = IntEnum("RewardTerm", ["ROP", "STICK_SLIP", "WHIRL", "EFFORT", "FAILURE"], start=0)
REWARD_TERMS = tuple(term.name.lower() for term in RewardTerm)


#: Columns of the per-env state a batch hands to :func:`finish_rows`.
BatchState = IntEnum("BatchState", [
    "COUNT", "ENERGY", "SPEED", "WOB", "EFFORT", "START", "LIMIT", "MAX_STEPS", "INCLINATION",
    "STATUS", "SSI", "WORST"], start=0)
#: The config values :func:`finish_rows` uses (the envs of a batch share one config).
BatchWeight = IntEnum("BatchWeight", [
    "ROP", "ROP_SCALE", "STICK_SLIP", "SSI_CAP", "WHIRL", "EFFORT", "FAILURE", "MAKEUP_TORQUE"],
    start=0)


class BatchOut(NamedTuple):
    """What :func:`finish_rows` writes, one row (or column) per env."""

    obs: np.ndarray         # (n, n_obs) float32
    usable: np.ndarray      # bool: the observation is finite (else the env repeats its last)
    reward: np.ndarray      # float64
    terms: np.ndarray       # (len(REWARD_TERMS), n)
    terminated: np.ndarray  # bool
    truncated: np.ndarray   # bool
    energy: np.ndarray      # top-drive energy of the episode (J)
    worst: np.ndarray       # the episode's lowest step reward without the failure term
    floats: np.ndarray      # (len(_BATCH_FLOAT_INFO), n): the float info values


@njit(**TUPLE_KERNEL)
def finish_rows(state, n_rec, flags, step, window, readings, source, divisor, weights, out):
    """The termination, reward terms, observation and float info of every env of a
    batch (row e: env e), each computed as ``DrillStringEnv.finish_metrics`` does in
    Python, operation for operation (the same floats).

    ``state``: :data:`BatchState` columns (COUNT the step count after this step, STATUS
    the simulator's, SSI the reward's: ``_window_ssi``, the window's or, when its bit
    speed is not finite, infinite; WORST ``_worst_step`` before this step); ``n_rec``,
    ``flags``, ``step``, ``window``, ``readings``: as :meth:`BatchFinish.finish_batch`
    takes them, with the readings of diverged envs already replaced by their last finite
    ones and the info metrics of envs without a finite window by their own (``_window``:
    0.0); ``source``, ``divisor``: the observation's columns (of the readings then the two
    set points) and scales;
    ``weights``: :data:`BatchWeight`; ``out``: a :class:`BatchOut`.
    """
    n_read = readings.shape[1]
    n_info = _INFO_READING_INDEX.shape[0]
    for e in range(readings.shape[0]):
        st = state[e]
        has = n_rec[e] > 0
        step_ok = has and (flags[e] & STEP_FINITE) != 0
        energy = st[BatchState.ENERGY]
        if step_ok:  # records not all finite add no energy (finish_metrics)
            energy += step[e, Metric.TOP_DRIVE_ENERGY]
        out.energy[e] = energy
        # _termination_reason: a stopped simulator, or the torque above make-up
        peak = step[e, Metric.SURFACE_TORQUE_MAX] if has else 0.0
        torque = abs(readings[e, _SURFACE_TORQUE])
        if torque > peak:
            peak = torque
        terminated = st[BatchState.STATUS] != 0.0 or peak > weights[BatchWeight.MAKEUP_TORQUE]
        out.terminated[e] = terminated
        out.truncated[e] = (not terminated) and st[BatchState.COUNT] >= st[BatchState.MAX_STEPS]
        # _reward_terms, summed in their order from 0 as metrics.summed does
        rop = step[e, Metric.ROP] if step_ok else 0.0
        excursion = step[e, Metric.EXCURSION_RATIO] if step_ok else 1.0
        ssi = st[BatchState.SSI]
        cap = weights[BatchWeight.SSI_CAP]
        ssi = cap if cap < ssi else ssi  # min(ssi, cap)
        out.terms[RewardTerm.ROP, e] = weights[BatchWeight.ROP] * rop / \
            weights[BatchWeight.ROP_SCALE]
        out.terms[RewardTerm.STICK_SLIP, e] = -weights[BatchWeight.STICK_SLIP] * ssi
        out.terms[RewardTerm.WHIRL, e] = -weights[BatchWeight.WHIRL] * excursion
        out.terms[RewardTerm.EFFORT, e] = -weights[BatchWeight.EFFORT] * st[BatchState.EFFORT]
        reward = 0.0
        for k in range(RewardTerm.FAILURE):
            reward += out.terms[k, e]
        worst = st[BatchState.WORST]
        worst = reward if reward < worst else worst
        out.worst[e] = worst
        failure = 0.0
        if terminated:  # and each step it cuts off at the episode's worst (finish_metrics)
            cut_off = st[BatchState.MAX_STEPS] - st[BatchState.COUNT]
            failure = -weights[BatchWeight.FAILURE] - cut_off * (-worst if worst < 0.0 else 0.0)
        out.terms[RewardTerm.FAILURE, e] = failure
        out.reward[e] = reward + failure
        # _observation: each entry its source over its scale, clipped, as float32
        usable = True
        for j in range(source.shape[0]):
            k = source[j]
            value = readings[e, k] if k < n_read else (
                st[BatchState.SPEED] if k == n_read else st[BatchState.WOB])
            value = value / divisor[e, j]
            if not math.isfinite(value):
                usable = False
            value = OBS_BOUND if value > OBS_BOUND else -OBS_BOUND if value < -OBS_BOUND \
                else value
            out.obs[e, j] = np.float32(value)
        out.usable[e] = usable
        # _info's floats, in _BATCH_FLOAT_INFO's order
        for j in range(n_info):
            out.floats[j, e] = readings[e, _INFO_READING_INDEX[j]]
        out.floats[n_info, e] = st[BatchState.SPEED]
        out.floats[n_info + 1, e] = st[BatchState.WOB]
        out.floats[n_info + 2, e] = st[BatchState.LIMIT]
        out.floats[n_info + 3, e] = readings[e, _TIME] - st[BatchState.START]
        out.floats[n_info + 4, e] = energy
        out.floats[n_info + 5, e] = st[BatchState.INCLINATION]
        for j in range(_INFO_METRIC_INDEX.shape[0]):
            out.floats[n_info + 6 + j, e] = window[e, _INFO_METRIC_INDEX[j]]


#: Gymnasium's batched info names: every key, then its mask ``_key``.
_INFO_NAMES = tuple(name for key in INFO_KEYS for name in (key, f"_{key}"))
_TERM_NAMES = tuple(name for key in REWARD_TERMS for name in (key, f"_{key}"))


class BatchInfo:
    """The ``info`` of many envs' step as arrays (:meth:`BatchFinish.finish_batch`).

    ``floats``: one row per float key of :data:`INFO_KEYS` (a column per env);
    ``bit_lateral`` and ``rock_share``: one row per env; ``terms``: one row per reward
    term; ``reasons``: the termination reasons. :meth:`batched` gives Gymnasium's batched
    layout (a ``VectorEnv``'s info), :meth:`dicts` one dict per env (an SB3 ``VecEnv``'s);
    each holds the values that the env's own ``step`` puts in its info.
    """

    def __init__(self, floats: np.ndarray, bit_lateral: np.ndarray, rock_share: np.ndarray,
                 terms: np.ndarray, reasons: list[str]) -> None:
        self.floats, self.bit_lateral, self.rock_share = floats, bit_lateral, rock_share
        self.terms, self.reasons = terms, reasons

    def __len__(self) -> int:
        return len(self.reasons)

    def batched(self) -> dict[str, Any]:
        """Every key an array over the envs with its ``_key`` mask (all True), nested
        for the reward terms: what ``VectorEnv._add_info`` builds from the envs' dicts."""
        n = len(self)
        terms: list[Any] = [None] * len(_TERM_NAMES)
        terms[0::2] = self.terms
        terms[1::2] = np.ones(self.terms.shape, dtype=np.bool_)
        reasons = np.empty(n, dtype=object)
        reasons[:] = self.reasons
        split = _N_INFO_READINGS
        values: list[Any] = [None] * len(_INFO_NAMES)
        values[0::2] = [*self.floats[:split], self.bit_lateral, self.rock_share,
                        *self.floats[split:], dict(zip(_TERM_NAMES, terms, strict=True)),
                        reasons]
        values[1::2] = np.ones((len(INFO_KEYS), n), dtype=np.bool_)
        return dict(zip(_INFO_NAMES, values, strict=True))

    def dicts(self) -> list[dict[str, Any]]:
        """One info dict per env, as the env's own ``step`` returns it."""
        split = _N_INFO_READINGS
        out = []
        for row, lateral, share, terms, reason in zip(
                self.floats.T.tolist(), self.bit_lateral, self.rock_share,
                self.terms.T.tolist(), self.reasons, strict=True):
            values = (*row[:split], lateral, share, *row[split:],
                      dict(zip(REWARD_TERMS, terms, strict=True)), reason)
            out.append(dict(zip(INFO_KEYS, values, strict=True)))
        return out


class BatchFinish:
    """The batch form of :meth:`~drill_env.env.DrillStringEnv.finish_metrics`, mixed into
    the env class: classmethods over a list of its instances."""

    # What the methods below read and write: the env's own state (drill_env.env).
    sim: Any
    config: Any
    weight_on_bit_limit: float
    _frames: Any
    _obs_plan: list[tuple[int, float]]
    _readings: list[float]
    _last_obs: np.ndarray
    _window_metrics: tuple[list[float], bool] | None
    _step_count: int
    _status: float
    _episode_energy: float
    _speed_target: float
    _wob_target: float
    _effort: float
    _start_time: float
    _max_steps: int

    #: The last :meth:`_batch_observation_plan`: the plans it was built from (held, so
    #: their ids stay theirs), the source columns and the divisors.
    _batch_plan: tuple[list, np.ndarray, np.ndarray] = ([], np.zeros(0), np.zeros(0))

    @classmethod
    def finishes_batch(cls, envs: Sequence[Any]) -> bool:
        """Whether :meth:`finish_batch` can finish these envs' step: instances of exactly
        this class (a subclass computes its own observation, reward or info in Python)
        with one config (weights, limits, sensors), without telemetry delay, observation
        noise or rendered frames, and :meth:`same_readings`. All but the last hold for
        the envs' lifetime: a vector env checks them once and :meth:`same_readings` at
        every step."""
        config = envs[0].config
        return all(type(env) is cls and env._frames is None and env.config == config
                   for env in envs) and not config.telemetry_delay \
            and not config.observation_noise and cls.same_readings(envs)

    @staticmethod
    def same_readings(envs: Sequence[Any]) -> bool:
        """Whether the envs' simulators have readings of one length (the same rocks;
        a randomised scenario builds a new simulator at every reset)."""
        width = len(envs[0].sim.readings)
        return all(len(env.sim.readings) == width for env in envs)

    @classmethod
    def finish_batch(cls, envs: Sequence[Any], n_rec: np.ndarray, flags: np.ndarray,
                     step: np.ndarray, window: np.ndarray, readings: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, BatchInfo]:
        """:meth:`finish_metrics` of many envs at once, as arrays: (observations, rewards,
        terminated, truncated, :class:`BatchInfo`), row i for ``envs[i]``.

        For envs that :meth:`finishes_batch` accepts, after their records went into
        their metric windows: ``n_rec``, ``flags``, ``step``, ``window`` and ``readings``
        are, row by row, each env's record count, :func:`~drill_env.metrics.rolling_add`
        flags, step and window metrics and fresh readings (the batch gathers them in its
        compiled call, :mod:`drill_env.batching`). Every value is the float
        :meth:`finish_metrics` computes (the same operations in the same order, for all
        envs in one compiled call, :func:`finish_rows`), and every env's state is left as
        :meth:`finish_metrics` leaves it. What is rare
        (an empty or non-finite window, a diverged simulator) goes through the envs' own
        methods.
        """
        n = len(envs)
        cfg = envs[0].config
        counts = [env._step_count + 1 for env in envs]
        state = np.fromiter(chain.from_iterable(
            (count, env._episode_energy, env._speed_target, env._wob_target, env._effort,
             env._start_time, env.weight_on_bit_limit, env._max_steps,
             env.sim.bit_inclination, 0.0, 0.0, env._worst_step)
            for count, env in zip(counts, envs, strict=True)),
            np.float64, len(BatchState) * n).reshape(n, len(BatchState))
        state[:, BatchState.STATUS] = readings[:, _STATUS]  # as read, diverged or not
        state[:, BatchState.SSI] = window[:, Metric.SSI]
        has = n_rec > 0
        window_ok = has & (flags & WINDOW_FINITE != 0)
        fresh = readings.copy()
        if not np.isfinite(fresh).all():  # diverged envs: their last finite readings
            for i in np.flatnonzero(~np.isfinite(fresh).all(axis=1)).tolist():
                fresh[i] = envs[i]._readings
        status = state[:, BatchState.STATUS].tolist()
        metrics = window.tolist()  # each env's window metrics, as rolling_add left them
        if not window_ok.all():  # no finite window: the envs' own SSI and info metrics
            window = window.copy()
            for i in np.flatnonzero(~window_ok).tolist():
                env = envs[i]
                if has[i]:  # (finish_metrics takes the window before its hooks)
                    env._window_metrics = (metrics[i], False)
                state[i, BatchState.SSI] = env._window_ssi()
                values = env._window()
                window[i, _INFO_METRIC_INDEX] = [values[k] if values is not None else 0.0
                                                 for _, k in INFO_METRICS]
        source, divisor = cls._batch_observation_plan(envs)
        weights = np.array([cfg.rop_weight, cfg.rop_scale, cfg.stick_slip_weight, cfg.ssi_cap,
                            cfg.whirl_weight, cfg.effort_weight, cfg.failure_weight,
                            cfg.makeup_torque])
        out = BatchOut(obs=np.empty((n, len(source)), dtype=np.float32),
                       usable=np.empty(n, dtype=np.bool_), reward=np.empty(n),
                       terms=np.empty((len(REWARD_TERMS), n)),
                       terminated=np.empty(n, dtype=np.bool_),
                       truncated=np.empty(n, dtype=np.bool_), energy=np.empty(n),
                       worst=np.empty(n),
                       floats=np.empty((len(_BATCH_FLOAT_INFO), n)))
        finish_rows(state, n_rec, flags, step, window, fresh, source, divisor, weights, out)
        obs = out.obs
        kept = obs.copy()
        # every env's state as finish_metrics leaves it, in one pass
        for i, (env, count, stat, row, has_records, values, finite, energy, usable,
                last, worst) in enumerate(zip(envs, counts, status, fresh.tolist(),
                                              has.tolist(), metrics, window_ok.tolist(),
                                              out.energy.tolist(), out.usable.tolist(), kept,
                                              out.worst.tolist(), strict=True)):
            env._step_count = count
            env._worst_step = worst
            env._status = stat
            env._readings = row
            if has_records:
                env._window_metrics = (values, finite)
                env._episode_energy = energy
            if usable:
                env._last_obs = last
            else:  # diverged: repeat the last finite observation
                obs[i] = env._last_obs
        reasons = [""] * n
        if out.terminated.any():
            for i in np.flatnonzero(out.terminated).tolist():
                reasons[i] = envs[i].sim.status_message if status[i] != 0 else \
                    "surface torque above make-up torque"
        info = BatchInfo(out.floats, fresh[:, _BIT_X:_BIT_Y + 1].copy(),
                         fresh[:, N_READINGS:].copy(), out.terms, reasons)
        return obs, out.reward, out.terminated, out.truncated, info

    @classmethod
    def _batch_observation_plan(cls, envs: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
        """(source column, divisor) of every observation entry of every env: the
        columns are the same for all (one sensor set), the divisors per env. Built again
        only when an env has a new plan (a new simulator)."""
        plans = [env._obs_plan for env in envs]
        cached, source, divisor = BatchFinish._batch_plan
        if len(cached) != len(plans) or not all(map(operator.is_, plans, cached)):
            source = np.array([k for k, _ in plans[0]], dtype=np.int64)
            divisor = np.array([[d for _, d in plan] for plan in plans])
            BatchFinish._batch_plan = (plans, source, divisor)
        return source, divisor
