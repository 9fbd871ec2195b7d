"""Every standing benchmark of ``benchmarks/`` at its ``--smoke`` size, in this process: it runs, writes its table
(with the command, the machine and the commit) and, with ``--update-docs``, replaces exactly its own section of the
performance page. Optional baselines (gymnax, bsuite) are skipped by the benchmarks themselves when missing."""

from __future__ import annotations

import math

import pytest
from benchmark_loader import load_benchmark

# bench_plans and bench_indicators compile the largest buckets' plan and gain programs even at smoke size (minutes):
# nightly. bench_ray starts a Ray instance and has no --update-docs (it prints its ratio).
BENCHMARKS = ("bench_env", "bench_agents", "bench_hardness", "bench_sampling", "bench_compile", "bench_family_build",
              "benchmark_wall_time", pytest.param("bench_plans", marks=pytest.mark.nightly),
              pytest.param("bench_indicators", marks=pytest.mark.nightly))


@pytest.mark.parametrize("name", BENCHMARKS)
def test_benchmark_runs_at_smoke_size_and_updates_only_its_section(name, tmp_path, monkeypatch):
    monkeypatch.setenv("JAXMDP_COMPILATION_CACHE", "0")  # bench_compile's children: no user cache either
    docs = tmp_path / "performance.md"
    other = "<!-- bench:other -->\nkept\n<!-- /bench:other -->"
    docs.write_text(f"# Performance\n\n<!-- bench:{name} -->\nold table\n<!-- /bench:{name} -->\n\n{other}\n")
    argv = ["--smoke", "--out", str(tmp_path / "out"), "--update-docs", "--docs", str(docs), "--no-compile-cache"]
    if name == "benchmark_wall_time":
        argv += ["--work-dir", str(tmp_path / "work")]
    assert load_benchmark(name).main(argv) == 0
    table = (tmp_path / "out" / f"{name}.md").read_text()
    assert f"`python benchmarks/{name}.py --smoke" in table and "Machine: " in table and "Commit: `" in table
    assert "|---" in table  # a Markdown table
    text = docs.read_text()
    assert "old table" not in text and other in text and text.startswith("# Performance\n")
    section = text.split(f"<!-- bench:{name} -->\n")[1].split(f"<!-- /bench:{name} -->")[0]
    assert section.strip() and section.strip() in table


def test_update_docs_needs_the_markers(tmp_path):
    common = load_benchmark("_common")
    docs = tmp_path / "performance.md"
    docs.write_text("# Performance\n")
    with pytest.raises(SystemExit, match="bench:bench_env"):
        common.update_docs(docs, "bench_env", ["| a |"])


def test_bench_agents_table_with_a_skipped_configuration():
    # A configuration skipped for its predicted time has no measurements: the table marks it, and a deep DQN without
    # bsuite installed says so (the table once failed with KeyError: 'compile_s' after a skip).
    ba = load_benchmark("bench_agents")
    rows = [
        dict(agent="dqn_continuous", mdp="RiverSwim", S=25, seeds=16, skipped=False, steps_per_s=2e3, compile_s=3.0,
             cpu_ns_per_step=1.0, regret=0.1),
        dict(agent="dqn_continuous", mdp="RiverSwim", S=25, seeds=64, skipped=True),
        dict(agent="bsuite_jax_dqn (continuous)", mdp="RiverSwim", S=25, seeds=1, skipped=False, steps_per_s=1e3,
             compile_s=math.nan, cpu_ns_per_step=math.nan, regret=math.nan),
    ]
    args = type("Args", (), dict(steps=100, repeats=1, mdps=1))()
    lines = ba.body(rows, [], args)
    row = next(line for line in lines if line.startswith("| dqn_continuous | RiverSwim"))
    assert "2.0 k (3.0 s)" in row and "skipped" in row
    assert any("| dqn_continuous | 16 | 2.0 k | 1.0 k | 2.0x |" in line for line in lines)
    assert ba.cell(None) == "-" and ba.cell(rows[1]) == "skipped" and ba.cell(rows[2]) == "1.0 k"
    assert any("bsuite is not installed" in line for line in ba.body(rows[:2], [], args))
