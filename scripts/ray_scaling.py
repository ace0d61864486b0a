"""Ray scaling on this machine: speed-up from 1 to 2 worker nodes, per-task overhead.

    .venv/bin/python scripts/ray_scaling.py [--tasks 12] [--seconds 30] [--repeats 2]

Starts a local cluster (``ray.cluster_utils.Cluster``: a head without CPUs and one-CPU
worker nodes, separate processes, joined by address like a remote cluster) and runs
stability-map points (``--seconds`` of simulated time each, the map's default) through
:class:`drill_env.distributed.RayExecutor`:

- compute: one point in this process, after a warm-up (numba cache loaded);
- 1 worker and 2 workers: the wall time of ``--tasks`` points, measured in turns
  (1, 2, 1, 2, ...: the machine is shared, so compare within the run; min and median);
- overhead: the wall time per task of a no-op task on one worker (submission,
  scheduling, result transfer), against the point's compute time.

Prints a table and writes ``logs/ray_scaling.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from ray.cluster_utils import Cluster

from drill_env.distributed import RayExecutor
from drill_env.stability_map import MapSettings, _point_task, map_config


def noop(x: int) -> int:
    return x


def timed(executor: RayExecutor, fn, items) -> float:
    t0 = time.perf_counter()
    for _ in executor.map_unordered(fn, items):
        pass
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", type=int, default=12)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("logs/ray_scaling.json"))
    args = parser.parse_args()

    settings = MapSettings(seconds=args.seconds, measure=min(10.0, args.seconds))
    config = map_config("P4")
    # fast, light points: no stick-slip, so each runs its whole simulated time
    points = [(config, 150.0 + 10.0 * (k % 6), 30e3 + 5e3 * (k // 6), settings)
              for k in range(args.tasks)]
    _point_task(points[0])  # compile / load the cache
    compute = []
    for item in points[:3]:
        t0 = time.perf_counter()
        _point_task(item)
        compute.append(time.perf_counter() - t0)
    per_task = min(compute)

    cluster = Cluster(initialize_head=True,
                      head_node_args={"num_cpus": 0, "include_dashboard": False})
    nodes = [cluster.add_node(num_cpus=1)]
    cluster.wait_for_nodes()
    walls: dict[int, list[float]] = {1: [], 2: []}
    overhead = []
    try:
        for _ in range(args.repeats):
            for n in (1, 2):
                while len(nodes) < n:
                    nodes.append(cluster.add_node(num_cpus=1))
                while len(nodes) > n:
                    cluster.remove_node(nodes.pop())
                cluster.wait_for_nodes()
                executor = RayExecutor(cluster.address)
                timed(executor, _point_task, points[:n])  # start and warm the workers
                walls[n].append(timed(executor, _point_task, points))
                if n == 1:
                    calls = 200
                    overhead.append(timed(executor, noop, list(range(calls))) / calls)
                executor.close()
    finally:
        cluster.shutdown()

    result = {
        "tasks": args.tasks, "simulated_s_per_task": args.seconds,
        "compute_s_per_task_in_process": per_task,
        "wall_s_1_worker": walls[1], "wall_s_2_workers": walls[2],
        "speedup_min": min(walls[1]) / min(walls[2]),
        "speedup_median": statistics.median(walls[1]) / statistics.median(walls[2]),
        "overhead_s_per_task": min(overhead),
        "overhead_share_of_compute": min(overhead) / per_task,
        "ray_s_per_task_1_worker": min(walls[1]) / args.tasks,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))
    print(f"{args.tasks} stability-map points of {args.seconds:g} s simulated each")
    print(f"  compute per point in this process   {per_task:8.3f} s")
    print(f"  1 worker: wall (min / median)        {min(walls[1]):8.2f} / "
          f"{statistics.median(walls[1]):.2f} s  ({result['ray_s_per_task_1_worker']:.3f} s "
          "per point)")
    print(f"  2 workers: wall (min / median)       {min(walls[2]):8.2f} / "
          f"{statistics.median(walls[2]):.2f} s")
    print(f"  speed-up 1 -> 2 workers (min / median) {result['speedup_min']:6.2f} / "
          f"{result['speedup_median']:.2f}")
    print(f"  overhead per task (no-op task)       {min(overhead) * 1e3:8.2f} ms = "
          f"{100 * result['overhead_share_of_compute']:.2f} % of a point's compute")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
