"""The benchmark's batches as Ray tasks (hardness.benchmark.distributed): the same ``members.csv`` byte for byte as a
run without Ray, a worker killed mid-batch costing nothing, a batch's error stopping the run with its id and the
finished batches kept, and Ray never imported without ``--ray``.

The run is test_benchmark_run's tiny benchmark (two MDPs of the episodic quick-test set in two size buckets, two
agents, two seeds, 200 steps in four runner chunks) on a local Ray instance of two CPUs, started once for the module.
"""

import csv
import json
import os
import shutil
import subprocess
import sys

import pytest

from conftest import REPO
from hardness.benchmark import run

ray = pytest.importorskip("ray")

TINY = dict(sets=("episodic quick test",), agents=("q_learning_episodic", "random_episodic"), seeds=(0, 1),
            n_steps=200, log_period=50, n_buckets=2, hparams="reference", only=("RiverSwim", "DeepSea"))


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    """The tiny benchmark run without Ray."""
    out = tmp_path_factory.mktemp("plain")
    summary = run.run_benchmark(run.RunConfig(**TINY), out, progress=False, report=False)
    return out, summary


def _rows(path):
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_ray_run_gives_the_plain_run_s_members_csv(local_ray, plain, tmp_path):
    out, summary = plain
    got = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, report=False, ray=True)
    assert got.finished and sorted(got.ran) == sorted(summary.ran) and not got.reused
    assert (tmp_path / "members.csv").read_bytes() == (out / "members.csv").read_bytes()
    batches = _rows(tmp_path / "batches.csv")
    assert sorted(b["batch"] for b in batches) == sorted(summary.ran)
    # each batch ran in a Ray worker (not this process), which batches.csv names, with its compile and run seconds
    assert all(b["pid"] != str(os.getpid()) and b["host"] and float(b["compile_s"]) > 0 and float(b["run_s"]) > 0
               for b in batches)
    for b in got.ran:  # the worker saw the folder: the runner's CSV is there, its checkpoint gone
        assert (tmp_path / "runs" / f"{b}.csv").read_bytes().count(b"\n") == len(_rows(out / "runs" / f"{b}.csv")) + 1
        assert not (tmp_path / "runs" / f"{b}.ckpt.npz").exists()
    assert not list((tmp_path / "runs").glob(".ray-*"))  # the driver's token is gone
    again = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, report=False, ray=True)
    assert again.finished and not again.ran and sorted(again.reused) == sorted(summary.ran)


def test_a_worker_killed_mid_batch_is_retried_from_its_checkpoint(local_ray, plain, tmp_path, monkeypatch):
    out, summary = plain
    victim = summary.ran[-1]
    marker = tmp_path / "killed.pid"
    # the private test seam: the first attempt runs 2 of the 4 chunks (checkpointed), then kills its own worker
    monkeypatch.setenv("JAXMDP_RAY_TEST_FAULT", f"{victim}:2:{marker}")
    got = run.run_benchmark(run.RunConfig(**TINY), tmp_path / "run", progress=False, report=False, ray=True)
    assert got.finished and marker.exists()
    assert (tmp_path / "run" / "members.csv").read_bytes() == (out / "members.csv").read_bytes()
    ran_on_ray = [line for line in (tmp_path / "run" / "runs" / f"{victim}.log").read_text().splitlines()
                  if " ran-on-ray " in line]
    assert len(ran_on_ray) == 1 and "resumed_at_step=100" in ran_on_ray[0]  # 2 chunks of 50 steps
    assert f"pid={marker.read_text().strip()} " not in ran_on_ray[0]  # another worker finished it
    with (tmp_path / "run" / "runs" / f"{victim}.csv").open(newline="") as f:
        assert len(list(csv.reader(f))) == len(_rows(out / "runs" / f"{victim}.csv")) + 1  # each record once


def test_a_batch_s_error_stops_the_run_naming_it_and_the_finished_batches_stay(local_ray, plain, tmp_path):
    out, summary = plain
    first, bad = summary.ran[0], summary.ran[-1]
    # a checkpoint of another batch where the last batch's belongs: the runner refuses it (ValueError), a retry
    # could not help
    run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, report=False, stop_at=(0, 1))
    shutil.move(tmp_path / "runs" / f"{first}.ckpt.npz", tmp_path / "runs" / f"{bad}.ckpt.npz")
    with pytest.raises(ValueError, match=f"batch {bad} failed: ValueError: .*checkpoint"):
        run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, report=False, ray=True)
    kept = [b for b in summary.ran if (tmp_path / "runs" / f"{b}.json").exists()]
    assert kept and bad not in kept
    assert {r["batch"] for r in _rows(tmp_path / "members.csv")} == set(kept)
    assert not list((tmp_path / "runs").glob("*.claim"))
    # the same command, once the cause is gone, runs only the rest
    (tmp_path / "runs" / f"{bad}.ckpt.npz").unlink()
    again = run.run_benchmark(run.RunConfig(**TINY), tmp_path, progress=False, report=False, ray=True)
    assert again.finished and sorted(again.reused) == sorted(kept) and bad in again.ran
    assert (tmp_path / "members.csv").read_bytes() == (out / "members.csv").read_bytes()


