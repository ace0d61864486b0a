"""Modal analysis of a configured string: natural frequencies, mode shapes, damping.

From the assembled FE matrices (:mod:`drill_env.physics.fem`), independent of the time
integrator:

* torsion: polar inertia J (top-drive rotor at the top, bit at the bottom), stiffness K,
  damping C = mud drag + b K. The top is ``"fixed"`` (a stiff speed loop: the
  literature's fixed-top boundary) or the ``"top_drive"``: its rotor inertia on the top
  node with the PI speed loop acting as a damper ``kp`` and a spring ``ki`` (the PI as
  an impedance, Kyllingstad & Nessjoen 2009). The bit end is free (off bottom).
* lateral (one bending plane; the other is the same): lumped mass with rotary inertia,
  K + K_g(WOB) with the static axial force at ``weight_on_bit``, Rayleigh damping
  a M + b K; the top node pinned, and with ``supports="stabilizers"`` (the usual BHA
  analysis) every stabilizer node and the bit pinned too (in contact with the wall).

Damped modes come from the eigenvalues ``lambda`` of the first-order system:
natural frequency ``|lambda| / 2 pi`` and damping ratio ``-Re(lambda) / |lambda|``;
:func:`undamped_frequencies` solves ``K phi = w^2 M phi`` (scipy ``eigh``).

:func:`critical_speeds` intersects the natural frequencies with the excitations of a
rotating string: once per revolution (mass imbalance, bent pipe), blade count per
revolution (the bit's blades), and backward whirl of a component rolling on the wall
(its centre orbits at ``w R / clearance`` against the rotation).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.linalg

from drill_env.physics.config import SimulationConfig
from drill_env.physics.fem import (
    Mesh,
    assemble_lateral,
    assemble_torsion,
    axial_force_profile,
    build_mesh,
    mud_torsional_damping,
)
from drill_env.physics.linalg import one_blas_thread
from drill_env.physics.statics import (  # noqa: F401  (re-exported for the CLI)
    PIPE_KINDS,
    bit_buoyed_weight,
    component_loads,
    is_pipe,
    neutral_point_height,
)
from drill_env.physics.top_drive import resolve as resolve_top_drive

__all__ = ["CHART_MODES", "CriticalSpeed", "Modes", "chart_cutoff", "critical_speed_chart",
           "critical_speed_figure", "critical_speeds", "excitation_label", "excitations",
           "lateral_buckling_weight", "lateral_modes", "neutral_point_height",
           "require_vertical", "torsional_modes", "undamped_frequencies"]

TopBoundary = Literal["fixed", "top_drive"]
LateralSupports = Literal["stabilizers", "top_only"]


@dataclass(frozen=True)
class Modes:
    """The lowest modes of one kind, sorted by frequency."""

    kind: str  # "torsional" or "lateral"
    frequency: np.ndarray  # (n,) natural frequency |lambda| / 2 pi (Hz)
    damping_ratio: np.ndarray  # (n,) -Re(lambda) / |lambda|
    shapes: np.ndarray  # (n, n_nodes) mode shapes over the nodes, max |.| = 1
    node_depth: np.ndarray  # (n_nodes,) measured depth of the nodes (m)
    boundary: str  # the boundary conditions, in words
    #: Undamped frequencies (Hz) and modal damping ratios of the overdamped modes (no
    #: oscillation: not in ``frequency``) below the highest one listed
    overdamped: np.ndarray = field(default_factory=lambda: np.zeros(0))
    overdamped_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _damped(k: np.ndarray, c: np.ndarray, m: np.ndarray, n_modes: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz), damping ratios and displacement shapes of the ``n_modes`` lowest
    oscillating modes of ``M x'' + C x' + K x = 0`` (``m`` diagonal)."""
    n = k.shape[0]
    m_inv = 1.0 / m
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -m_inv[:, None] * k
    a[n:, n:] = -m_inv[:, None] * c
    with one_blas_thread():
        lam, vec = scipy.linalg.eig(a)
    keep = lam.imag > 1e-9  # one of each conjugate pair; overdamped modes dropped
    lam, vec = lam[keep], vec[:n, keep]
    order = np.argsort(np.abs(lam))[:n_modes]
    lam, vec = lam[order], vec[:, order]
    freq = np.abs(lam) / (2 * math.pi)
    zeta = -lam.real / np.abs(lam)
    shapes = np.real(vec * np.exp(-1j * np.angle(vec[np.argmax(np.abs(vec), axis=0),
                                                     np.arange(vec.shape[1])])))
    shapes /= np.max(np.abs(shapes), axis=0)
    return freq, zeta, shapes.T


