"""Planning only the members that asked (jaxmdp.experiment.planning): bit for bit the results of planning the whole
batch whenever one member asks (``plan_slots`` at least the batch, the earlier scheme), for every slot count, on one
device and on two (shard_map)."""

from __future__ import annotations

import functools
import hashlib
import re
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp.experiment import lockstep, programs, runner
from jaxmdp.experiment.agent_interface import spec_of, where_due
from jaxmdp.experiment.members import member_mdp
from jaxmdp.experiment.planning import default_plan_slots, plan_due
from progress_run import run_on_host_devices
from jaxpr_eqns import equations


def _toy_plan(key, state):
    # Depends on the key and on every leaf of the member's state, so a wrong gather or scatter shows.
    x, n = state["x"], state["n"]
    return {"x": x * 2.0 + jax.random.uniform(key, x.shape) + n, "n": n + 1}


@pytest.mark.parametrize("lone_rounds", [True, False])
@pytest.mark.parametrize("whole_batch", [True, False])
@pytest.mark.parametrize("slots", [1, 2, 3, 7])
def test_plan_due_equals_planning_the_whole_batch(slots, whole_batch, lone_rounds):
    B = 7
    states = {"x": jnp.arange(B * 3, dtype=jnp.float32).reshape(B, 3), "n": jnp.arange(B, dtype=jnp.int32) * 10}
    keys = jax.random.split(jax.random.key(3), B)
    patterns = [np.zeros(B, bool), np.ones(B, bool), np.eye(B, dtype=bool)[B - 1], np.eye(B, dtype=bool)[0]]
    patterns += [np.random.default_rng(i).random(B) < 0.5 for i in range(4)]
    run = jax.jit(lambda due: plan_due(_toy_plan, slots, due, keys, states, whole_batch, lone_rounds))
    for due in patterns:
        due = jnp.asarray(due)
        want = where_due(due, jax.vmap(_toy_plan)(keys, states), states)
        got = run(due)
        for name in states:
            np.testing.assert_array_equal(got[name], want[name], err_msg=f"{name}, due {due}")


def _scatter_shapes(jaxpr) -> list[tuple[int, ...]]:
    """The output shapes of every scatter in ``jaxpr`` and in the jaxprs of its loops, conditionals and calls."""
    return [tuple(e.outvars[0].aval.shape) for e in equations(jaxpr) if e.primitive.name.startswith("scatter")]


@pytest.mark.parametrize("slots", [1, 2])
def test_plan_due_does_not_write_back_the_leaves_a_plan_passes_through(slots):
    # A plan that reads a large leaf and returns it as it is (episodic PSRL's dense counts): writing it back is a
    # no-op that XLA turned into two copies of the whole leaf per round with one slot. The rounds scatter the
    # planned leaf and leave the passed-through one alone; the results are those of planning the whole batch.
    B = 5
    states = {"q": jnp.zeros((B, 2)), "counts": jnp.arange(B * 12, dtype=jnp.int32).reshape(B, 4, 3)}
    keys = jax.random.split(jax.random.key(0), B)

    def plan(key, state):
        q = state["q"] + jnp.sum(state["counts"]).astype(jnp.float32) + jax.random.uniform(key)
        return where_due(jnp.asarray(True), {"q": q, "counts": state["counts"]}, state)

    due = jnp.asarray([True, False, True, True, False])
    rounds = lambda due: plan_due(plan, slots, due, keys, states, False, lone_rounds=False)  # noqa: E731
    shapes = _scatter_shapes(jax.make_jaxpr(rounds)(due).jaxpr)
    assert (B, 2) in shapes and (B, 4, 3) not in shapes, shapes
    want = where_due(due, jax.vmap(plan)(keys, states), states)
    got = jax.jit(rounds)(due)
    for name in states:
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)


def test_where_due_keeps_a_passed_through_leaf_as_it_is_for_one_member():
    # One member's merge (a plan guarding itself, under the rounds' vmap) returns a passed-through leaf as it is, so
    # that the rounds do not write it back; the runner's merge over a batch selects every leaf (XLA simplifies the
    # select, and a leaf returned as it is made XLA copy a deep agent's replay buffer at every step:
    # test_a_deep_agent_s_step_loop_does_not_copy_its_replay_buffer).
    old = {"a": jnp.arange(3.0), "b": jnp.zeros(3)}
    new = {"a": old["a"], "b": jnp.ones(3)}
    for due in (jnp.asarray(False), jnp.asarray([True, False, True])):
        merged = where_due(due, new, old)
        assert (merged["a"] is old["a"]) == (due.ndim == 0)
        np.testing.assert_array_equal(merged["a"], old["a"])
        np.testing.assert_array_equal(merged["b"], jnp.where(due, 1.0, 0.0) * jnp.ones(3))


