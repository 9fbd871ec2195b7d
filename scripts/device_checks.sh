#!/usr/bin/env bash
# The GPU checks of the performance issue (bench_env, bench_agents, bench_hardness) and a measured fraction of the
# full tabular benchmark (scripts/benchmark_wall_time.py), in one call on a lent GPU machine, each part under its own
# time limit so that one slow part cannot take the others' time. Tarballs of the logs and results go to $OUT.
#
#   bash scripts/device_checks.sh            # on the GPU machine (python3 there has jax with CUDA)
#   SMALL=1 PY=.venv/bin/python OUT=/tmp/dc bash scripts/device_checks.sh   # a few-minute dry run on a CPU
#   PARTS="env agents" bash scripts/device_checks.sh   # only some parts (after info, which always runs)
#
# Parts, in the order they run (PARTS, default "hlo split splitc": the costs per step that the extrapolation to the
# full benchmark on a GPU still lacks; the first H200 lease ran "split beta buckets deep", docs/benchmarks/gpu_h200.md,
# the H100 lease "env agents hardness wall", docs/benchmarks/gpu_h100.md):
#   env, agents, hardness: bench_env, bench_agents --ratio, bench_hardness;
#   wall: the largest bucket of every tabular agent of the two ergodic settings, 500 steps (benchmark_wall_time.py);
#   hlo: the optimised programs of episodic Q-learning's and the random agent's largest batch (XLA's dump, 100 steps),
#     packed into $OUT/hlo.tgz: the kernels and copies of a step, to read on any machine;
#   split: the largest bucket of SPLIT_AGENTS (default episodic PSRL; episodic ergodic) at 500 and 5 000 steps and of
#     UCRL2 (continuous ergodic) at 500 and 2 000 steps (benchmark_wall_time.py --steps N1 N2 --scaling
#     lockstep-step): the difference of the two runs is the cost of a step without the fixed cost of a call;
#   splitc: as split, for continuous Q-learning, the random agent and PSRL (continuous ergodic, 500 and 2 000 steps;
#     SPLITC_AGENTS, SPLITC_STEPS and SPLITC_LIMIT change them);
#   beta: the step's Beta draw with 1, 2 or 3 rounds before its loop (bench_beta_rounds.py), BETA_MEMBERS members;
#   buckets: episodic Q-learning on all 20 episodic ergodic MDPs in one batch (--buckets 1, 400 members) against the
#     default 4 buckets, 2 000 steps (each part's limit also holds the process start, the report's hardness measures
#     and the compiles, about 25-35 s on the H200);
#   deep: DQN on two continuous ergodic MDPs (RiverSwim (1), SimpleGrid (1)) through StateInfo, 2 000 steps, 20 seeds.
# The default parts' limits add up to 545 s (the device's per-call limit is 600 s): run it with timeout_s=600.
# Each part's log goes to results/device/logs/; after every part the logs and results (without checkpoints) are packed
# into $OUT/results.tgz, so a call stopped at its limit still brings back what finished (the device returns at most 8
# files, so the logs travel packed).
#
# Packages missing there (distrax, flashbax, gymnax and what they need) travel as Python 3.12 wheels in .whl/ (ignored
# by git), installed into /tmp/site; the dry run (SMALL=1) uses the local environment instead.
set -u
OUT=${OUT:-results/device_out}
PY=${PY:-python3}
mkdir -p "$OUT" results/device/logs
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
if [ -z "${SMALL:-}" ] && [ -d .whl ] && ls .whl/*.whl >/dev/null 2>&1; then
    $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
        && export PYTHONPATH="$PYTHONPATH:/tmp/site"
fi

# Sizes: the GPU's, or a small dry run. Part limits (seconds) from the H200 lease's times: a continuous ergodic batch
# compiled in 70 s or more there, episodic PSRL's in 16.5 s.
SPLIT_AGENTS=${SPLIT_AGENTS:-psrl_episodic}
if [ -n "${SMALL:-}" ]; then
    ENVS="64 1024"; SEEDS=64; WALL_SEEDS=2; WALL_STEPS=200; LIMIT_SCALE=${LIMIT_SCALE:-1}
    SPLIT_STEPS="100 300"; SPLIT_STEPS_UCRL2="100 300"; BETA_MEMBERS="64 1024"
    BUCKET_SEEDS=1; BUCKET_STEPS=200; DEEP_SEEDS=1; DEEP_STEPS=200
else
    ENVS="1024 16384 262144"; SEEDS=16384; WALL_SEEDS=20; WALL_STEPS=500; LIMIT_SCALE=1
    SPLIT_STEPS="500 5000"; SPLIT_STEPS_UCRL2="500 2000"; BETA_MEMBERS="16384 262144"
    BUCKET_SEEDS=20; BUCKET_STEPS=2000; DEEP_SEEDS=20; DEEP_STEPS=2000
    export JAXMDP_NO_XLA_GUARD=1  # the guard's flag is for jaxlib 0.10.2's CPU backend; leave a GPU jaxlib's flags alone
fi
part() {  # part NAME LIMIT_S COMMAND...: run under a time limit, log to results/device/logs/NAME.log, print its tail
    local name=$1 limit=$2
    shift 2
    echo "== $name: start $(date -u +%T), limit ${limit}s"
    timeout "$((limit * LIMIT_SCALE))" "$@" >"results/device/logs/$name.log" 2>&1
    echo "== $name: rc=$? end $(date -u +%T)"
    tail -n "${TAIL:-8}" "results/device/logs/$name.log"
    pack
}

pack() {  # the logs and results so far, without checkpoints or the HLO dump, into $OUT/results.tgz
    tar czf "$OUT/results.tgz" --exclude='*.ckpt.npz' --exclude=results/device/hlo results/device \
        $(ls results/bench_hardness.* 2>/dev/null)
}

part info 45 bash -c "nvidia-smi -L 2>&1; $PY -c '
import jax, jaxlib, flax, optax, chex
print(\"jax\", jax.__version__, \"jaxlib\", jaxlib.__version__, \"flax\", flax.__version__, \"optax\", optax.__version__)
print(jax.devices())
import jaxmdp, agents, hardness
from jaxmdp.experiment import runner
mdp = jaxmdp.make(\"RiverSwim\", episodic=True, seed=0, size=5)
g = runner.product([mdp], [agents.get(\"q_learning_episodic\").default_hparams], seeds=range(8))
r = runner.run(agents.get(\"q_learning_episodic\"), g, 500, log_period=100, n_records=5)
print(\"smoke run ok\", r.column(\"normalized_cumulative_regret\")[-1])
'" || { echo "smoke failed"; exit 1; }
grep -q "smoke run ok" results/device/logs/info.log || { echo "smoke failed: see info.log"; exit 1; }

want() { [[ " ${PARTS:-hlo split splitc} " == *" $1 "* ]]; }

want env && part env 90 $PY scripts/bench_env.py --quick --envs $ENVS --out results/device/env \
    --doc results/device/env/bench_env.md
want agents && part agents 120 $PY scripts/bench_agents.py --quick --ratio --seeds $SEEDS --repeats 2 \
    --agents q_learning_episodic,q_learning_continuous --out results/device/agents
want hardness && part hardness 110 $PY scripts/bench_hardness.py --quick --repeats 2
want wall && part wall 190 $PY scripts/benchmark_wall_time.py --out results/device/wall --which largest \
    --seeds $WALL_SEEDS --steps $WALL_STEPS --measure "episodic ergodic" "continuous ergodic"
if want hlo; then
    # Compiled afresh (no persistent cache: a cache hit would dump nothing); only the runner's chunk programs.
    dump="--xla_dump_to=results/device/hlo --xla_dump_hlo_as_text --xla_dump_hlo_module_re=.*chunk.*"
    part hlo 60 env XLA_FLAGS="$dump" \
        $PY scripts/benchmark_wall_time.py --no-compile-cache --out results/device/hlo_run --which largest \
        --seeds $WALL_SEEDS --steps 100 --measure "episodic ergodic" --agents q_learning_episodic random_episodic
    find results/device/hlo -name '*after_optimizations*' -print0 | tar czf "$OUT/hlo.tgz" --null -T -
    ls -l "$OUT/hlo.tgz"
fi
if want split; then
    # One process per setting: each batch runs both step counts (the second reuses the first's compiled program).
    part split_episodic 90 $PY scripts/benchmark_wall_time.py --out results/device/split_e --which largest \
        --seeds $WALL_SEEDS --steps $SPLIT_STEPS --scaling lockstep-step --measure "episodic ergodic" \
        --agents $SPLIT_AGENTS
    part split_ucrl2 150 $PY scripts/benchmark_wall_time.py --out results/device/split_c --which largest \
        --seeds $WALL_SEEDS --steps $SPLIT_STEPS_UCRL2 --scaling lockstep-step --measure "continuous ergodic" \
        --agents ucrl2
fi
if want splitc; then
    # The continuous agents the H200 lease did not measure: Q-learning, the random agent and PSRL, largest bucket.
    part split_continuous "${SPLITC_LIMIT:-200}" $PY scripts/benchmark_wall_time.py --out results/device/split_cc \
        --which largest --seeds $WALL_SEEDS --steps ${SPLITC_STEPS:-$SPLIT_STEPS_UCRL2} --scaling lockstep-step \
        --measure "continuous ergodic" --agents ${SPLITC_AGENTS:-q_learning_continuous random_continuous psrl_continuous}
fi
want beta && part beta 60 $PY scripts/bench_beta_rounds.py --members $BETA_MEMBERS --repeats 3 \
    --doc results/device/bench_beta_rounds.md
if want buckets; then
    for b in 1 4; do
        part "buckets_$b" "$((75 + 5 * (b > 1)))" $PY scripts/run_benchmark.py --settings "episodic ergodic" \
            --agents q_learning_episodic \
            --seeds $BUCKET_SEEDS --steps $BUCKET_STEPS --buckets $b --quiet --out "results/device/buckets_$b"
    done
fi
want deep && part deep 90 $PY scripts/run_benchmark.py --settings "continuous ergodic" --emission state_info \
    --agents dqn_continuous --mdps RiverSwim/prms_0 SimpleGrid/prms_0 --seeds $DEEP_SEEDS --steps $DEEP_STEPS \
    --quiet --out results/device/deep

find results/device -name batches.csv | sort | while read -r f; do echo "== $f"; cat "$f"; done
pack
echo "== done $(date -u +%T)"
