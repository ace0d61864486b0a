"""``drill-env well``: a well path and the soft-string torque-and-drag chart of a string.

For a survey (a preset of :data:`WELLS` or a CSV) and a scenario's string, the chart
drilling engineers use to plan and to read friction from the rig's data: hook load
against bit depth while picking up, slacking off and rotating off bottom, and the
rotating off-bottom surface torque, at several friction factors
(:func:`drill_env.physics.trajectory.soft_string`). Plus the path: 3-D, plan and
vertical section. This is the static soft-string model; the dynamic FE string in the
same holes: config ``well`` and the deviated scenarios (docs/model.md section 6).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.fem import build_mesh
from drill_env.physics.statics import bit_buoyed_weight
from drill_env.physics.trajectory import MODES, StringColumn, Survey, Trajectory, soft_string
from drill_env.sweep import save_text, save_whole

#: Well shapes by name: total measured depth (m) -> survey. Build rates and angles are
#: typical of land wells (2-4 deg/30 m builds; Mitchell & Miska, Fundamentals of
#: Drilling Engineering, ch. 11).
WELLS: dict[str, Callable[[float], Survey]] = {
    "vertical": lambda md: Survey.profile(md),
    "j_shaped": lambda md: Survey.profile(md, kickoff=500.0, build_rate=3.0,
                                          hold_inclination=45.0),
    "s_shaped": lambda md: Survey.profile(md, kickoff=300.0, build_rate=3.0,
                                          hold_inclination=30.0, drop_start=750.0,
                                          drop_rate=2.0, final_inclination=0.0),
    "lateral_60": lambda md: Survey.profile(md, kickoff=300.0, build_rate=4.0,
                                            hold_inclination=60.0),
}
#: Friction factors of the chart: cased hole ~0.15-0.25, open hole ~0.25-0.4 in
#: water-based mud (Johancsik et al. 1984; Aadnoy et al. 2010).
FRICTIONS = (0.1, 0.2, 0.3, 0.4)
#: Length (m) of the drill-pipe pieces added above the scenario's string to reach a
#: deeper bit (the pipe's own elements are coarser; the chart needs the hole's shape).
PIPE_PIECE = 10.0


def with_survey(config: SimulationConfig, survey: Survey) -> SimulationConfig:
    """``config`` in the hole of ``survey`` (its stations as the ``well`` section)."""
    return replace(config, **{"well.md": tuple(survey.md),
                              "well.inclination": tuple(np.degrees(survey.inclination)),
                              "well.azimuth": tuple(np.degrees(survey.azimuth))})


def sliding_friction(config: SimulationConfig, speed: float) -> float:
    """Wall friction coefficient (eq. 23) of the drill pipe's surface turning at
    ``speed`` (rad/s): what the soft-string model should use to compare with the FE
    string's contacts."""
    from drill_env.physics.string_friction import wall_friction_coefficient

    c = config.contact
    v = speed * config.string.drill_pipe.outer_diameter / 2.0
    return float(wall_friction_coefficient(v, c.friction_static, c.friction_kinetic,
                                           c.friction_decay_speed))


def rotating_wall_torque(config: SimulationConfig, speed: float, seconds: float = 10.0,
                         average: float = 4.0, wound: bool = True) -> tuple[float, Any]:
    """Rotate the simulated string off bottom at ``speed`` (rad/s) for ``seconds``: the
    wall torque (the surface torque averaged over the last ``average`` s, less the mud
    drag ``sum(tor_c) speed``) and the simulator. ``wound=False`` starts from an
    untwisted string, so the friction alone must wind it up."""
    from drill_env.physics.layout import R
    from drill_env.physics.simulator import OperatingPoint, Simulator

    sim = Simulator(config)
    sim.reset(OperatingPoint(speed, 0.0))
    if not wound:
        sim.ut[:] = 0.0
    rec = sim.run(seconds, record_every=50)
    late = rec[rec[:, R.TIME] > seconds - average]
    drag = float(np.sum(sim.tor_c)) * speed
    return float(late[:, R.SURFACE_TORQUE].mean()) - drag, sim


def column_for(config: SimulationConfig, bit_md: float) -> StringColumn:
    """The scenario's string from the bit up (its BHA and pipe elements), drill pipe
    added in ``PIPE_PIECE`` lengths to reach ``bit_md``. Contact at each element's
    contact radius (stabilizer blades; pipe body: tool joints are not modelled). The
    bit's buoyed weight is spread over the lowest element, as the dynamic model and
    ``info["hook_load"]`` carry it."""
    mesh = build_mesh(config)
    length = mesh.element_length[::-1]
    weight = mesh.buoyed_weight[::-1].copy()
    weight[0] += bit_buoyed_weight(config) / length[0]
    radius = mesh.contact_radius[::-1]
    missing = bit_md - float(np.sum(length))
    if missing > 0.0:
        n = math.ceil(missing / PIPE_PIECE)
        length = np.concatenate([length, np.full(n, missing / n)])
        weight = np.concatenate([weight, np.full(n, mesh.buoyed_weight[0])])
        radius = np.concatenate([radius, np.full(n, mesh.contact_radius[0])])
    return StringColumn(length.copy(), weight.copy(), radius.copy())