@pytest.mark.parametrize("name", ["dqn_continuous", "boot_dqn_episodic", "actor_critic_continuous",
                                  "actor_critic_rnn_episodic"])
def test_the_deep_agents_plan_the_whole_batch(name):
    # Their members take their gradient steps together: a slot per member, so the runner compiles no planning rounds.
    agent = agents.get(name)
    assert agent.hints.plans_together
    states = {"replay": jax.ShapeDtypeStruct((40, 10_000, 3), jnp.float32)}
    assert runner.plan_slots_for(agent, states) == 40
    assert runner.plan_slots_for(agent.with_hints(plans_together=False), states) == 3


def _chunk_text(agent, g) -> str:
    """The runner's compiled chunk program of ``agent`` on grid ``g`` (one device), as optimised HLO text."""
    settings = runner._validated_settings(agent, g, 200, 100, 2, "paper", None, 1)
    display, _ = runner._display(False, agent, g, settings.n_steps)
    return runner._compile(agent, g, settings, display).chunk.as_text()


def _copies(text: str, dims: str) -> list[str]:
    """The ``copy`` instructions of ``text`` whose f32 result has the dimensions ``dims`` (e.g. ``"20,37,37"``)."""
    return [line for line in text.splitlines() if re.search(rf"= f32\[{dims}\]\S* copy\(", line)]


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the CPU compiler option")
def test_the_runner_compiles_so_that_a_plan_updates_the_parameters_in_place(monkeypatch):
    # The actor-critic (hidden width 37, a size no other array has) on 20 members learns under the runner's planning
    # conditional. With XLA's default copy insertion every parameter and Adam moment came out of the conditional into
    # a new buffer and was copied back into the loop's carry at every step; with the runner's compiler options
    # (programs.CPU_COMPILER_OPTIONS) none is (docs/performance.md, Deep agents).
    agent = agents.get("actor_critic_continuous")
    mdp = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False),
                           "state_info")
    g = runner.product([mdp], [agent.default_hparams.replace(width=37)], seeds=range(20))
    assert not _copies(_chunk_text(agent, g), "20,37,37")
    monkeypatch.setattr(runner, "compile_options", lambda platform: None)
    assert len(_copies(_chunk_text(agent, g), "20,37,37")) >= 6  # two hidden kernels x (params, two Adam moments)


def test_an_option_the_jaxlib_does_not_know_compiles_without_the_options():
    lowered = jax.jit(lambda x: x * 2.0).lower(jnp.arange(3.0))
    compiled = programs.compile_lowered(lowered, {"xla_no_such_option_in_any_jaxlib": True})
    np.testing.assert_array_equal(compiled(jnp.arange(3.0)), [0.0, 2.0, 4.0])
    with pytest.raises(Exception, match="No such compile option"):
        lowered.compile({"xla_no_such_option_in_any_jaxlib": True})
    assert programs.compile_options("gpu") is None
    # The runner's own options are known to the installed jaxlib (a rename would silently lose their speed).
    lowered.compile(programs.compile_options("cpu"))