def overdamped_modes(k: np.ndarray, c: np.ndarray, m: np.ndarray, below: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(undamped frequency in Hz, modal damping ratio) of the modes below ``below`` Hz
    that :func:`_damped` drops as overdamped: the undamped modes ``K phi = w^2 M phi``
    whose modal damping ``phi' C phi / (2 w)`` (mass-normalised ``phi``; exact for
    proportional damping) is at least 1."""
    with one_blas_thread():
        w2, phi = scipy.linalg.eigh(k, np.diag(m))
    w = np.sqrt(np.maximum(w2, 0.0))
    ratio = np.einsum("ij,ik,kj->j", phi, c, phi) / np.maximum(2.0 * w, 1e-300)
    hz = w / (2 * math.pi)
    keep = (ratio >= 1.0) & (hz < below)
    return hz[keep], ratio[keep]


def torsional_system(config: SimulationConfig, top: TopBoundary = "fixed"
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(K, C, J, free DOFs) of the torsional model with the top boundary ``top``."""
    cfg = config.resolved()
    mesh = build_mesh(cfg)
    k, j = assemble_torsion(mesh)
    j[-1] += cfg.bit.inertia
    c = np.diag(mud_torsional_damping(mesh, cfg.mud.torsional_damping)) \
        + cfg.damping.stiffness_proportional * k
    free = np.arange(mesh.n_nodes)
    if top == "fixed":
        free = free[1:]
    else:
        td = cfg.top_drive
        law = resolve_top_drive(cfg)  # the speed loop; a torque feedback is not modelled
        kp, ki = law.proportional_gain, law.integral_gain
        j[0] += td.inertia
        c[0, 0] += kp
        k[0, 0] += ki
    return k, c, j, free


def torsional_modes(config: SimulationConfig, top: TopBoundary = "fixed",
                    n_modes: int = 6) -> Modes:
    """The lowest torsional modes (module docstring)."""
    k, c, j, free = torsional_system(config, top)
    ix = np.ix_(free, free)
    freq, zeta, shapes = _damped(k[ix], c[ix], j[free], n_modes)
    slow, slow_ratio = overdamped_modes(k[ix], c[ix], j[free],
                                        float(freq[-1]) if len(freq) else math.inf)
    full = np.zeros((len(freq), k.shape[0]))
    full[:, free] = shapes
    depth = build_mesh(config.resolved()).node_depth
    where = "fixed top" if top == "fixed" else "top drive (inertia + PI) at the top"
    feedback = "none" if top == "fixed" else resolve_top_drive(config.resolved()).torque_feedback
    if feedback != "none":  # its filter adds a state the modes leave out
        where = (f"top drive (inertia + PI; its {feedback.replace('_', '-')} torque feedback "
                 "not modelled) at the top")
        warnings.warn(f"top_drive.controller: {config.top_drive.controller}'s torque "
                      f"feedback ({feedback.replace('_', '-')}) is not in the modal model: "
                      "these are the modes of its PI speed loop alone (run the simulator "
                      "for the controller's effect)", UserWarning, stacklevel=2)
    return Modes("torsional", freq, zeta, full, depth, f"{where}, bit free (off bottom)",
                 slow, slow_ratio)


