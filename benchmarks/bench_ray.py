"""The quick benchmark without and with Ray: the wall time of ``jaxmdp-benchmark run --quick`` in this process (one
batch after another, every core through the runner's host devices) against ``--ray`` on a local Ray instance of
``--cpus`` CPUs (one batch per core at a time), each into a fresh output folder, and their ratio.

The Ray time counts everything the command does: starting the local instance, its worker processes (each starts Python
and JAX and compiles its batches' programs), running and shutting down. No persistent compilation cache is used, so
that neither run loads what the other compiled. Both runs must give the same ``members.csv`` byte for byte; the script
checks it.

    python benchmarks/bench_ray.py                  # the quick benchmark, 2 CPUs
    python benchmarks/bench_ray.py --cpus 4
    python benchmarks/bench_ray.py --smoke          # a tiny benchmark, to check that it runs
"""

from __future__ import annotations

import os

if __name__ == "__main__" and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    # One lockstep loop per core, as jaxmdp-benchmark run runs (set before JAX starts).
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={os.cpu_count() or 1}"
    ).strip()

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

#: ``--smoke``: two MDPs of the episodic quick-test set in two buckets, two cheap agents, two seeds, 200 steps.
SMOKE = dict(sets=("episodic quick test",), agents=("q_learning_episodic", "random_episodic"), seeds=(0, 1),
             n_steps=200, log_period=50, n_buckets=2, hparams="reference", only=("RiverSwim", "DeepSea"))


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cpus", type=int, default=2, help="CPUs of the local Ray instance (%(default)s)")
    parser.add_argument("--smoke", action="store_true", help="a tiny benchmark, to check that the script runs")
    parser.add_argument("--work-dir", type=Path, default=None, help="where the two output folders go (a fresh "
                        "temporary folder by default)")
    args = parser.parse_args(argv)

    import ray

    from hardness.benchmark import run

    config = run.RunConfig(**SMOKE) if args.smoke else run.quick_config()
    work = Path(tempfile.mkdtemp(prefix="bench_ray-")) if args.work_dir is None else args.work_dir
    plain_out, ray_out = work / "plain", work / "ray"
    for folder in (plain_out, ray_out):
        if folder.exists() and any(folder.iterdir()):
            raise SystemExit(f"bench_ray: {folder} is not empty; give a fresh --work-dir")

    t0 = time.perf_counter()
    run.run_benchmark(config, plain_out, progress=False, report=False)
    plain_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    ray.init(num_cpus=args.cpus, include_dashboard=False, log_to_driver=False)
    try:
        run.run_benchmark(config, ray_out, progress=False, report=False, ray=True)
    finally:
        ray.shutdown()
    ray_s = time.perf_counter() - t0

    same = (plain_out / "members.csv").read_bytes() == (ray_out / "members.csv").read_bytes()
    print(f"{'smoke' if args.smoke else 'quick'} benchmark: plain {plain_s:.1f} s, --ray ({args.cpus} CPUs, its "
          f"start included) {ray_s:.1f} s, ratio {ray_s / plain_s:.2f}; members.csv identical: {same} ({work})")
    if not same:
        raise SystemExit("bench_ray: the two runs' members.csv differ")
    return dict(plain_s=plain_s, ray_s=ray_s, ratio=ray_s / plain_s)


if __name__ == "__main__":
    main()
