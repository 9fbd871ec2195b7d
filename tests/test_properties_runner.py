"""Property test: a member's runner records do not depend on the other members of its batch or on the number of
devices, on random MDPs (tests/random_mdps.py; Hypothesis profiles in tests/hypothesis_profiles.py).

For every draw, member 0 (Q-learning on a random MDP with Beta rewards, its own key) runs alone (a grid of one
member: the runner gathers nothing from a stack of one MDP), then at a drawn position in a batch of four members with
other random MDPs and keys split over two devices (two members in lockstep on each), and in the nightly profile also
on one device (four in lockstep). Its records (every indicator sum at every record), indicator constants and final
agent state must be identical, bit for bit, in every run. The CI profile leaves the one-device batch out because
each run compiles a chunk program per setting, and those compilations are most of the test's time.

The device count of the CPU backend is fixed when JAX starts, so the property runs inside a subprocess started with
``XLA_FLAGS=--xla_force_host_platform_device_count=2`` (as tests/test_runner_sharding.py), which runs Hypothesis
itself with the profile of ``$HYPOTHESIS_PROFILE`` and prints how many examples it drew. Every draw is padded to one
shape, so each of the three runs compiles once per setting.
"""

from __future__ import annotations

import textwrap

from progress_run import run_on_host_devices

SCRIPT = textwrap.dedent(
    """
    import json
    import hypothesis_profiles
    import jax
    import numpy as np
    from hypothesis import given, settings
    from hypothesis import strategies as st

    import agents
    from jaxmdp.experiment import runner
    from random_mdps import draws

    assert jax.local_device_count() == 2
    AGENTS = {e: agents.get("q_learning_episodic" if e else "q_learning_continuous") for e in (False, True)}
    N_STEPS, N_RECORDS, LOG_PERIOD = 60, 3, 20
    drawn = {"continuous": 0, "episodic": 0}
    # The batch on two devices runs two members in lockstep on each; the nightly profile adds the batch on one device
    # (a chunk program per setting and device count: most of the test's time is their compilation).
    SHARDS = (2,) if hypothesis_profiles.PROFILE == "ci" else (1, 2)


    def run(agent, mdps, key_data, shards):
        hparams = runner.stack_hparams([agent.default_hparams] * len(mdps))
        g = runner.grid(mdps, hparams, np.asarray(key_data, np.uint32))
        return runner.run(agent, g, N_STEPS, n_records=N_RECORDS, log_period=LOG_PERIOD, shards=shards)


    def member(result, i):
        return (result.values[:, i], jax.tree.map(lambda x: x[i], result.constants),
                jax.tree.map(lambda x: x[i], result.agent_state))


    members = st.booleans().flatmap(lambda e: st.lists(draws(episodic=e, beta_rewards=True), min_size=4, max_size=4))
    keys = st.lists(st.tuples(st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1)), min_size=4, max_size=4,
                    unique=True)


    @given(members=members, keys=keys, position=st.integers(0, 3))
    @settings(max_examples=hypothesis_profiles.examples({N}))
    def prop(members, keys, position):
        episodic = members[0].horizon is not None
        drawn["episodic" if episodic else "continuous"] += 1
        agent = AGENTS[episodic]
        mdps = [d.padded() for d in members]
        order = [i for i in range(1, 4)]
        order.insert(position, 0)
        alone = member(run(agent, mdps[:1], keys[:1], 1), 0)
        for shards in SHARDS:
            batch = run(agent, [mdps[i] for i in order], [keys[i] for i in order], shards)
            for a, b in zip(jax.tree.leaves(alone), jax.tree.leaves(member(batch, position))):
                np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=f"shards={{shards}}")


    prop()
    print(json.dumps(drawn))
    """
)

#: Examples of the CI profile (the nightly profile multiplies them).
CI_EXAMPLES = 8


def test_member_records_do_not_depend_on_the_batch_or_the_devices():
    drawn = run_on_host_devices(SCRIPT.replace("{N}", str(CI_EXAMPLES)).replace("{{", "{").replace("}}", "}"), 2)
    print(f"examples drawn: {drawn}")
    assert drawn["continuous"] > 0 and drawn["episodic"] > 0, drawn
