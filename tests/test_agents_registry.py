"""The agent registry: the deep agents imported only when one is asked for, and ``agents.register`` for your own
agent (docs/guide/own_agent.md)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import textwrap

import pytest

import agents
from agents import search_spaces
from conftest import REPO
from hardness.benchmark import hparams
from jaxmdp.experiment.agent_interface import Agent


def _fresh_modules(code: str) -> set[str]:
    """The modules loaded by ``code`` in a fresh interpreter."""
    script = textwrap.dedent(code) + "\nimport json, sys; print(json.dumps(sorted(sys.modules)))\n"
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(REPO), "JAX_PLATFORMS": "cpu", "PATH": "/usr/bin:/bin"})
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


DEEP_MODULES = ("distrax", "flashbax", "agents.deep")


def test_import_agents_and_a_tabular_agent_leave_the_deep_agents_unimported():
    loaded = _fresh_modules("""
        import agents
        agents.get("q_learning_episodic")
        names = list(agents.AGENTS)
        assert "dqn_episodic" in names and "dqn_episodic" in agents.names(episodic=True, observations=("emission",))
    """)
    assert not {m for m in loaded if m.split(".")[0] in DEEP_MODULES or m.startswith("agents.deep")}
    assert "agents.q_learning_episodic" in loaded


def test_the_benchmark_and_the_commands_do_not_import_the_deep_agents():
    loaded = _fresh_modules("""
        import jaxmdp, hardness, hardness.benchmark.run, hardness.benchmark.report, hardness.benchmark.search
        import hardness.benchmark.baselines, hardness.cli.benchmark, hardness.cli.sweep, hardness.cli.regret_table
        from hardness.benchmark import run
        run.default_agents("episodic ergodic"); run.plan(run.quick_config(only=("RiverSwim",)))
        hardness.cli.benchmark.build_parser()
    """)
    assert not {m for m in loaded if m.split(".")[0] in DEEP_MODULES or m.startswith("agents.deep")}


def test_a_deep_agent_loads_when_asked_for_under_every_access():
    from agents.deep.dqn import DQN_EPISODIC

    assert agents.get("dqn_episodic") is DQN_EPISODIC and agents.AGENTS["dqn_episodic"] is DQN_EPISODIC
    from agents import ACTOR_CRITIC_RNN_CONTINUOUS

    assert agents.AGENTS["actor_critic_rnn_continuous"] is ACTOR_CRITIC_RNN_CONTINUOUS
    with pytest.raises(AttributeError, match="NOT_AN_AGENT"):
        agents.NOT_AN_AGENT  # noqa: B018


def test_the_names_settings_and_observations_known_before_import_are_the_agents_own():
    # agents.names answers from what the registry knows without importing; every agent, once loaded, agrees.
    assert list(agents.AGENTS) == [
        "random_episodic", "random_continuous", "q_learning_episodic", "q_learning_continuous", "psrl_episodic",
        "psrl_continuous", "ucrl2", "dqn_episodic", "dqn_continuous", "boot_dqn_episodic", "boot_dqn_continuous",
        "actor_critic_episodic", "actor_critic_continuous", "actor_critic_rnn_episodic",
        "actor_critic_rnn_continuous"]
    for name, deferred in agents._DEEP.items():  # what the registry knows before the import
        agent = deferred.load()
        assert (agent.name, agent.episodic, agent.observation) == (name, deferred.episodic, deferred.observation)
    for name in agents.AGENTS:
        agent = agents.AGENTS[name]
        assert agent.name == name
        for episodic in (True, False):
            for obs in (("state",), ("emission",), ("any",), ("state", "any")):
                assert (name in agents.names(episodic=episodic, observations=obs)) == (
                    agent.episodic == episodic and agent.observation in obs), (name, episodic, obs)
    assert agents.names() == list(agents.AGENTS)
    with pytest.raises(ValueError, match="observations must be a tuple"):
        agents.names(observations="state")


def _user_agent(name: str = "my_q", base: Agent | None = None) -> Agent:
    return dataclasses.replace(base or agents.AGENTS["q_learning_episodic"], name=name)


def test_register_then_get_and_the_search_space(registry):
    mine = _user_agent()
    assert registry.register(mine, search_space={"c_1": (0.1, 0.9)}) is mine
    assert registry.get("my_q") is mine and registry.AGENTS["my_q"] is mine and "my_q" in registry.names()
    assert dict(search_spaces.SEARCH_SPACES["my_q"]) == {"c_1": (0.1, 0.9)}
    assert dict(search_spaces.search_space(mine)) == {"c_1": (0.1, 0.9)}
    registry.register(mine)  # the same agent again (its module imported twice): allowed, its space kept
    assert dict(search_spaces.SEARCH_SPACES["my_q"]) == {"c_1": (0.1, 0.9)}
    with pytest.raises(ValueError, match="already registered; pass replace=True"):
        registry.register(_user_agent())
    other = _user_agent()
    registry.register(other, replace=True)
    assert registry.get("my_q") is other and "my_q" not in search_spaces.SEARCH_SPACES
    with pytest.raises(ValueError, match="has no 'colosseum' variant"):
        registry.get("my_q", "colosseum")


def test_register_refuses_bad_agents_and_spaces(registry):
    with pytest.raises(ValueError, match="agent must be a jaxmdp.agent_interface.Agent; got dict"):
        registry.register({"name": "x"})
    with pytest.raises(ValueError, match="shipped agent's"):
        registry.register(_user_agent("ucrl2"))
    with pytest.raises(ValueError, match="shipped agent's"):
        registry.register(registry.AGENTS["ucrl2"], search_space={"alpha_p": (0.1, 1.0)})
    registry.register(registry.AGENTS["ucrl2"])  # a shipped agent as it is: a no-op
    with pytest.raises(ValueError, match="without '@'"):
        registry.register(_user_agent("my@q"))
    with pytest.raises(ValueError, match="'nope', not a field"):
        registry.register(_user_agent(), search_space={"nope": (0.0, 1.0)})
    with pytest.raises(ValueError, match="needs finite low < high"):
        registry.register(_user_agent(), search_space={"c_1": (0.5, 0.5)})
    with pytest.raises(ValueError, match="must map to \\(low, high\\)"):
        registry.register(_user_agent(), search_space={"c_1": 0.5})
    with pytest.raises(ValueError, match="non-empty mapping"):
        registry.register(_user_agent(), search_space={})
    with pytest.raises(ValueError, match="is static"):
        registry.register(_user_agent("my_dqn", registry.AGENTS["dqn_episodic"]),
                          search_space={"network_width": (1, 8)})
    with pytest.raises(ValueError, match="must hold a numeric scalar"):
        registry.register(_user_agent(), search_space={"bernstein": (0, 1)})
    assert "my_q" not in registry.AGENTS and "my_q" not in search_spaces.SEARCH_SPACES  # nothing half-registered


def test_a_registered_agent_runs_with_its_defaults_under_tuned_and_its_values_from_a_file(registry, tmp_path):
    from hardness.benchmark import run, search

    mine = registry.register(_user_agent(), search_space={"c_1": (0.1, 0.9)})
    assert hparams.hparams_for("my_q", "tuned") is mine.default_hparams
    assert "my_q" not in run.default_agents("episodic quick test")  # your agent runs when named
    path = tmp_path / "tuned.json"
    search.start_tuned_file(path)
    search.write_tuned(path, {"my_q": {"values": {"c_1": 0.25}}})
    assert float(hparams.hparams_for("my_q", path).c_1) == 0.25
    assert hparams.hparams_for("ucrl2", path) == hparams.hparams_for("ucrl2", "tuned")  # the shipped entries kept
    assert hparams.source_of("my_q", path) == f"the tuned file {path}"
    assert hparams.source_of("my_q") == "its defaults (not in the shipped tuned file)"