#: The units of ``well_<name>.json`` (an engineer reading it found none).
JSON_UNITS = {
    "md": "m", "inclination_deg": "deg", "azimuth_deg": "deg (from north)", "bit_md": "m",
    "frictions": "1 (friction factor)",
    "pick_up, slack_off, rotating": "N (hook load off bottom, without the blocks' weight)",
    "torque": "N m (surface torque rotating off bottom: wall friction only, no mud drag "
              "and no bit torque)"}

#: Bit-depth step of the torque-and-drag chart (m).
CHART_STEP = 100.0


def torque_drag_table(trajectory: Trajectory, config: SimulationConfig,
                      frictions: Sequence[float] = FRICTIONS, step: float = CHART_STEP
                      ) -> dict[str, object]:
    """Hook load (N) per mode and rotating off-bottom surface torque (N m) against bit
    depth, per friction factor."""
    depths = np.arange(step, trajectory.total_md + 1e-9, step)
    if depths.size == 0 or depths[-1] < trajectory.total_md - 1e-9:
        depths = np.append(depths, trajectory.total_md)
    column = column_for(config, float(depths[-1]))
    table: dict[str, object] = {"bit_md": depths.tolist(), "frictions": list(frictions)}
    for mu in frictions:
        entry: dict[str, list[float]] = {m: [] for m in MODES}
        entry["torque"] = []
        for depth in depths:
            for mode in MODES:
                result = soft_string(trajectory, column, float(depth), mu, mode)
                entry[mode].append(result.hook_load)
                if mode == "rotating":
                    entry["torque"].append(result.surface_torque)
        table[f"mu={mu:g}"] = entry
    return table


def write_well(name: str, trajectory: Trajectory, config: SimulationConfig, out: Path,
               frictions: Sequence[float] = FRICTIONS, string: str = "the scenario"
               ) -> list[Path]:
    """``well_<name>.png`` (path and torque-and-drag chart) and ``well_<name>.json``;
    ``string``: whose string it is, for the title (``--config FILE``'s)."""
    out.mkdir(parents=True, exist_ok=True)
    table = torque_drag_table(trajectory, config, frictions)
    fig = well_figure(name, trajectory, table, frictions, string)
    png = out / f"well_{name}.png"
    save_whole(png, lambda file: fig.savefig(file, dpi=100))
    stations = {"md": trajectory.survey.md.tolist(),
                "inclination_deg": np.degrees(trajectory.survey.inclination).tolist(),
                "azimuth_deg": np.degrees(trajectory.survey.azimuth).tolist()}
    data = out / f"well_{name}.json"
    save_text(data, json.dumps({"survey": stations, "torque_drag": table,
                                "units": JSON_UNITS}, indent=1))
    return [png, data]


#: A path whose plan view spans less than this (m) is a vertical hole: drawn as a point.
NO_DEPARTURE = 0.01


