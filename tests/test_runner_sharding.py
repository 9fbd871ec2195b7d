"""Members split over several host devices (shard_map) give the same records as one device.

The device count of the CPU backend is fixed when JAX starts, so the check runs in a subprocess started with
``XLA_FLAGS=--xla_force_host_platform_device_count=2``.
"""

from __future__ import annotations

import textwrap

from progress_run import run_on_host_devices

SCRIPT = textwrap.dedent(
    """
    import json
    import jax, numpy as np
    import agents, jaxmdp
    from jaxmdp.experiment import runner
    from test_runner import SCRIPTED, ScriptedHParams

    assert jax.local_device_count() == 2
    out = {}
    mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False, p_lazy=0.1,
                      make_reward_stochastic=True)
    agent = agents.get("q_learning_continuous")
    g = runner.product([mdp], [agent.default_hparams], seeds=range(4))
    one = runner.run(agent, g, 700, n_records=7, shards=1)
    two = runner.run(agent, g, 700, n_records=7)  # default: every device that divides the batch
    out["q_values_equal"] = bool(np.array_equal(one.values, two.values))
    out["q_max_diff"] = float(np.max(np.abs(one.values - two.values)))
    # Planning predicates are per shard: members 0-1 and 2-3 plan at different periods, on different shards.
    hps = [ScriptedHParams(plan_every=5), ScriptedHParams(plan_every=7)]
    g = runner.product([jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, randomize_actions=False)], hps,
                       seeds=[0, 1])
    res = runner.run(SCRIPTED[True], g, 400, n_records=4, shards=2)
    out["plans"] = res.agent_state.plans.tolist()
    print(json.dumps(out))
    """
)


def test_two_shards_equal_one():
    out = run_on_host_devices(SCRIPT, 2)
    assert out["q_values_equal"], out
    assert out["plans"] == [1 + 399 // 5, 1 + 399 // 5, 1 + 399 // 7, 1 + 399 // 7]
