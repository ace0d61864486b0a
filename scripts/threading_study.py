"""Which threading set-up keeps PPO training fast when the machine is shared?

    .venv/bin/python scripts/threading_study.py [--steps 8192] [--rounds 2]

The batched env steps all envs' physics in one numba ``prange`` call; between two calls
the serial Python (policy, VecNormalize, SB3 bookkeeping) runs. With numba's OpenMP
layer (GNU libgomp) the idle workers spin-wait before sleeping, which costs nothing on
an idle machine and steals the core from anyone else on a shared one. This script
trains PPO (task 1's hyperparameters, 8 batched envs) in a fresh process per set-up:

=================  ========================================================
``omp``            numba's default layer here (OpenMP), libgomp's default wait
``omp-passive``    OpenMP with ``OMP_WAIT_POLICY=PASSIVE`` (workers sleep at once),
                   what ``import drill_env`` sets unless the user set the variable
``workqueue``      numba's own thread pool (no spinning)
``omp-1thread``    OpenMP, one numba thread (no parallel physics)
``passive-torch1`` OpenMP passive, torch held at one thread by the training
                   callback (``TrainConfig.torch_threads = 1``, as ``drill-env
                   train`` holds it); the default until 2026-12-04; the set-ups
                   above leave torch at its own count (``torch_threads = 0``)
``spin30k-torch1`` as ``passive-torch1``, but libgomp's workers spin ~0.3 ms
                   (``GOMP_SPINCOUNT=30000``) before they sleep
``tbb-torch1``     as ``passive-torch1``, with numba's TBB layer (oneTBB's
                   workers) for the batched physics: the default since
                   2026-12-04 (``import drill_env`` loads the ``tbb`` package's
                   library); OpenMP's passive wait still governs torch
=================  ========================================================

quiet and with one competing CPU-bound process, in turns (``--rounds``), and prints env
steps/s (wall) and CPU seconds per 1,000 env steps (min over rounds); writes
``logs/threading_study.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

SETUPS = {
    # an empty OMP_WAIT_POLICY is libgomp's default wait, and keeps drill_env from
    # setting PASSIVE (it only fills in an absent variable)
    "omp": {"NUMBA_THREADING_LAYER": "omp", "OMP_WAIT_POLICY": ""},
    "omp-passive": {"NUMBA_THREADING_LAYER": "omp"},  # drill_env's default
    "workqueue": {"NUMBA_THREADING_LAYER": "workqueue", "OMP_WAIT_POLICY": ""},
    "omp-1thread": {"NUMBA_THREADING_LAYER": "omp", "NUMBA_NUM_THREADS": "1",
                    "OMP_WAIT_POLICY": ""},
    "passive-torch1": {"NUMBA_THREADING_LAYER": "omp", "STUDY_TORCH_THREADS": "1"},
    # libgomp spins GOMP_SPINCOUNT times (~100 per us) before sleeping; the variable
    # wins over OMP_WAIT_POLICY. 30000: ~0.3 ms, about the serial gap between two
    # batched steps of 16 plain envs
    "spin30k-torch1": {"NUMBA_THREADING_LAYER": "omp", "GOMP_SPINCOUNT": "30000",
                       "STUDY_TORCH_THREADS": "1"},
    # Intel's oneTBB (the ``tbb`` wheel, which puts libtbb.so.12 in the environment's
    # lib/, off the loader's path) for numba's parallel calls; torch stays on OpenMP
    "tbb-torch1": {"NUMBA_THREADING_LAYER": "tbb", "STUDY_TORCH_THREADS": "1",
                   "LD_LIBRARY_PATH": str(Path(sys.prefix) / "lib")},
}


def child(steps: int) -> None:
    import drill_env  # noqa: F401, I001  (first, as in drill-env train: before torch's OpenMP)
    import numba
    import torch

    from training.config import load_config
    from training.train import make_train_env, new_model
    from training.callbacks import torch_threads_callback

    config = load_config("stick_slip", "ppo")
    model = new_model(config, make_train_env(config, 0))
    threads = int(os.environ.get("STUDY_TORCH_THREADS", "0"))
    callback = torch_threads_callback(threads) if threads else None
    model.learn(4096, callback=callback)  # compile / load caches, first update
    wall, cpu = time.perf_counter(), time.process_time()
    model.learn(steps, reset_num_timesteps=False, callback=callback)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(json.dumps({"steps_per_s": steps / wall, "cpu_s_per_1000": 1e3 * cpu / steps,
                      "layer": numba.threading_layer(), "numba_threads":
                      numba.get_num_threads(), "torch_threads": torch.get_num_threads()}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=8192)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--setups", default=",".join(SETUPS),
                        help="comma-separated subset of: " + ", ".join(SETUPS))
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=Path("logs/threading_study.json"))
    args = parser.parse_args()
    if args.child:
        child(args.steps)
        return
    setups = {name: SETUPS[name] for name in args.setups.split(",")}
    results: dict[str, dict[str, list[dict]]] = {s: {"quiet": [], "loaded": []}
                                                 for s in setups}
    for _ in range(args.rounds):
        for load in ("quiet", "loaded"):
            hog = (subprocess.Popen([sys.executable, "-c", "while True: pass"])
                   if load == "loaded" else None)
            try:
                for name, env in setups.items():
                    out = subprocess.run(
                        [sys.executable, __file__, "--child", "--steps", str(args.steps)],
                        env={**os.environ, **env}, capture_output=True, text=True,
                        check=True)
                    row = json.loads(out.stdout.strip().splitlines()[-1])
                    results[name][load].append(row)
                    print(f"{name:12s} {load:7s} {row['steps_per_s']:8.0f} steps/s "
                          f"{row['cpu_s_per_1000']:6.2f} cpu s/1000 ({row['layer']}, "
                          f"{row['numba_threads']} numba threads)", flush=True)
            finally:
                if hog is not None:
                    hog.kill()
    print(f"\n{'set-up':12s} {'quiet steps/s':>14s} {'loaded steps/s':>15s} "
          f"{'loaded/quiet':>13s} {'cpu s/1000 quiet':>17s}")
    summary = {}
    for name in setups:
        quiet = max(r["steps_per_s"] for r in results[name]["quiet"])
        loaded = max(r["steps_per_s"] for r in results[name]["loaded"])
        cpu = min(r["cpu_s_per_1000"] for r in results[name]["quiet"])
        summary[name] = {"quiet_steps_per_s": quiet, "loaded_steps_per_s": loaded,
                         "loaded_over_quiet": loaded / quiet, "cpu_s_per_1000_quiet": cpu}
        print(f"{name:12s} {quiet:14.0f} {loaded:15.0f} {loaded / quiet:13.2f} {cpu:17.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "runs": results}, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
