"""A deep agent's run on a BlockMDP, interrupted and resumed from its checkpoint, equals the straight run byte for
byte: the records, the runner's CSV and the whole agent state (online and target networks, Adam's moments and step
count, the replay buffer's items, write position and fill flag, the step counters).

How we know the comparison has teeth: the run is cut after 2 of 5 chunks, when the agent has already taken SGD steps
(Adam's state is not its initial one) and its replay buffer is partly filled (it fills and wraps around after the
resume), on noisy observations (the emission noise has a stream of its own, which the resumed run must continue).
A checkpoint that dropped or reset any of these would give other parameters at the end.
"""

from __future__ import annotations

import csv

import jax
import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp.experiment import runner

N_STEPS, CHUNK = 300, 60
HP = dict(network_width=8, network_depth=1, batch_size=4, replay_capacity=150, min_replay=8)


def _rows(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    cut = rows[0].index("steps_per_second")
    return [r[:cut] + r[cut + 1:] for r in rows]


@pytest.fixture(scope="module")
def block():
    mdp = jaxmdp.make("RiverSwim", episodic=False, seed=0, size=5, p_rand=0.1, make_reward_stochastic=True)
    return jaxmdp.block_mdp(mdp, "state_info", "gaussian", scale=0.5)


def test_dqn_on_a_block_mdp_resumes_byte_for_byte(block, tmp_path):
    agent = agents.get("dqn_continuous")
    g = runner.product([block], [agent.default_hparams.replace(**HP)], seeds=[0, 1])
    kw = dict(log_period=CHUNK, n_records=5, chunk_steps=CHUNK)
    whole = runner.run(agent, g, N_STEPS, csv_path=tmp_path / "whole.csv", **kw)
    ckpt, path = tmp_path / "run.npz", tmp_path / "parts.csv"
    part = runner.run(agent, g, N_STEPS, csv_path=path, checkpoint_path=ckpt, stop_after_chunks=2, **kw)
    assert part.steps[-1] == 2 * CHUNK and ckpt.exists()
    state = part.agent_state
    assert np.all(np.asarray(state.sgd_steps) > 0)  # Adam's moments and the target network have moved
    assert np.all(np.asarray(state.replay.current_index) == 2 * CHUNK) and not np.any(state.replay.is_full)
    rest = runner.run(agent, g, N_STEPS, csv_path=path, checkpoint_path=ckpt, **kw)
    np.testing.assert_array_equal(rest.steps, whole.steps)
    np.testing.assert_array_equal(rest.values, whole.values)
    leaves, treedef = jax.tree.flatten(whole.agent_state)
    resumed, resumed_def = jax.tree.flatten(rest.agent_state)
    assert resumed_def == treedef
    for i, (a, b) in enumerate(zip(leaves, resumed, strict=True)):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), f"agent state leaf {i}"
    assert np.all(np.asarray(whole.agent_state.replay.is_full))  # the buffer wrapped after the resume
    assert _rows(path) == _rows(tmp_path / "whole.csv") and len(_rows(path)) == 1 + 5 * 2