def test_a_deep_agent_s_step_loop_does_not_copy_its_replay_buffer():
    # DQN (a capacity of 3 000 items, a size no other array of the program has) on 20 members: the compiled chunk
    # program writes each step's transition into the buffer in place. Planning rounds, or a whole-batch merge that
    # returned the buffer as it is, made XLA copy the buffer's arrays twice per step, halving DQN's throughput
    # (docs/performance.md, Deep agents).
    agent = agents.get("dqn_continuous")
    mdp = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False),
                           "state_info")
    g = runner.product([mdp], [agent.default_hparams.replace(replay_capacity=3000)], seeds=range(20))
    text = _chunk_text(agent, g)
    buffer_copies = [line for line in text.splitlines()
                     if re.search(r"= \w+\[[0-9,]*\b3000\b[0-9,]*\]\S* copy\(", line)]
    assert "3000" in text and not buffer_copies, buffer_copies[:4]


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the CPU backend's layouts")
def test_boot_dqn_s_ensemble_moves_no_activation_between_layouts():
    # BootDQN (hidden width 29 and batch 41, sizes no other array has) on 6 members: its ensemble's activations are
    # laid out [heads, width, batch] from the first layer on (agents.deep.networks.ensemble_apply), so that the
    # compiled chunk program neither copies nor transposes an array with the width and the batch among its dimensions.
    # With [heads, batch, width] XLA's CPU backend transposed and copied them around its batched products, forward
    # and backward, and the SGD step ran about 1.3x slower (docs/performance.md, Deep agents).
    agent = agents.get("boot_dqn_continuous")
    mdp = jaxmdp.block_mdp(jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, randomize_actions=False),
                           "state_info")
    hp = agent.default_hparams.replace(network_width=29, batch_size=41, n_ensemble=5, replay_capacity=500)
    text = _chunk_text(agent, runner.product([mdp], [hp], seeds=range(6)))
    moved = [line for line in text.splitlines()
             if re.search(r"= f32\[(?=[0-9,]*\b29\b)(?=[0-9,]*\b41\b)[0-9,]*\]\S* (copy|transpose)\(", line)]
    assert re.search(r"f32\[[0-9,]*\b29\b[0-9,]*\b41\b[0-9,]*\]", text) and not moved, moved[:4]


def test_default_plan_slots():
    assert [default_plan_slots(b) for b in (1, 15, 16, 17, 90, 180)] == [1, 1, 1, 2, 6, 12]
    # A byte cap: at most slot_bytes // member_bytes slots, at least one, never more than without it.
    assert [default_plan_slots(90, 1000, cap) for cap in (None, 0, 999, 1000, 2999, 3000, 10**9)] == [6, 1, 1, 1, 2,
                                                                                                      3, 6]
    assert default_plan_slots(90, 0, 10) == 6  # no state: nothing to cap


def test_plan_slots_for_caps_by_one_member_s_state_on_a_cpu():
    agent = agents.get("psrl_episodic")
    states = {"counts": jax.ShapeDtypeStruct((40, 10, 100), jnp.int32),
              "q": jax.ShapeDtypeStruct((40, 250), jnp.float32)}
    member = 10 * 100 * 4 + 250 * 4  # 5 000 bytes
    on_cpu = jax.default_backend() == "cpu"
    for cap, want in ((None, 3), (2 * member, 2 if on_cpu else 3), (member - 1, 1 if on_cpu else 3)):
        assert runner.plan_slots_for(agent.with_hints(plan_slot_bytes=cap), states) == want, cap
    assert runner.plan_slots_for(agent, jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), states)) == 3
    # Continuous PSRL plans one member a round on a CPU whatever its state (a cap of 0 bytes); UCRL2 is not capped.
    assert runner.plan_slots_for(agents.get("psrl_continuous"), states) == (1 if on_cpu else 3)
    assert runner.plan_slots_for(agents.get("ucrl2"), states) == 3


@pytest.mark.nightly  # by default: test_results_do_not_depend_on_the_slots
def test_the_runner_picks_the_slots_by_the_agent_s_state_bytes(monkeypatch):
    # The runner's default slots come from the shard's agent states (their shapes) and the agent's plan_slot_bytes,
    # and give the results of planning the whole batch.
    calls = []
    real = lockstep.default_plan_slots
    monkeypatch.setattr(lockstep, "default_plan_slots", lambda *args: calls.append(args) or real(*args))
    agent = agents.get("psrl_episodic").with_hints(plan_slot_bytes=12345)  # a new program, traced here
    g = _episodic_grid(agent)
    got = runner.run(agent, g, 150, log_period=10, n_records=5)
    hp = jax.tree.map(lambda x: jnp.asarray(x[0]), g.hparams)  # float32, as the runner holds them
    one = agent.init(jax.random.key(0), spec_of(member_mdp(g.mdps, 0), 150), hp)
    member_bytes = sum(x.nbytes for x in jax.tree.leaves(one))
    assert calls and set(calls) == {(g.n_members, member_bytes, 12345 if jax.default_backend() == "cpu" else None)}
    _assert_same_run(got, _whole_batch_run("psrl_episodic", _episodic_grid, 150))