def _lateral_supports(config: SimulationConfig, supports: LateralSupports, top_node: int
                      ) -> np.ndarray:
    """Nodes held at zero lateral displacement: ``top_node``, and with "stabilizers" every
    node below it that is a stabilizer (one of ``string.stabilizers`` at
    ``stabilizer_diameter``, or a component of kind ``stabilizer`` at its own
    ``contact_diameter``), and the bit."""
    from drill_env.physics.simulator import Simulator

    sim = Simulator(config.resolved())
    pinned = [top_node]
    if supports == "stabilizers":
        # string.stabilizer_diameter only where it places stabilizers (else, in a large
        # hole, every collar as tight as its blades would count as one)
        tight = sim.node_clearance <= (sim.config.string.hole_diameter
                                       - sim.config.string.stabilizer_diameter) / 2 + 1e-9
        tight &= bool(sim.config.string.stabilizer_positions)
        # a stabilizer sub touches the wall at its lower node (Simulator): its component
        kinds = np.array([section.kind for section in sim.config.string.sections])
        tight[1:] |= kinds[sim.mesh.component] == "stabilizer"
        stabilized = np.flatnonzero(tight[top_node + 1:-1]) + top_node + 1
        pinned += stabilized.tolist() + [sim.n_nodes - 1]
    return np.asarray(sorted(set(pinned)))


def _below(mesh: Mesh, first_node: int) -> Mesh:
    """The part of ``mesh`` from node ``first_node`` down (its elements from there)."""
    if first_node == 0:
        return mesh
    e = first_node
    return Mesh(node_depth=mesh.node_depth[first_node:], element_length=mesh.element_length[e:],
                bending_stiffness=mesh.bending_stiffness[e:],
                torsional_stiffness=mesh.torsional_stiffness[e:],
                steel_mass=mesh.steel_mass[e:], lateral_mass=mesh.lateral_mass[e:],
                rotary_inertia=mesh.rotary_inertia[e:], polar_inertia=mesh.polar_inertia[e:],
                buoyed_weight=mesh.buoyed_weight[e:], outer_radius=mesh.outer_radius[e:],
                is_bha=mesh.is_bha[e:], contact_radius=mesh.contact_radius[e:],
                component=mesh.component[e:])


def bha_top_node(config: SimulationConfig) -> int:
    """Node where the BHA joins the lowest pipe (``statics.PIPE_KINDS``, and the top
    section whatever its label)."""
    node = 0
    for index, section in enumerate(config.string.sections):
        if not is_pipe(section, top=index == 0):
            return node
        node += section.n_elements
    return node - config.string.sections[-1].n_elements


#: Steepest survey inclination (deg) a vertical hole may show: its survey noise.
VERTICAL_NOISE = 0.5


def _steepest(config: SimulationConfig) -> float:
    """The steepest survey inclination (deg) along the string: of the stations above its
    deepest node and the end of the course that node lies in; 0 for the vertical hole.
    (A well bending only below the string was refused as not vertical, after a warning
    that the string hangs in a vertical hole: a fuzzing walkthrough.)"""
    md, inclination = config.well.md, config.well.inclination
    deepest = max(config.string.length, config.initial_depth or 0.0)
    along = [abs(a) for m, a in zip(md, inclination, strict=True) if m < deepest]
    below = [abs(a) for m, a in zip(md, inclination, strict=True) if m >= deepest][:1]
    return max(along + below, default=0.0)


def require_vertical(config: SimulationConfig) -> None:
    """The modal analysis loads the string by measured depth, as in a vertical hole; a
    deviated well's loads (weight across the hole, contact on the low side) are not in
    it. ValueError naming ``well`` otherwise."""
    steepest = _steepest(config)
    if steepest > VERTICAL_NOISE:
        raise ValueError(f"well: the modal analysis is for vertical holes (axial load by "
                         f"measured depth); this well reaches {steepest:.0f} deg along the "
                         "string. Its static "
                         "loads: drill-env well")