def test_bad_ray_options_are_refused(tmp_path):
    from hardness.benchmark import distributed

    for bad, message in ((0, "ray must be True"), ("  ", "ray must be True"),
                         (distributed.RayOptions(gpus_per_batch=1.5), "gpus_per_batch above 1"),
                         (distributed.RayOptions(cpus_per_batch=-1), "cpus_per_batch must be a number >= 0"),
                         (distributed.RayOptions(cpus_per_batch=0, gpus_per_batch=0), "both 0"),
                         (distributed.RayOptions(max_retries=-1), "max_retries")):
        with pytest.raises(ValueError, match=message):
            distributed.ray_options(bad)
    assert distributed.ray_options("auto").address == "auto"


def test_without_ray_nothing_imports_ray(tmp_path):
    code = f"""
import sys
from pathlib import Path
from hardness.cli import benchmark as cli
from hardness.benchmark import run
args = cli.build_parser().parse_args(["run", "--quick", "--out", "x"])
assert cli.ray_from_args(args) is None
config = run.RunConfig(sets=("episodic quick test",), agents=("random_episodic",), seeds=(0,), n_steps=20,
                       log_period=10, n_buckets=1, hparams="reference", only=("RiverSwim",))
assert run.run_benchmark(config, Path({str(tmp_path)!r}), progress=False, report=False).finished
bad = [m for m in sys.modules if m == "ray" or m.startswith("ray.") or m == "hardness.benchmark.distributed"]
assert not bad, bad
"""
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]


def test_cli_ray_arguments():
    from hardness.cli import benchmark as cli

    p = cli.build_parser()
    local = cli.ray_from_args(p.parse_args(["run", "--quick", "--ray", "--out", "x"]))
    assert local.address is None and local.gpus_per_batch is None and local.cpus_per_batch == 1
    packed = cli.ray_from_args(p.parse_args(["run", "--quick", "--ray", "auto", "--gpus-per-batch", "0.25",
                                             "--out", "x"]))
    assert packed.address == "auto" and packed.gpus_per_batch == 0.25
    with pytest.raises(ValueError, match="are for --ray runs"):
        cli.ray_from_args(p.parse_args(["run", "--quick", "--gpus-per-batch", "0.5", "--out", "x"]))
    with pytest.raises(SystemExit):
        p.parse_args(["run", "--quick", "--ray", "--gpus-per-batch", "-1", "--out", "x"])


def test_tune_through_ray_writes_the_plain_tuner_s_winners(local_ray, tmp_path):
    # One agent's search as a Ray task (hardness.benchmark.distributed_tune): the same tuned-file entry as the
    # search in this process, timings and date aside; the runner's checkpoints in the agent's work folder beside the file.
    from hardness.cli import benchmark as cli

    argv = ["--agents", "q_learning_episodic", "--steps", "100", "--candidates", "1", "--mdps-per-family", "1",
            "--seeds", "1", "--max-states", "30", "--buckets", "1", "--quiet"]

    def tune(out, *extra):
        return cli.tune_command(cli.build_parser().parse_args(["tune", *argv, "--out", str(out), *extra]))

    def without_timings(entries):
        return {n: {k: v for k, v in e.items() if k not in ("wall_s", "run_s", "compile_s", "date")}
                for n, e in entries.items()}

    plain = tune(tmp_path / "plain")
    through_ray = tune(tmp_path / "ray", "--ray")
    assert set(through_ray) == {"q_learning_episodic"}
    assert without_timings(through_ray) == without_timings(plain)
    written = json.loads((tmp_path / "ray" / "tuned_hparams.json").read_text())["agents"]
    assert without_timings({"q_learning_episodic": written["q_learning_episodic"]}) == without_timings(plain)
    # The worker saw the driver's folder: the runner's files are in the agent's work folder there.
    assert any(p.is_file() for p in (tmp_path / "ray" / "runs" / "q_learning_episodic").rglob("*"))
    assert tune(tmp_path / "ray", "--ray") == {}  # already tuned with this budget: skipped, Ray not started