def _assert_same_run(a, b):
    np.testing.assert_array_equal(a.values, b.values)
    for x, y in zip(jax.tree.leaves(a.agent_state), jax.tree.leaves(b.agent_state)):
        np.testing.assert_array_equal(x, y)


def _digests(result) -> list[str]:
    """SHA-256 of the records and of every final agent-state leaf (dtype and shape included): a run's bits, small
    enough to come back from a subprocess."""
    arrays = [result.values, *jax.tree.leaves(result.agent_state)]
    return [f"{x.dtype}{x.shape}" + hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()
            for x in map(np.asarray, arrays)]


def _episodic_grid(agent):
    # Horizons 3, 4, 5, 6 (RiverSwim's horizon is its size): episodes end at different steps, several at once at
    # common multiples (every 12 steps: 3, 4 and 6, i.e. six of the eight members; every 15: 3 and 5, four).
    mdps = [jaxmdp.make("RiverSwim", episodic=True, seed=0, size=n, randomize_actions=False) for n in (3, 4, 5, 6)]
    return runner.product(mdps, [agent.default_hparams], seeds=[0, 1])


def _continuous_grid(agent):
    mdps = [jaxmdp.make("RiverSwim", episodic=False, seed=0, size=n, randomize_actions=False, p_lazy=0.1,
                        make_reward_stochastic=True) for n in (4, 6)]
    return runner.product(mdps, [agent.default_hparams], seeds=[0, 1, 2])


@pytest.mark.parametrize("name, make_grid, n_steps, slots", [
    ("psrl_episodic", _episodic_grid, 150, 2),
    pytest.param("psrl_episodic", _episodic_grid, 150, 1, marks=pytest.mark.nightly),
    pytest.param("ucrl2", _continuous_grid, 400, 2, marks=pytest.mark.nightly),
    ("psrl_continuous", _continuous_grid, 400, 1),
    pytest.param("psrl_continuous", _continuous_grid, 400, 2, marks=pytest.mark.nightly),
])
def test_results_do_not_depend_on_the_slots(name, make_grid, n_steps, slots):
    agent = agents.get(name)
    g = make_grid(agent)
    # Two slots: one member waiting leaves a slot empty, two to four (episodic; continuous: two or three) need rounds,
    # more than half the batch is planned whole (episodic PSRL; UCRL2 and continuous PSRL plan in rounds only,
    # RunnerHints.whole_batch_plans). One slot (PSRL continuous's on a CPU): every plan is a call without vmap.
    whole = _whole_batch_run(name, make_grid, n_steps)
    _assert_same_run(runner.run(agent, g, n_steps, log_period=10, n_records=5, plan_slots=slots), whole)


@functools.cache
def _whole_batch_run(name, make_grid, n_steps):
    """The grid planned as a whole batch on one device (``plan_slots`` = the batch): the results every other slot
    count and shard count must give, computed once for this module's tests."""
    agent = agents.get(name)
    g = make_grid(agent)
    return runner.run(agent, g, n_steps, log_period=10, n_records=5, plan_slots=g.n_members)


def test_bad_plan_slots():
    agent = agents.get("psrl_episodic")
    for bad in (0, -1, 2.5):
        with pytest.raises(ValueError, match="plan_slots"):
            runner.run(agent, _episodic_grid(agent), 10, plan_slots=bad)


SHARDED = textwrap.dedent(
    """
    import json
    import agents, jax
    from jaxmdp.experiment import runner
    from test_runner_planning import _digests, _episodic_grid

    assert jax.local_device_count() == 2
    agent = agents.get("psrl_episodic")
    g = _episodic_grid(agent)
    two = runner.run(agent, g, 150, log_period=10, n_records=5, shards=2, plan_slots=1)
    print(json.dumps({"digests": _digests(two)}))
    """
)


@pytest.mark.nightly  # by default: test_runner_sharding.py's two shards, test_properties_runner.py on 2 devices
def test_two_shards_with_one_slot_equal_the_whole_batch():
    # The two shards run in a subprocess (the host device count is fixed when JAX starts); the whole batch on one
    # device is this process's run, shared with test_results_do_not_depend_on_the_slots.
    whole = _whole_batch_run("psrl_episodic", _episodic_grid, 150)
    assert run_on_host_devices(SHARDED, 2)["digests"] == _digests(whole)