def _lateral_system(cfg: SimulationConfig, weight_on_bit: float, supports: LateralSupports,
                    region: Literal["bha", "string"]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Mesh, int]:
    """(K, K_g, lumped M, free DOFs, mesh, top node) of :func:`lateral_modes`."""
    full = build_mesh(cfg)
    force = axial_force_profile(full, weight_on_bit, bit_buoyed_weight(cfg))
    top_node = bha_top_node(cfg) if region == "bha" else 0
    mesh = _below(full, top_node)  # the BHA alone: pinned at its top, free to tilt there
    k, kg, m = assemble_lateral(mesh, force[top_node:])
    m[-2] += cfg.bit.mass
    n = mesh.n_nodes
    fixed = [2 * (node - top_node) for node in _lateral_supports(cfg, supports, top_node)]
    if cfg.bit.axis_aligned:
        fixed.append(2 * n - 1)  # bit tilt held (paper section 3.1.1)
    free = np.setdiff1d(np.arange(2 * n), fixed)
    return k, kg, m, free, mesh, top_node


def bha_buckles(config: SimulationConfig, weight_on_bit: float) -> bool:
    """Whether ``weight_on_bit`` buckles the straight BHA pinned at its stabilizers and bit
    (:func:`lateral_buckling_weight`'s test at one WOB: one eigenvalue problem); False in
    a curved hole, which this model does not load, and without lateral motion or a wall."""
    cfg = config.resolved()
    if not cfg.solver.lateral or not cfg.contact.enabled or _steepest(cfg) > VERTICAL_NOISE:
        return False
    return not _straight_stable(cfg, weight_on_bit, "stabilizers", "bha")


def _straight_stable(cfg: SimulationConfig, weight_on_bit: float, supports: LateralSupports,
                     region: Literal["bha", "string"]) -> bool:
    """Whether K + K_g(WOB) of :func:`lateral_modes` is positive definite: the straight
    string stable at ``weight_on_bit``."""
    k, kg, _, free, _, _ = _lateral_system(cfg, weight_on_bit, supports, region)
    ix = np.ix_(free, free)
    with one_blas_thread():
        return bool(np.linalg.eigvalsh((k + kg)[ix])[0] > 0.0)


def lateral_buckling_weight(config: SimulationConfig, supports: LateralSupports = "stabilizers",
                            region: Literal["bha", "string"] = "bha") -> float:
    """The WOB (N) at which K + K_g(WOB) of :func:`lateral_modes` stops being positive
    definite (the first lateral buckling load of that model), by bisection to 0.1 %."""
    cfg = config.resolved()

    def stable(wob: float) -> bool:
        return _straight_stable(cfg, wob, supports, region)

    low, high = 0.0, 1.0e5
    while stable(high):
        low, high = high, 2.0 * high
        if high > 1.0e9:
            return math.inf
    while high - low > 1e-3 * high:
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stable(mid) else (low, mid)
    return low


def lateral_modes(config: SimulationConfig, weight_on_bit: float = 0.0,
                  supports: LateralSupports = "stabilizers", n_modes: int = 6,
                  region: Literal["bha", "string"] = "bha") -> Modes:
    """The lowest lateral (bending) modes at ``weight_on_bit`` (module docstring).

    ``region="bha"`` (what BHA design tools analyse) keeps the BHA below the lowest pipe
    (drill pipe, heavy-weight pipe), pinned where it joins the pipe: the tensioned pipe
    above has its own slow string modes (~0.1 Hz for 1000 m), which ``region="string"``
    includes (the whole string pinned at the surface)."""
    cfg = config.resolved()
    require_vertical(cfg)
    k, kg, m, free, mesh, top_node = _lateral_system(cfg, weight_on_bit, supports, region)
    n = mesh.n_nodes
    k = k + kg
    c = cfg.damping.mass_proportional * np.diag(m) + cfg.damping.stiffness_proportional * \
        (k - kg)
    ix = np.ix_(free, free)
    with one_blas_thread():
        lowest = np.linalg.eigvalsh(k[ix])[0]
    if lowest <= 0.0:
        limit = lateral_buckling_weight(cfg, supports, region)
        raise ValueError(f"weight_on_bit: {weight_on_bit / 1e3:.0f} kN buckles the "
                         f"{'BHA' if region == 'bha' else 'string'} (K + K_g is not positive "
                         f"definite: a static mode has replaced the lowest lateral mode); "
                         f"its lateral modes exist below {limit / 1e3:.0f} kN"
                         + (" (a buckled BHA drills on: the simulation bends it against "
                            "the wall, where modes of the straight string do not hold)"
                            if region == "bha" else ""))
    freq, zeta, shapes = _damped(k[ix], c[ix], m[free], n_modes)
    slow, slow_ratio = overdamped_modes(k[ix], c[ix], m[free],
                                        float(freq[-1]) if len(freq) else math.inf)
    dofs = np.zeros((len(freq), 2 * n))
    dofs[:, free] = shapes
    displacement = dofs[:, 0::2]
    displacement /= np.maximum(np.max(np.abs(displacement), axis=1, keepdims=True), 1e-300)
    where = ("BHA pinned below the pipe" if region == "bha" else "top pinned") + (
        ", stabilizers and bit pinned" if supports == "stabilizers" else "")
    return Modes("lateral", freq, zeta, displacement, mesh.node_depth,
                 f"{where}, WOB {weight_on_bit / 1e3:.0f} kN", slow, slow_ratio)


