#!/usr/bin/env bash
# The GPU checks of the performance issue (bench_env, bench_agents, bench_hardness) and a measured fraction of the
# full tabular benchmark (scripts/benchmark_wall_time.py), in one call on a lent GPU machine, each part under its own
# time limit so that one slow part cannot take the others' time. Logs and a tarball of results/ go to $OUT.
#
#   bash scripts/device_checks.sh            # on the GPU machine (python3 there has jax with CUDA)
#   SMALL=1 PY=.venv/bin/python OUT=/tmp/dc bash scripts/device_checks.sh   # a few-minute dry run on a CPU
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
    ENVS="64 1024"; SEEDS=64; WALL_SEEDS=2; WALL_STEPS=200; LIMIT_SCALE=1
else
    ENVS="1024 16384 262144"; SEEDS=16384; WALL_SEEDS=20; WALL_STEPS=500; LIMIT_SCALE=1
    export JAXMDP_NO_XLA_GUARD=1  # the guard's flag is for jaxlib 0.10.2's CPU backend; leave a GPU jaxlib's flags alone
fi

part() {  # part NAME LIMIT_S COMMAND...: run under a time limit, log to $OUT/NAME.log, print its tail
    local name=$1 limit=$2
    shift 2
    echo "== $name: start $(date -u +%T), limit ${limit}s"
    timeout "$((limit * LIMIT_SCALE))" "$@" >"$OUT/$name.log" 2>&1
    echo "== $name: rc=$? end $(date -u +%T)"
    tail -n "${TAIL:-25}" "$OUT/$name.log"
}

part info 60 bash -c "nvidia-smi -L 2>&1; $PY -c '
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

part env 90 $PY scripts/bench_env.py --quick --envs $ENVS --out results/device/env --doc results/device/env/bench_env.md
part agents 120 $PY scripts/bench_agents.py --quick --ratio --seeds $SEEDS --repeats 2 \
    --agents q_learning_episodic,q_learning_continuous --out results/device/agents
part hardness 110 $PY scripts/bench_hardness.py --quick --repeats 2
part wall 190 $PY scripts/benchmark_wall_time.py --out results/device/wall --which largest \
    --seeds $WALL_SEEDS --steps $WALL_STEPS --measure "episodic ergodic" "continuous ergodic"

tar czf "$OUT/results.tgz" results/device results/bench_hardness.* 2>/dev/null
echo "== done $(date -u +%T)"
