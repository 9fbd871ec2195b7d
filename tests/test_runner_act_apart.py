"""The runner computes an agent's action apart from the rest of the step (``lockstep.apart``): the same values, in a
conditional that stays one under ``vmap`` (an unbatched predicate), so that XLA cannot fuse the act into its users."""


import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp.experiment import lockstep, runner
from tests.jaxpr_eqns import equations

_apart = lockstep.apart


def _act(key, table, obs):
    """An act-like function with a pytree result: a row of a table and a draw."""
    row = table[obs]
    return {"action": jnp.argmax(row + jax.random.uniform(key, row.shape)), "row_sum": jnp.sum(row)}


@pytest.fixture
def batch():
    keys = jax.random.split(jax.random.key(3), 5)
    tables = jax.random.normal(jax.random.key(4), (5, 7, 3))
    obs = jnp.array([0, 6, 2, 2, 5])
    return keys, tables, obs


def test_apart_gives_the_function_s_values_under_jit_and_vmap(batch):
    keys, tables, obs = batch
    want = jax.vmap(_act)(keys, tables, obs)
    got = jax.jit(jax.vmap(lambda k, t, o: lockstep.apart(_act, k, t, o)))(keys, tables, obs)
    assert jax.tree.structure(got) == jax.tree.structure(want)
    for g, w in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
        assert g.dtype == w.dtype and g.shape == w.shape
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the conditional is the CPU path")
def test_apart_stays_one_conditional_under_vmap_with_the_function_inside(batch):
    jaxpr = jax.make_jaxpr(jax.vmap(lambda k, t, o: lockstep.apart(_act, k, t, o)))(*batch)
    top = [e.primitive.name for e in jaxpr.jaxpr.eqns]
    assert top.count("cond") == 1, top  # not turned into a select of both branches
    assert "argmax" not in top and "random_bits" not in top and "threefry2x32" not in top  # only in the branch
    inside = [e.primitive.name for e in equations(jaxpr) if e.primitive.name not in top]
    assert "argmax" in inside


def test_the_q_learning_agents_opt_in_and_the_others_do_not():
    on = {name for name, agent in agents.AGENTS.items() if agent.hints.act_apart}
    assert on == {"q_learning_episodic", "q_learning_continuous"}
    assert agents.get("q_learning_episodic", variant="colosseum").hints.act_apart


def test_a_run_with_the_action_apart_equals_one_without(monkeypatch):
    # The runner routes the act through _apart exactly when the agent asks, and the boundary changes no result: the
    # same values at every record and the same final tables. (One agent: the runner's code path is the same for all.)
    calls = []
    monkeypatch.setattr(lockstep, "apart", lambda fn, *args: calls.append(fn) or _apart(fn, *args))
    agent = agents.get("q_learning_episodic")
    mdps = [jaxmdp.make("RiverSwim", episodic=True, seed=i, size=5) for i in range(2)]
    grid = runner.product(mdps, [agent.default_hparams], seeds=range(3))
    runs = {}
    for on in (True, False):
        n_calls = len(calls)
        runs[on] = runner.run(agent.with_hints(act_apart=on), grid, 600, log_period=50, n_records=4)
        assert (len(calls) > n_calls) == on
    for got, want in zip(jax.tree.leaves((runs[True].values, runs[True].agent_state)),
                         jax.tree.leaves((runs[False].values, runs[False].agent_state))):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    assert np.ptp(np.asarray(runs[True].agent_state.Q)) > 0  # it learnt something (the tables moved)