def well_figure(name: str, trajectory: Trajectory, table: dict[str, object],
                frictions: Sequence[float] = FRICTIONS, string: str = "the scenario") -> Any:
    """The matplotlib ``Figure`` of :func:`write_well` (not pyplot's: the process's
    backend is left as it is), laid out: the path (3-D, plan,
    vertical section) and the :func:`torque_drag_table` ``table``. The hook-load legend
    names each friction factor once (by colour) and each operation once (by line style):
    rotating off bottom has no axial drag, so its line is one for every friction."""
    import matplotlib
    from matplotlib.lines import Line2D

    from drill_env.figures import agg_figure

    md = np.linspace(0.0, trajectory.total_md, 400)
    pos, _, _ = trajectory.at(md)
    azimuth = float(trajectory.survey.azimuth[-1])
    section = pos[:, 0] * math.cos(azimuth) + pos[:, 1] * math.sin(azimuth)

    fig = agg_figure(figsize=(15, 9))
    ax3 = fig.add_subplot(2, 3, 1, projection="3d")
    ax3.plot(pos[:, 1], pos[:, 0], -pos[:, 2], lw=2)
    half = 0.5 * max(np.ptp(pos[:, 0]), np.ptp(pos[:, 1]), 100.0)  # one scale both ways
    for setter, axis in ((ax3.set_xlim, 1), (ax3.set_ylim, 0)):
        middle = 0.5 * (pos[:, axis].min() + pos[:, axis].max())
        setter(middle - half, middle + half)
    from matplotlib.ticker import MaxNLocator

    for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):  # few ticks: long labels stay apart
        axis.set_major_locator(MaxNLocator(4))
    ax3.tick_params(labelsize=8)
    ax3.set_xlabel("east (m)", labelpad=8)
    ax3.set_ylabel("north (m)", labelpad=8)
    ax3.set_zlabel("-TVD (m)", labelpad=10)  # clear of the z tick labels
    ax3.set_box_aspect(None, zoom=0.85)  # the labels inside the panel, off the next one
    ax3.set_title("path")
    plan = fig.add_subplot(2, 3, 2)
    plan.plot(pos[:, 1], pos[:, 0], lw=2)
    point = max(np.ptp(pos[:, 0]), np.ptp(pos[:, 1])) < NO_DEPARTURE
    if point:  # a vertical hole: one
        # point, which a line does not draw, on axes of +-0.04 m (a check of the pictures)
        plan.plot(pos[-1, 1], pos[-1, 0], "o", ms=6, color="C0")
        plan.set_xlim(-50.0, 50.0)
        plan.set_ylim(-50.0, 50.0)
        plan.text(0.5, 0.35, "vertical hole: no departure", transform=plan.transAxes,
                  ha="center", color="0.3")
    plan.set_xlabel("east (m)")
    plan.set_ylabel("north (m)")
    # (a vertical hole's limits are fixed: its box keeps the aspect, where the data limits
    # printed matplotlib's "Ignoring fixed y limits" twice per chart)
    plan.set_aspect("equal", adjustable="box" if point else "datalim")
    plan.set_title("plan view")
    vertical = fig.add_subplot(2, 3, 3)
    vertical.plot(section, pos[:, 2], lw=2)
    for k, s_md in enumerate(trajectory.survey.md):
        north, east, down = trajectory.at(s_md)[0][0]
        vertical.plot(north * math.cos(azimuth) + east * math.sin(azimuth), down,
                      "k.", ms=5, label="survey stations" if k == 0 else None)
    vertical.invert_yaxis()
    vertical.set_aspect("equal", adjustable="datalim")
    vertical.set_xlabel(f"departure along azimuth {math.degrees(azimuth):.0f} deg (m)")
    vertical.set_ylabel("TVD (m)")
    vertical.set_title("vertical section")
    vertical.legend(fontsize=8)

    depths = np.array(table["bit_md"])
    hook = fig.add_subplot(2, 3, (4, 5))
    torque = fig.add_subplot(2, 3, 6)
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.85, len(frictions)))
    styles = {"pick_up": "-", "rotating": ":", "slack_off": "--"}
    entries = [table[f"mu={mu:g}"] for mu in frictions]
    assert all(isinstance(entry, dict) for entry in entries)
    rotating = [np.array(entry["rotating"]) for entry in entries]  # type: ignore[index]
    one_rotating = all(np.allclose(r, rotating[0], rtol=1e-9) for r in rotating)
    for mu, colour, entry in zip(frictions, colours, entries, strict=True):
        assert isinstance(entry, dict)
        for mode in MODES:
            if mode != "rotating" or not one_rotating:
                hook.plot(np.array(entry[mode]) / 1e3, depths, styles[mode], color=colour)
        torque.plot(np.array(entry["torque"]) / 1e3, depths, color=colour,
                    label=f"mu {mu:g}")
    if one_rotating:
        hook.plot(rotating[0] / 1e3, depths, styles["rotating"], color="k", lw=1.5)
    handles = [Line2D([], [], color=colour, label=f"mu {mu:g}")
               for mu, colour in zip(frictions, colours, strict=True)]
    handles += [Line2D([], [], ls=styles[mode], color="k", label=mode.replace("_", "-")
                       + (" (every mu)" if mode == "rotating" and one_rotating else ""))
                for mode in MODES]
    for ax, xlabel in ((hook, "hook load (kN), off bottom, no blocks weight"),
                       (torque, "surface torque of wall friction, rotating off bottom (kN m)")):
        ax.invert_yaxis()
        ax.set_ylabel("bit depth MD (m)")
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    # colours: the friction factor; line styles: the operation. In the empty corner.
    hook.legend(handles=handles, fontsize=7, ncol=2, loc="upper right")
    torque.legend(fontsize=8)
    hook.set_title("soft-string drag: hook load picking up, slacking off and rotating off "
                   "bottom (no axial drag: one line for every mu)", fontsize=9)
    if not np.any(np.abs([entry["torque"] for entry in entries]) > 1e-6):  # type: ignore[index]
        # no wall contact anywhere (a vertical hole): zeros on a +-0.04 kN m axis, four
        # lines on one, said instead
        torque.set_xlim(0.0, 1.0)
        torque.text(0.5, 0.5, "no wall contact: no wall torque\nand no drag (every line "
                    "of the hook load is one)", transform=torque.transAxes, ha="center",
                    va="center", color="0.3")
    torque.set_title("soft-string wall torque (no mud drag, no bit)", fontsize=9)
    fig.suptitle(f"well {name}: {trajectory.total_md:.0f} m MD, string of {string} "
                 "(drill pipe added above it to reach the bit)")
    fig.tight_layout()
    return fig
