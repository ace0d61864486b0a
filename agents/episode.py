"""One benchmark episode (:func:`run_episode`): a controller in its env from the scenario's
settled start, its actions, the window metrics and the judgement of a swing still growing.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.settings import (
    UNFINISHED,
    BenchmarkSettings,
    Episode,
    check_acts_in,
    guest_env_kwargs,
    scenario_set_points,
    starting_at,
)
from agents.tables import ROCK_CHANGED, SERIES_CHANNELS, SET_POINT_MOVED, sets_own_speed
from drill_env.physics.units import HOUR, KILO, MEGA, RPM
from drill_env.physics.validation import numbers
from drill_env.sweep import save_text, save_whole

#: Seconds by which a step may start before the warm-up's end and still count in the
#: window return: the control steps' times are sums of floats (50 steps of 0.1 s end at
#: 5 s give or take 1e-15 s), far below any control interval.
WINDOW_SLACK = 1e-6


def run_episode(episode: Episode) -> dict[str, Any]:
    """Run one episode; returns its benchmark row (plus ``termination``)."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.registry import make_controller
    from drill_env.metrics import window_metrics
    from drill_env.physics.config import flatten
    from drill_env.physics.layout import RECORD_CHANNELS, R

    settings = BenchmarkSettings(**episode.settings)
    controller = make_controller(episode.controller, env_id=episode.env_id,
                                 **episode.policy_kwargs())
    if episode.env_id is not None:  # a task benchmark: one task for every controller
        env_kwargs = dict(settings.env_kwargs)
    else:
        env_kwargs = guest_env_kwargs(controller)
    physics = {**flatten(env_kwargs.pop("physics", None) or {}), **settings.physics,
               **controller.physics()}
    env_id = episode.env_id or controller.env_id
    check_acts_in(episode.controller, controller, env_id)
    # under the benchmark's episode settings, which are the same for every controller
    env_kwargs.update(scenario=episode.scenario, episode_duration=settings.duration,
                      start_kick=settings.start_kick, fidelity=settings.fidelity)
    # a task's policy within a benchmark of DrillString-v0 scenarios acts in its task's
    # env (its observation and action), from the same start as every other controller
    guest = episode.env_id is None and env_id != "DrillString-v0"
    if guest:
        env_kwargs["startup"] = "settled"
    if episode.env_id is None:  # --rpm / --wob, the scenario's start (also reset options)
        env_kwargs.update(starting_at(episode.scenario, settings.set_points(), physics))
    try:
        env: Any = gym.make(env_id, physics=physics, **env_kwargs)
    except ValueError as err:  # said with whose episode it is (a gain of yours too high
        # for the step read as the scenario's)
        raise ValueError(f"{err} (the episode of {episode.label} on {episode.scenario})"
                         ) from None
    if episode.record:
        from drill_env.recording import RecordEpisode

        # marked until it ends: a rerun after an interrupt told its own recording cut short
        # from another run's and set it aside as one (a fuzzing walkthrough)
        stamped = episode.recording_stamp.read_text(encoding="utf-8") \
            if episode.recording_stamp.exists() else None
        episode.recording_stamp.parent.mkdir(parents=True, exist_ok=True)
        save_text(episode.recording_stamp, f"{UNFINISHED}\n{episode.run}\n")
        env = RecordEpisode(env, Path(episode.out) / "recordings", scenario=episode.scenario,
                            controller=episode.label, stem=episode.stem)
    base = env.unwrapped
    kept: list[np.ndarray] = []
    targets: list[tuple[float, float]] = []  # (time, target speed) per step
    # (time, (speed and WOB set points, rock shares)) per step: what must hold for a
    # growing swing to be the loop's (window_swing_trend)
    held: list[tuple[float, tuple[float, ...]]] = []
    total = 0.0
    # the return of the steps the metrics measure (those from the end of the warm-up on): a
    # task's return counts its stalled start too, where most of task 1's differences lie
    # (an outside review: 241 of the shipped policy's 391 in its first 5 s)
    window = 0.0
    reason = ""
    # a task's policy in its task's env, within a benchmark of the scenario's set points:
    # at those (else the task would draw its own targets)
    options = scenario_set_points(episode.scenario, episode.seed) if guest else None
    if episode.env_id is None and settings.set_points():  # the user's, over the scenario's
        options = {**(options or {}), **settings.set_points()}
    try:
        obs, info = env.reset(seed=episode.seed, options=options)
        if guest:  # scored as DrillString-v0 scores the other controllers
            base.plain_return = 0.0
        # ("random seed 0" read as an adjective and a noun: a new user's trial)
        where = f"scenario {episode.scenario}, seed {episode.seed}"
        reset(controller, episode.controller, where, base)
        start = float(info["time"])
        while True:
            measured = float(info["time"]) >= start + settings.warmup - WINDOW_SLACK
            before = base.plain_return if guest else total
            obs, reward, terminated, truncated, info = env.step(
                act(controller, episode.controller, where, env.action_space, obs, info))
            total += float(reward)
            if measured:  # a guest's is what DrillString-v0 pays, as its episode_return
                window += (base.plain_return if guest else total) - before
            kept.append(base.last_records)
            targets.append((float(info["time"]), base.targets[0]))
            held.append((float(info["time"]), (float(info["speed_setpoint"]),
                                               float(info["weight_on_bit_setpoint"]),
                                               *np.asarray(info["rock_share"], float))))
            if terminated or truncated:
                reason = str(info.get("termination_reason", "")) if terminated else ""
                break
    finally:
        env.close()
    if episode.record and getattr(env, "last_path", None) == episode.recording:
        # (only a file this run wrote: RERUN=off writes none, and an older one stays old)
        save_text(episode.recording_stamp, f"{episode.stamp}\n{episode.run}\n")
    elif episode.record:  # none written: the stamp as it was
        if stamped is None:
            episode.recording_stamp.unlink(missing_ok=True)
        else:
            save_text(episode.recording_stamp, stamped)
    everything = np.concatenate(kept) if kept else np.zeros((0, len(RECORD_CHANNELS)))
    records = everything[everything[:, R.TIME] >= start + settings.warmup]
    if len(records) < 2 <= len(everything) and reason:  # a failure in the warm-up is a
        # result too: its metrics are the whole episode's (it stopped the whole benchmark)
        records = everything
        # and its window return the whole episode's: none of its steps was in the window,
        # and a 0 would be task 1's best (an outside review: a lead of ~1,400 by failing)
        window = base.plain_return if guest else total
        reason += "; in the warm-up: metrics over the whole episode (its return too)"
    if len(records) < 2:  # (a ValueError: said in one line, not a worker's traceback)
        # not a failure: whole control steps end the episode before --duration (20 s are
        # 202 steps of 0.0988 s, 19.97 s, at the fast level: a metrics audit's 19.98 s
        # warm-up left no sample)
        ended = float(info["time"]) - start
        why = reason or (f"the warm-up, {settings.warmup:g} s, leaves no two samples in it: "
                         f"it ends at {ended:.4g} s, {base.max_episode_steps} control steps of "
                         f"{base.control_interval:.4g} s")
        raise ValueError(f"the episode of {episode.label} on {episode.scenario}, seed "
                         f"{episode.seed}, ended before a second sample, with nothing to "
                         f"measure ({why})")
    dt = float(records[1, R.TIME] - records[0, R.TIME])
    m = window_metrics(records, RECORD_CHANNELS, dt, base.clearance,
                       base.sim.config.bit.diameter)
    mean_speed = float(np.mean(records[:, R.BIT_SPEED]))
    # the target may change during an episode (the tasks' driller): its mean over the
    # measured part, step by step
    in_window = [speed for t, speed in targets if t >= start + settings.warmup]
    target_rpm = float(np.mean(in_window or [targets[-1][1]])) / RPM
    own = getattr(controller, "sets_own_speed", None)  # a controller of your own may say
    row = {
        "controller": episode.label, "scenario": episode.scenario, "seed": episode.seed,
        "ssi": m["ssi"], "stuck_fraction": m["stuck_fraction"],
        "mean_bit_rpm": mean_speed / RPM, "target_rpm": target_rpm,
        "rpm_tracking_error": abs(mean_speed / RPM - target_rpm) / target_rpm
        if target_rpm > 0 else math.nan,
        "rop_m_per_h": m["rop"] * HOUR, "radial_ratio": m["radial_ratio"],
        "backward_whirl_fraction": m["backward_whirl_fraction"],
        "max_lateral_force_kN": m["lateral_force_max"] / KILO,
        "mse_MPa": m["mse"] / MEGA, "top_drive_energy_MJ": m["top_drive_energy"] / MEGA,
        # a guest's own return is its task's reward: DrillString-v0's is comparable
        "episode_return": base.plain_return if guest else total, "termination": reason,
        # the steps from the end of the warm-up on, the window of the metrics (not a
        # column: comparison.md pairs the controllers on it too)
        "window_return": window,
        # judged in the env it acted in: a drilling-task policy chooses the rpm in a
        # scenario benchmark too, as a guest (not a benchmark.csv column)
        "own_speed": own if isinstance(own, bool) else sets_own_speed(episode.label, env_id),
        "guest": guest,  # a task's policy in a scenario benchmark (not a column either)
        # a stick-slip still building, which the window's SSI may not show yet (not a
        # column): judged in DrillString-v0 (a guest's corrections, like a task's
        # target changes, would read as swing) where set points and rock held
        "swing_trend": window_swing_trend(everything, held, start, settings)
        if episode.env_id is None and not guest and not reason else "",
    }
    if episode.series:
        series_dir = Path(episode.out) / "series"
        series_dir.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, Any] = {name: everything[:, RECORD_CHANNELS.index(name)]
                                  for name in SERIES_CHANNELS}
        arrays["time"] = arrays["time"] - start
        arrays["clearance"] = base.clearance
        arrays["target_time"] = np.array([0.0] + [t - start for t, _ in targets[:-1]])
        arrays["target_rpm"] = np.array([speed / RPM for _, speed in targets])
        arrays["stamp"] = np.array(episode.stamp)
        save_whole(episode.series_file, lambda file: np.savez_compressed(file, **arrays))
    return row


