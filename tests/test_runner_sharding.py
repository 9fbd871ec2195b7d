"""A planning agent's members split over several host devices (shard_map): each shard plans its members exactly
when they ask (every member's plan count is its own period's), and the records equal one device's.

That a Q-learning member's records are the same alone and in a batch on two devices is
tests/test_properties_runner.py's property (on random MDPs). The device count of the CPU backend is fixed when JAX
starts, so the check runs in a subprocess started with ``XLA_FLAGS=--xla_force_host_platform_device_count=2``.
"""

from __future__ import annotations

import textwrap

from progress_run import run_on_host_devices

SCRIPT = textwrap.dedent(
    """
    import json
    import jax, numpy as np
    import jaxmdp
    from jaxmdp.experiment import runner
    from test_runner import SCRIPTED, ScriptedHParams

    assert jax.local_device_count() == 2
    out = {}
    # Members 0-1 and 2-3 plan at different periods, on different shards (the default: every device that divides
    # the batch).
    hps = [ScriptedHParams(plan_every=5), ScriptedHParams(plan_every=7)]
    g = runner.product([jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, randomize_actions=False)], hps,
                       seeds=[0, 1])
    res = runner.run(SCRIPTED[True], g, 400, n_records=4)
    one = runner.run(SCRIPTED[True], g, 400, n_records=4, shards=1)
    out["values_equal"] = bool(np.array_equal(one.values, res.values))
    out["plans"] = res.agent_state.plans.tolist()
    print(json.dumps(out))
    """
)


def test_two_shards_equal_one():
    out = run_on_host_devices(SCRIPT, 2)
    assert out["values_equal"], out
    assert out["plans"] == [1 + 399 // 5, 1 + 399 // 5, 1 + 399 // 7, 1 + 399 // 7]