def undamped_frequencies(k: np.ndarray, m: np.ndarray, n_modes: int) -> np.ndarray:
    """The ``n_modes`` lowest natural frequencies (Hz) of ``K phi = w^2 diag(m) phi``."""
    with one_blas_thread():
        w2 = scipy.linalg.eigh(k, np.diag(m), eigvals_only=True,
                               subset_by_index=[0, n_modes - 1])
    return np.sqrt(np.maximum(w2, 0.0)) / (2 * math.pi)


@dataclass(frozen=True)
class CriticalSpeed:
    """A rotary speed where an excitation meets a natural frequency."""

    rpm: float
    frequency: float  # Hz
    mode: str  # e.g. "lateral 1"
    excitation: str  # "1x", "6x (blades)", "backward whirl (collars)"


def excitations(config: SimulationConfig, kind: str = "lateral") -> list[tuple[str, float]]:
    """(name, excitation frequency per rev/s) of a rotating string. Lateral modes: 1x
    (imbalance, a bent collar), the blade count (the bit's blades passing), and backward
    whirl of the bit and of the largest BHA body rolling on the wall (of those that touch
    it with their body: a stabilizer's blades do not roll). Torsional modes:
    the blade count (the bit's torque fluctuating as the blades pass)."""
    cfg = config.resolved()
    if kind == "torsional":
        return [(f"{cfg.bit.n_blades}x (blades)", float(cfg.bit.n_blades))]
    out = [("1x", 1.0), (f"{cfg.bit.n_blades}x (blades)", float(cfg.bit.n_blades))]
    hole = cfg.string.hole_diameter / 2
    bit_radius = cfg.bit.gauge_radius
    out.append(("backward whirl (bit)", bit_radius / cfg.bit.gauge_clearance))
    # a stabilizer touches with its blades, not its body (a new user's trial: a stabilizer
    # whose body tied with the collars' named the line and gave the collars' ratio)
    rolling = [s for s in cfg.string.lower if s.wall_diameter == s.outer_diameter]
    body = max(rolling or cfg.string.lower, key=lambda s: s.outer_diameter)
    clearance = hole - body.outer_diameter / 2
    out.append((f"backward whirl ({body.label})", body.outer_diameter / 2 / clearance))
    return out


def excitation_label(name: str, per_rev: float) -> str:
    """The chart's label of an :func:`excitations` line: its name, and for a backward
    whirl (whose name does not say it) how many times per revolution it excites,
    ``"backward whirl (bit): 21.2x"``."""
    return f"{name}: {per_rev:.3g}x" if name.startswith("backward whirl") else name


def critical_speeds(config: SimulationConfig, modes: Sequence[Modes],
                    max_rpm: float = 300.0) -> list[CriticalSpeed]:
    """Every speed up to ``max_rpm`` where an :func:`excitations` line crosses a mode."""
    out = []
    for m in modes:
        for i, f in enumerate(m.frequency):
            for name, per_rev in excitations(config, m.kind):
                rpm = 60.0 * f / per_rev
                if 0.0 < rpm <= max_rpm:
                    out.append(CriticalSpeed(rpm, float(f), f"{m.kind} {i + 1}", name))
    return sorted(out, key=lambda c: c.rpm)


