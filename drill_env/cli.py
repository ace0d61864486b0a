"""Command line: ``drill-env <command>`` (or ``python -m drill_env.cli <command>``).

Commands
--------
demo        the main job on the built-in default case: the paper's string drilling hard
            rock at 50 and 100 rpm (stick-slip vs steady), plus a crossing of the
            hard-soft-hard sandwich; prints a table, writes plots and JSON to ``logs/``.
run         one episode of ``DrillString-v0`` with a constant-RPM controller, optionally
            recorded to rerun.
benchmark   speed and memory figures: real-time factor and speed-up over NumPy, env
            steps/s (single, looped, batched), cost scaling with the mesh, compile time,
            memory per env; prints tables, writes ``benchmark.json`` (docs/performance.md).
stability-map
            torsional stability maps of the paper's bit positions P1-P6 (Fig. 15) by
            boundary tracking; prints a table, writes ``stability_map.png`` and
            ``stability_map.json``.
replay      open a ``.rrd`` recording in the rerun viewer (``--web`` for the web viewer).

SI inside; rpm and kN only here at the edge.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from drill_env.studies import COL, RPM


def demo(out: Path) -> int:
    """Paper section 4, case 1 at 100 kN: stick-slip at 50 rpm, steady at 100 rpm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drill_env.physics.config import FormationConfig, SimulationConfig, SolverConfig
    from drill_env.scenarios import HARD
    from drill_env.studies import simulate, stick_slip_summary

    out.mkdir(parents=True, exist_ok=True)
    # Paper case 1 is a torsional study: lateral DOFs frozen (see docs/model.md, "Axial
    # load and buckling" for why the coupled 35 m BHA is not used at 100 kN).
    config = SimulationConfig(formation=FormationConfig(rocks=(HARD,)),
                              solver=SolverConfig(lateral=False))
    wob, seconds = 100e3, 60.0
    rows, runs = [], {}
    t0 = time.perf_counter()
    for rpm in (50.0, 100.0):
        tic = time.perf_counter()
        run = simulate(config, rpm, wob, seconds, progress=f"{rpm:.0f} rpm")
        wall = time.perf_counter() - tic
        runs[rpm] = run
        window = run.window(seconds / 2)
        bit = window[:, COL["bit_speed"]]
        rows.append({
            "rpm": rpm,
            "wob_kN": wob / 1e3,
            **stick_slip_summary(run, seconds / 2),
            "bit_rpm_min": float(bit.min() / RPM),
            "bit_rpm_max": float(bit.max() / RPM),
            "mean_tob_kNm": float(window[:, COL["torque_on_bit"]].mean() / 1e3),
            "rop_m_per_h": float(window[:, COL["rop"]].mean() * 3600),
            "real_time_factor": seconds / wall,
            "status": run.status or "ok",
        })
    header = (f"{'rpm':>5} {'SSI':>6} {'stuck':>6} {'bit rpm min-max':>16} "
              f"{'TOB kN m':>9} {'ROP m/h':>8} {'x real time':>11}")
    print("Default string (1000 m DP + 35 m BHA), mesoscopic bit, hard rock, WOB 100 kN, "
          "torsional dynamics (paper case 1)")
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r['rpm']:5.0f} {r['ssi']:6.2f} {r['stuck_fraction']:6.2f} "
              f"{r['bit_rpm_min']:7.1f} - {r['bit_rpm_max']:6.1f} {r['mean_tob_kNm']:9.2f} "
              f"{r['rop_m_per_h']:8.2f} {r['real_time_factor']:11.0f}")
    verdict = rows[0]["ssi"] > 0.8 and rows[1]["ssi"] < 0.2
    print(f"paper result 1 (stick-slip at 50 rpm, none at 100 rpm): "
          f"{'reproduced' if verdict else 'NOT reproduced'}")

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, rpm in zip(axes, (50.0, 100.0), strict=True):
        run = runs[rpm]
        ax.plot(run.time, run.channel("bit_speed") / RPM, lw=0.8, label="bit")
        ax.plot(run.time, run.channel("surface_speed") / RPM, lw=0.8, label="surface")
        ax.set_ylabel("speed (rpm)")
        ax.set_title(f"{rpm:.0f} rpm set point, WOB 100 kN, hard rock")
        ax.legend(loc="upper right")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out / "demo_stick_slip.png", dpi=120)
    plt.close(fig)
    (out / "demo_summary.json").write_text(json.dumps(rows, indent=2))
    print(f"wrote {out / 'demo_stick_slip.png'} and {out / 'demo_summary.json'} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0 if verdict else 1


def run(scenario: str, rpm: float | None, wob: float | None, seed: int,
        duration: float | None, fidelity: str, record: Path | None, out: Path) -> int:
    """One episode under a constant set point; prints its metrics, writes JSON to ``out``."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the ids)
    from agents.policies import ConstantSetpoint
    from drill_env.benchmark import _progress

    kwargs: dict = {"scenario": scenario, "fidelity": fidelity}
    if duration is not None:
        kwargs["episode_duration"] = duration
    env = gym.make("DrillString-v0", **kwargs)
    base = env.unwrapped
    rpm = rpm if rpm is not None else base.scenario.surface_speed / RPM
    wob_n = wob * 1e3 if wob is not None else base.scenario.weight_on_bit
    cfg = base.config
    policy = ConstantSetpoint(rpm, wob_n, cfg.rpm_range, cfg.weight_on_bit_range)
    if record is not None:
        from drill_env.recording import RecordEpisode

        env = RecordEpisode(env, record)
    t0 = time.perf_counter()
    obs, info = env.reset(seed=seed, options={"surface_speed": rpm * RPM,
                                              "weight_on_bit": wob_n})
    policy.reset()
    totals: dict[str, float] = {}
    keys = ("ssi", "stuck_fraction", "whirl_ratio", "radial_ratio", "lateral_force", "rop")
    steps, reward, reason = 0, 0.0, ""
    for _ in _progress(range(base.max_episode_steps), f"{scenario} {rpm:.0f} rpm", True):
        obs, r, terminated, truncated, info = env.step(policy.act(obs, info))
        steps += 1
        reward += r
        for key in keys:
            totals[key] = totals.get(key, 0.0) + info[key]
        if terminated or truncated:
            reason = info["termination_reason"]
            break
    summary = {
        "scenario": scenario, "rpm": rpm, "weight_on_bit": wob_n, "seed": seed,
        "fidelity": fidelity, "steps": steps, "simulated_s": info["episode_time"],
        "return": reward, "termination_reason": reason,
        **{f"mean_{key}": totals[key] / max(steps, 1) for key in keys},
        "wall_s": time.perf_counter() - t0,
    }
    if record is not None:
        summary["recording"] = str(env.last_path) if env.last_path else None
    env.close()
    out.mkdir(parents=True, exist_ok=True)
    (out / "run_summary.json").write_text(json.dumps(summary, indent=2))
    print(f"{scenario}: {steps} steps ({summary['simulated_s']:.1f} s) at {rpm:.0f} rpm, "
          f"{wob_n / 1e3:.0f} kN in {summary['wall_s']:.1f} s; return {reward:.2f}"
          + (f"; terminated: {reason}" if reason else ""))
    print(f"  mean over the episode: SSI {summary['mean_ssi']:.2f}, stuck "
          f"{summary['mean_stuck_fraction']:.2f}, whirl ratio {summary['mean_whirl_ratio']:.2f}"
          f", radial ratio {summary['mean_radial_ratio']:.2f}, lateral force "
          f"{summary['mean_lateral_force'] / 1e3:.1f} kN, ROP {summary['mean_rop'] * 3600:.1f}"
          " m/h")
    if record is not None:
        print(f"  recording: {summary['recording']} (drill-env replay <file>)")
    print(f"wrote {out / 'run_summary.json'}")
    return 0


def stability_map(positions: str, rpm_step: float, wob_step: float, max_rpm: float,
                  max_wob: float, seconds: float, out: Path) -> int:
    """Maps of ``positions`` (comma-separated); wob in kN here, N inside."""
    from drill_env import stability_map as sm

    names = tuple(p.strip() for p in positions.split(",") if p.strip())
    settings = sm.MapSettings(seconds=seconds, measure=min(sm.MapSettings.measure, seconds))
    t0 = time.perf_counter()
    maps = sm.stability_maps(names, rpm_step, wob_step * 1e3, settings, max_rpm,
                             max_wob * 1e3, progress=True)
    print(sm.format_maps(maps))
    runs = sum(m.runs for m in maps)
    cells = sum(m.unstable.size for m in maps)
    print(f"{runs} simulations of {seconds:.0f} s for {cells} grid points (boundary tracking)"
          f" in {time.perf_counter() - t0:.1f} s")
    paths = sm.write_maps(maps, out, settings)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def benchmark(out: Path, quick: bool, sections: str | None) -> int:
    from drill_env.benchmark import FULL, QUICK, SECTIONS, parse_sections, run_benchmark

    run_benchmark(parse_sections(sections) if sections else SECTIONS, QUICK if quick else FULL,
                  out)
    return 0


def replay(path: Path, web: bool) -> int:
    from drill_env.recording import replay as open_viewer

    open_viewer(path, web=web)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="drill-env", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help="main job on the default case; outputs in logs/")
    p.add_argument("--out", type=Path, default=Path("logs"))
    p = sub.add_parser("run", help="one episode under a constant set point; optional rerun "
                                   "recording")
    p.add_argument("--scenario", default="default",
                   help="a scenario name (drill_env.scenarios.SCENARIOS)")
    p.add_argument("--rpm", type=float, default=None,
                   help="surface speed set point (default: the scenario's)")
    p.add_argument("--wob", type=float, default=None,
                   help="weight on bit in kN (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=None,
                   help="episode length in simulated s (default: the scenario's)")
    p.add_argument("--fidelity", choices=("full", "fast"), default="full")
    p.add_argument("--record", type=Path, default=None, nargs="?", const=Path("logs/recordings"),
                   help="write a rerun .rrd of the episode into this folder "
                        "(default folder: logs/recordings)")
    p.add_argument("--out", type=Path, default=Path("logs"), help="folder for run_summary.json")
    p = sub.add_parser("benchmark", help="speed and memory figures; benchmark.json in --out")
    p.add_argument("--out", type=Path, default=Path("logs"),
                   help="folder for benchmark.json, benchmark.md, benchmark_scaling.png")
    p.add_argument("--quick", action="store_true", help="short runs (smoke test, < 1 min)")
    p.add_argument("--sections", default=None,
                   help="comma-separated subset of core,env,scaling,compile,memory (default: all)")
    p = sub.add_parser("stability-map", help="torsional stability maps P1-P6 (paper Fig. 15)")
    p.add_argument("--positions", default="P1,P2,P3,P4,P5,P6",
                   help="comma-separated bit positions (default: all six)")
    p.add_argument("--rpm-step", type=float, default=5.0, help="speed step (rpm)")
    p.add_argument("--wob-step", type=float, default=5.0, help="WOB step (kN)")
    p.add_argument("--max-rpm", type=float, default=250.0)
    p.add_argument("--max-wob", type=float, default=200.0, help="kN")
    p.add_argument("--seconds", type=float, default=30.0,
                   help="simulated seconds per grid point")
    p.add_argument("--out", type=Path, default=Path("logs"),
                   help="folder for stability_map.png and stability_map.json")
    p = sub.add_parser("replay", help="open a .rrd in the rerun viewer")
    p.add_argument("path", type=Path)
    p.add_argument("--web", action="store_true", help="serve the web viewer")
    args = parser.parse_args(argv)
    if args.command == "demo":
        return demo(args.out)
    if args.command == "run":
        from drill_env.scenarios import SCENARIOS

        if args.scenario not in SCENARIOS:
            parser.error(f"--scenario: unknown {args.scenario!r}; known: {sorted(SCENARIOS)}")
        try:
            return run(args.scenario, args.rpm, args.wob, args.seed, args.duration,
                       args.fidelity, args.record, args.out)
        except ValueError as err:  # a bad set point or duration, named by the env
            parser.error(str(err))
    if args.command == "stability-map":
        try:
            return stability_map(args.positions, args.rpm_step, args.wob_step, args.max_rpm,
                                 args.max_wob, args.seconds, args.out)
        except ValueError as err:  # a bad position, step or duration, named
            parser.error(str(err))
    if args.command == "benchmark":
        if args.sections:
            from drill_env.benchmark import parse_sections

            try:
                parse_sections(args.sections)
            except ValueError as err:
                parser.error(str(err))
        return benchmark(args.out, args.quick, args.sections)
    if args.command == "replay":
        return replay(args.path, args.web)
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
