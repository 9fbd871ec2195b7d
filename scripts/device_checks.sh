#!/usr/bin/env bash
# The GPU checks of the performance issue (bench_env, bench_agents, bench_hardness) and a measured fraction of the
# full tabular benchmark (scripts/benchmark_wall_time.py), in one call on a lent GPU machine, each part under its own
# time limit so that one slow part cannot take the others' time. Logs and a tarball of results/ go to $OUT.
#
#   bash scripts/device_checks.sh            # on the GPU machine (python3 there has jax with CUDA)
#   SMALL=1 PY=.venv/bin/python OUT=/tmp/dc bash scripts/device_checks.sh   # a few-minute dry run on a CPU
#   PARTS="env agents" bash scripts/device_checks.sh   # only some parts (after info, which always runs)
#
# Parts, in the order they run (PARTS, default "split beta buckets deep"; the first lease, on an H100, ran "env agents
# hardness wall", see docs/benchmarks/gpu_h100.md, whose "What to do with the next GPU lease" the default follows):
#   env, agents, hardness: bench_env, bench_agents --ratio, bench_hardness;
#   wall: the largest bucket of every tabular agent of the two ergodic settings, 500 steps (benchmark_wall_time.py);
#   split: Q-learning, the random agent and PSRL (episodic ergodic, 500 and 5 000 steps) and UCRL2 (continuous
#     ergodic, 500 and 2 000 steps) on their largest buckets: the difference of the two runs is the cost per step
#     without the fixed cost of a call;
#   beta: the step's Beta draw with 1, 2 or 3 rounds before its loop (bench_beta_rounds.py), 1 024 to 262 144 members;
#   buckets: episodic Q-learning on all 20 episodic ergodic MDPs in one batch (--buckets 1, 400 members) against the
#     default 4 buckets, 5 000 steps: whether padding everything to 400 states costs less than three more batches;
#   deep: DQN on two continuous ergodic MDPs (RiverSwim (1), SimpleGrid (1)) through StateInfo, 2 000 steps, 20 seeds
#     (a batch per observation shape): the deep agents' cost per step on the GPU.
# The default parts' limits add up to 590 s (the device's per-call limit is 600 s): run it with timeout_s=600; the
# last part (deep) is the one a slow start would cut.
#
# Packages missing there (distrax, flashbax, gymnax and what they need) travel as Python 3.12 wheels in .whl/ (ignored
# by git), installed into /tmp/site; the dry run (SMALL=1) uses the local environment instead.
set -u
OUT=${OUT:-results/device_out}
PY=${PY:-python3}
mkdir -p "$OUT" results/device
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
if [ -z "${SMALL:-}" ] && [ -d .whl ] && ls .whl/*.whl >/dev/null 2>&1; then
    $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
        && export PYTHONPATH="$PYTHONPATH:/tmp/site"
fi

# Sizes: the GPU's, or a small dry run.
if [ -n "${SMALL:-}" ]; then
    ENVS="64 1024"; SEEDS=64; WALL_SEEDS=2; WALL_STEPS=200; LIMIT_SCALE=${LIMIT_SCALE:-1}
    SPLIT_STEPS="100 300"; SPLIT_STEPS_UCRL2="100 300"; BETA_MEMBERS="64 1024"
    BUCKET_SEEDS=1; BUCKET_STEPS=200; DEEP_SEEDS=1; DEEP_STEPS=200
    SPLIT_LIMIT_FIRST=90; SPLIT_LIMIT_SECOND=70; UCRL2_LIMIT_FIRST=100; UCRL2_LIMIT_SECOND=60
else
    ENVS="1024 16384 262144"; SEEDS=16384; WALL_SEEDS=20; WALL_STEPS=500; LIMIT_SCALE=1
    SPLIT_STEPS="500 5000"; SPLIT_STEPS_UCRL2="500 2000"; BETA_MEMBERS="1024 16384 262144"
    BUCKET_SEEDS=20; BUCKET_STEPS=5000; DEEP_SEEDS=20; DEEP_STEPS=2000
    # The H100 compiled a continuous batch in 70-74 s and episodic PSRL's in 39 s: the first run of each pair pays it.
    SPLIT_LIMIT_FIRST=90; SPLIT_LIMIT_SECOND=70; UCRL2_LIMIT_FIRST=100; UCRL2_LIMIT_SECOND=60
    export JAXMDP_NO_XLA_GUARD=1  # the guard's flag is for jaxlib 0.10.2's CPU backend; leave a GPU jaxlib's flags alone
fi

part() {  # part NAME LIMIT_S COMMAND...: run under a time limit, log to $OUT/NAME.log, print its tail
    local name=$1 limit=$2
    shift 2
    echo "== $name: start $(date -u +%T), limit ${limit}s"
    timeout "$((limit * LIMIT_SCALE))" "$@" >"$OUT/$name.log" 2>&1
    echo "== $name: rc=$? end $(date -u +%T)"
    tail -n "${TAIL:-8}" "$OUT/$name.log"
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
grep -q "smoke run ok" "$OUT/info.log" || { echo "smoke failed: see info.log"; exit 1; }

want() { [[ " ${PARTS:-split beta buckets deep} " == *" $1 "* ]]; }

want env && part env 90 $PY scripts/bench_env.py --quick --envs $ENVS --out results/device/env \
    --doc results/device/env/bench_env.md
want agents && part agents 120 $PY scripts/bench_agents.py --quick --ratio --seeds $SEEDS --repeats 2 \
    --agents q_learning_episodic,q_learning_continuous --out results/device/agents
want hardness && part hardness 110 $PY scripts/bench_hardness.py --quick --repeats 2
want wall && part wall 190 $PY scripts/benchmark_wall_time.py --out results/device/wall --which largest \
    --seeds $WALL_SEEDS --steps $WALL_STEPS --measure "episodic ergodic" "continuous ergodic"
if want split; then
    # The second step count of each pair reuses the first's programs (persistent compilation cache).
    limit=$SPLIT_LIMIT_FIRST
    for steps in $SPLIT_STEPS; do
        part "split_episodic_$steps" "$limit" $PY scripts/benchmark_wall_time.py --out "results/device/split_e$steps" \
            --which largest --seeds $WALL_SEEDS --steps "$steps" --measure "episodic ergodic" \
            --agents q_learning_episodic random_episodic psrl_episodic
        limit=$SPLIT_LIMIT_SECOND
    done
    limit=$UCRL2_LIMIT_FIRST
    for steps in $SPLIT_STEPS_UCRL2; do
        part "split_ucrl2_$steps" "$limit" $PY scripts/benchmark_wall_time.py --out "results/device/split_c$steps" \
            --which largest --seeds $WALL_SEEDS --steps "$steps" --measure "continuous ergodic" --agents ucrl2
        limit=$UCRL2_LIMIT_SECOND
    done
fi
want beta && part beta 40 $PY scripts/bench_beta_rounds.py --members $BETA_MEMBERS --repeats 3 \
    --doc results/device/bench_beta_rounds.md
if want buckets; then
    for b in 1 4; do
        part "buckets_$b" "$((45 + 5 * (b > 1)))" $PY scripts/run_benchmark.py --settings "episodic ergodic" --agents q_learning_episodic \
            --seeds $BUCKET_SEEDS --steps $BUCKET_STEPS --buckets $b --quiet --out "results/device/buckets_$b"
    done
fi
want deep && part deep 90 $PY scripts/run_benchmark.py --settings "continuous ergodic" --emission state_info \
    --agents dqn_continuous --mdps RiverSwim/prms_0 SimpleGrid/prms_0 --seeds $DEEP_SEEDS --steps $DEEP_STEPS \
    --quiet --out results/device/deep

find results/device -name batches.csv | sort | while read -r f; do echo "== $f"; cat "$f"; done
tar czf "$OUT/results.tgz" results/device results/bench_hardness.* 2>/dev/null
echo "== done $(date -u +%T)"