#: The most modes the critical-speed chart draws (the lowest, both kinds together): each
#: is labelled at its own line, which more lines than this leave no room for on the
#: page; the printed table and modes.json list them all.
CHART_MODES = 24
_LABEL: dict[str, Any] = {"fontsize": 7, "bbox": {"fc": "white", "ec": "none", "pad": 0.3}}
#: Pixels between a mode label and the one beside it (close frequencies: the labels
#: stand in columns, the gap showing the right one's line).
MODE_LABEL_GAP = 16.0


def critical_speed_chart(config: SimulationConfig, modes: Sequence[Modes], path,
                         max_rpm: float = 300.0, title: str = "") -> None:
    """The chart BHA design tools show: natural frequencies (horizontal lines) against
    rotary speed, with the excitation lines; the circles are the critical speeds."""
    fig = critical_speed_figure(config, modes, max_rpm, title)
    fig.savefig(path, dpi=120)


def chart_cutoff(config: SimulationConfig, modes: Sequence[Modes], max_rpm: float) -> float:
    """The highest frequency (Hz) :func:`critical_speed_figure` draws: that of the
    ``CHART_MODES``-th lowest mode, and none above the fastest excitation at ``max_rpm``
    (no higher mode is critical in the chart's range), though always the lowest mode."""
    freqs = np.sort(np.concatenate([m.frequency for m in modes] + [np.zeros(0)]))
    if not len(freqs):
        return 0.0
    ceiling = max(per_rev for m in modes for _, per_rev in excitations(config, m.kind)) \
        * max_rpm / 60.0
    return float(min(freqs[min(len(freqs), CHART_MODES) - 1], max(ceiling, freqs[0])))


def critical_speed_figure(config: SimulationConfig, modes: Sequence[Modes],
                          max_rpm: float = 300.0, title: str = "") -> Any:
    """The matplotlib ``Figure`` of :func:`critical_speed_chart`, laid out (not pyplot's:
    the process's backend is left as it is).

    The modes up to :func:`chart_cutoff` (the title says how many more there are, the
    frequencies above it are shaded), each
    labelled on its own line (the label breaks it) at the right edge or, where a close
    mode's label holds that place, in a column further left. Each excitation line runs
    into its label: in a band above the modes (the steeper a line, the higher its
    label, so that no line crosses another's label), or, for a line that leaves through
    the right edge, just above the line beyond its last critical speed and off the mode
    lines, the line ending there. No label covers a critical speed (the circles)."""
    from drill_env.figures import agg_figure

    cutoff = chart_cutoff(config, modes, max_rpm)
    fig = agg_figure(figsize=(10, 6.5))
    ax = fig.subplots()
    styles = {"lateral": ("tab:blue", "-"), "torsional": ("tab:red", "--")}
    mode_labels, mode_lines = [], []
    for m in modes:
        color, line = styles.get(m.kind, ("k", ":"))
        for i, f in enumerate(m.frequency.tolist()):
            if f <= cutoff:
                mode_lines.append(ax.axhline(
                    f, color=color, ls=line, lw=1.0, gid="mode line",
                    label=f"{m.kind} modes: {m.boundary}" if i == 0 else None))
                mode_labels.append(ax.text(max_rpm, f, f"{m.kind[0].upper()}{i + 1} {f:.2f} Hz",
                                           color=color, ha="right", va="center",
                                           gid="mode label", **_LABEL))
    lines: dict[str, float] = {}
    for m in modes:
        lines.update(excitations(config, m.kind))
    drawn = {name: ax.plot([0.0, max_rpm], [0.0, per_rev * max_rpm / 60.0], color="0.35",
                           lw=0.8, gid=f"excitation: {name}")[0]
            for name, per_rev in lines.items()}
    crit = [c for c in critical_speeds(config, modes, max_rpm) if c.frequency <= cutoff]
    for cs in crit:
        ax.plot(cs.rpm, cs.frequency, "o", ms=4, mfc="none", color="k", gid="critical speed")
    total = sum(len(m.frequency) for m in modes)
    if len(mode_labels) < total:
        title = (title or "Critical-speed chart") + (
            f"\n(the {len(mode_labels)} lowest of {total} modes; those above {cutoff:.2f} Hz, "
            "shaded, are in the table)")
    ax.set_xlim(0, max_rpm)
    ax.set_ylim(0, 1.2 * max(cutoff, 1e-3))
    ax.set_xlabel("rotary speed (rpm)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(title or "Critical-speed chart", fontsize=10)
    # below the axes: inside it would cover the excitations' labels or the modes'
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), fontsize=7, ncol=2,
              frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _lay_out_labels(fig, ax, list(zip(mode_labels, mode_lines, strict=True)), drawn, lines,
                    [(c.rpm, c.frequency) for c in crit], max(cutoff, 1e-3))
    if len(mode_labels) < total:  # the band above the modes holds labels, not the rest
        ax.axhspan(cutoff, ax.get_ylim()[1], color="0.92", lw=0, zorder=0,
                   gid="modes not drawn")
    return fig