#: Least bit-speed swing (rpm, half of max - min) of a window that the benchmark marks as
#: growing: above the ~0.02 rpm a held SoftSpeed loop (k = 4) settles to on a 1,500 kg m^2
#: top drive and the 0.027-0.028 rpm hump at 60-90 s of k = 5 there, which then decays
#: (seeds 0-4; both rise from ~0.003 rpm, neither is stick-slip), below the 0.045 rpm at
#: 60 s of the 2,000 kg m^2 drive's stick-slip, full by ~200 s (docs/controllers.md); about
#: midway. :data:`drill_env.swing.NO_SWING`, 0.01 rpm, marked loops that hold.
GROWING_FLOOR = 0.035
#: Rock shares under the bit that differ by more than this are another rock: a layer
#: crossed raises the swing without any loop's doing (paper_case2's ZTorque, x2.5).
SAME_ROCK = 1e-3


def window_swing_trend(records: np.ndarray, held: Sequence[tuple[float, tuple[float, ...]]],
                       start: float, settings: BenchmarkSettings) -> str:
    """Whether the bit-speed swing grows from the warm-up into the metric window
    (:func:`drill_env.swing.swing_trend`): the last ``block`` s of the window against the
    ``block`` s before it, ``block`` the shorter of the warm-up and the window. "" where
    the window's swing is under :data:`GROWING_FLOOR`; :data:`NOT_JUDGED` and why where
    ``held`` (per step: time, then set points and rock shares) changed over the two
    blocks: a set point moved by a policy or a target, or a layer crossed, would read as
    growth. A controls engineer's check: SoftSpeed on a 2,000 kg m^2 top drive read SSI
    0.00 over 30-60 s while its swing grew x4 per 30 s, to full stick-slip by ~200 s."""
    from drill_env.physics.layout import R
    from drill_env.swing import swing_trend

    split, end = start + settings.warmup, start + settings.duration
    block = min(settings.warmup, settings.duration - settings.warmup)
    spanned = np.array([values for t, values in held if t > split - block])
    if len(spanned) and np.ptp(spanned[:, :2], axis=0).any():
        return SET_POINT_MOVED
    if len(spanned) and float(np.max(np.ptp(spanned[:, 2:], axis=0))) > SAME_ROCK:
        return ROCK_CHANGED
    time, rpm = records[:, R.TIME], records[:, R.BIT_SPEED] / RPM
    before = rpm[(time >= split - block) & (time < split)]
    last = rpm[time >= min(end, float(time[-1])) - block]
    if len(before) < 2 or len(last) < 2 or 0.5 * float(np.ptp(last)) < GROWING_FLOOR:
        return ""
    swings = [0.5 * float(np.ptp(before)), 0.5 * float(np.ptp(last))]
    return swing_trend(swings, float(np.min(last)), block=end - split)