def _crosses(p0: np.ndarray, p1: np.ndarray, box: Any) -> bool:
    """Whether the segment ``p0``-``p1`` (pixels) passes through ``box`` (Liang-Barsky
    clipping)."""
    t0, t1 = 0.0, 1.0
    d = p1 - p0
    for p, q in ((-d[0], p0[0] - box.x0), (d[0], box.x1 - p0[0]),
                 (-d[1], p0[1] - box.y0), (d[1], box.y1 - p0[1])):
        if p == 0.0:
            if q < 0.0:
                return False
        elif p < 0.0:
            t0 = max(t0, q / p)
        else:
            t1 = min(t1, q / p)
    return t0 <= t1


def _lay_out_labels(fig: Any, ax: Any, modes: list[tuple[Any, Any]], drawn: dict[str, Any],
                    lines: dict[str, float], circles: list[tuple[float, float]],
                    f_top: float) -> None:
    """Place the labels of :func:`critical_speed_figure` (its docstring), in pixels of
    the laid-out figure: first the top of the y axis, which leaves a band above the
    highest mode with a row for each excitation's label. ``modes``: (label, line) of
    each mode; a line ends at its label, so that one moved left of a close mode's label
    does not run on under it."""
    from matplotlib.transforms import Bbox

    mode_labels = [text for text, _ in modes]
    renderer = fig.canvas.get_renderer()
    height = (mode_labels[0] if mode_labels else ax.title).get_window_extent(renderer).height
    row = height + 3.0
    band = height / 2 + 3.0 + len(lines) * row + 3.0
    span = ax.bbox.height
    ax.set_ylim(0.0, f_top * span / max(span - band, 0.5 * span))
    fig.tight_layout()
    span = ax.bbox.height
    ax.set_ylim(0.0, f_top * span / max(span - band, 0.5 * span))
    to_px = ax.transData.transform
    to_data = ax.transData.inverted().transform
    frame = ax.bbox
    dots = [Bbox.from_bounds(x - 4.0, y - 4.0, 8.0, 8.0) for x, y in to_px(circles)] \
        if circles else []
    taken: list[Any] = []  # the label boxes placed so far

    def put(text: Any, xy_px: Any, **align: str) -> Any:
        text.set_position(to_data(xy_px))
        text.set(**align)
        return text.get_window_extent(renderer).padded(1.0)

    def free(box: Any) -> bool:
        return (frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0
                and box.y1 <= frame.y1 and not any(box.overlaps(b) for b in taken + dots))

    # modes: at the right edge, else in the first column to the left with room (a
    # column apart: the gap shows the other label's line running into it)
    column = max((t.get_window_extent(renderer).width for t in mode_labels),
                 default=0.0) + MODE_LABEL_GAP
    for text, line in sorted(modes, key=lambda m: m[0].get_position()[1]):
        y = max(to_px((0.0, text.get_position()[1]))[1], frame.y0 + height / 2 + 2.0)
        boxes = (put(text, (frame.x1 - 3.0 - c * column, y)) for c in range(12))
        box = next((b for b in boxes if free(b)), None) or put(text, (frame.x1 - 3.0, y))
        taken.append(box)
        # axes fraction; under the label's left end (its right end showed past the
        # text's white box)
        line.set_xdata([0.0, (box.x0 + 3.0 - frame.x0) / frame.width])

    origin = to_px((0.0, 0.0))
    ends = {name: to_px(line.get_xydata()[-1]) for name, line in drawn.items()}

    def clear(box: Any, name: str, end: np.ndarray | None = None) -> bool:
        """``box`` free and crossed by no other excitation line; its own line, ending
        at ``end`` (None: where it leaves the plot), crossing no label."""
        return free(box) and not any(_crosses(origin, e, box) for n, e in ends.items()
                                     if n != name) \
            and (end is None or not any(_crosses(origin, end, b) for b in taken))

    texts = {name: ax.text(0.0, 0.0, excitation_label(name, per_rev), color="0.25",
                           gid="excitation label", **_LABEL)
             for name, per_rev in lines.items()}
    rows = to_px((0.0, f_top))[1] + height / 2 + 3.0 + (np.arange(len(lines)) + 0.5) * row

    def in_band(name: str) -> bool:
        """Label ``name`` in the lowest row of the band where it is clear: right of where
        its line reaches the row, else left of it (above the line), the line ending
        there. False where no row has room."""
        slope = (to_px((60.0, lines[name]))[1] - origin[1]) / (to_px((60.0, 0.0))[0] - origin[0])
        for y in rows:
            end = np.array([origin[0] + (y - origin[1]) / slope, y])
            low = np.array([origin[0] + (y - height / 2 - origin[1]) / slope, y - height / 2])
            for spot, corner, align in (((end[0] + 3.0, y), end, ("left", "center")),
                                        ((low[0] - 3.0, low[1] + 1.0), low, ("right", "bottom"))):
                box = put(texts[name], spot, ha=align[0], va=align[1])
                if clear(box, name, corner):
                    ends[name] = corner
                    drawn[name].set_data(*np.transpose(to_data([origin, corner])))
                    taken.append(box)
                    return True
        return False

    # the mode lines as drawn (pixels): height, right end (they end at their labels)
    mode_rows = [(to_px((0.0, line.get_ydata()[0]))[1],
                  frame.x0 + line.get_xdata()[1] * frame.width) for _, line in modes]
    dot_px = to_px(circles) if circles else np.zeros((0, 2))

    def off_modes(box: Any) -> bool:
        """``box`` crossed by no mode line."""
        return not any(box.y0 < y < box.y1 and box.x0 < right for y, right in mode_rows)

    # the least steep first: a steeper line's label then goes above the others' ends
    unplaced = [name for name in sorted(lines, key=lines.__getitem__) if not in_band(name)]
    for name in unplaced:  # above its line, short of where it leaves the plot
        right = ax.get_xlim()[1]
        far = to_px((right, lines[name] * right / 60.0))
        reach = min(1.0, (frame.y1 - origin[1]) / max(far[1] - origin[1], 1e-9))
        # the line ends at its label, beyond its last critical speed
        slope = (far[1] - origin[1]) / (far[0] - origin[0])
        own = [x for x, y in dot_px if abs(origin[1] + slope * (x - origin[0]) - y) < 1.0]
        last = max(own, default=origin[0])
        corners = [origin + t * (far - origin)  # on the line: a label's lower right
                   for t in np.linspace(0.97, 0.15, 42) * reach]
        placed = None
        for corner in corners:
            if corner[0] < last + 6.0:
                break
            box = put(texts[name], corner + (-3.0, 3.0), ha="right", va="bottom")
            if clear(box, name, corner) and off_modes(box):
                ends[name] = corner
                drawn[name].set_data(*np.transpose(to_data([origin, corner])))
                placed = box
                break
        if placed is None:  # no such room: the first spot free of labels, the line whole
            boxes = (put(texts[name], c + (-3.0, 3.0), ha="right", va="bottom")
                     for c in corners)
            placed = next((b for b in boxes if clear(b, name)), None) \
                or put(texts[name], corners[0] + (-3.0, 3.0))
        taken.append(placed)