def reset(controller: Any, typed: str, where: str, env: Any) -> None:
    """``controller.reset(env)``; for a controller of your own (``typed``), an error in its
    code said in one line as :func:`act` says one (a raising ``reset`` gave a traceback
    through the benchmark and exit 1 where every other hook gave a line and exit 2: a new
    user's trial)."""
    from agents.registry import USER_ERRORS, in_user_code, is_imported

    if not is_imported(typed):
        controller.reset(env)
        return
    try:
        controller.reset(env)
    except USER_ERRORS as err:  # the user's code: said in one line (a sys.exit in it
        # ended the command with its status, unsaid)
        raise ValueError(f"controller: {typed}: reset() raised {in_user_code(err)} "
                         f"({where})") from None


def act(controller: Any, typed: str, where: str, space: Any, obs: Any,
        info: dict[str, Any]) -> Any:
    """``controller.act``; for a controller of your own (``typed``: its name as given), an
    error in its code or an action the env cannot take is said in one line naming it,
    the line of its file and ``where`` (the episode), not a worker's traceback of dozens
    of lines of the pool's."""
    from agents.registry import USER_ERRORS, in_user_code, is_imported

    if not is_imported(typed):
        return controller.act(obs, info)
    try:
        action = controller.act(obs, info)
    except USER_ERRORS as err:  # the user's code: said in one line (a sys.exit in it
        # ended the command with its status, unsaid)
        raise ValueError(f"controller: {typed}: act() raised {in_user_code(err)} "
                         f"({where})") from None
    if action is None:  # (said as "an action of shape ()")
        raise ValueError(f"controller: {typed}: act() returned None; the env takes an "
                         f"action of shape {space.shape} ({where})")
    if np.shape(action) != space.shape:
        raise ValueError(f"controller: {typed}: act() returned an action of shape "
                         f"{np.shape(action)}; the env takes {space.shape} ({where})")
    try:
        values = numbers(action, "action")
    except ValueError as err:  # strings, None, ragged lists: said with the controller
        raise ValueError(f"controller: {typed}: act() returned an {err} ({where})") from None
    if not np.isfinite(values).all():
        raise ValueError(f"controller: {typed}: act() returned {values.tolist()}, not "
                         f"finite numbers ({where})")
    if typed not in CLIPPED and not (np.all(values >= space.low)
                                      and np.all(values <= space.high)):
        # the env clips it, as documented; a controller of your own hears it once (one
        # returning 5.0 ran at the top speed, its table saying only "rpm error 193 %")
        CLIPPED.add(typed)
        low, high = space.low.tolist(), space.high.tolist()
        bounds = f"[{low[0]:g}, {high[0]:g}]" if len(set(low)) == len(set(high)) == 1 \
            else f"[{low}, {high}]"
        warnings.warn(f"controller: {typed}: act() returned {values.tolist()}, outside the "
                      f"action space {bounds}: the env clips it ({where}; said at the first)",
                      stacklevel=2)
    return action


#: Controllers of your own already told that the env clips their actions.
CLIPPED: set[str] = set()
