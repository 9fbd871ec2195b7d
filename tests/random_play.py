"""An agent's state after uniformly random play (``update`` only), for tests of planning from a realistic state."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxmdp
from jaxmdp.experiment.agent_interface import Transition, spec_of


def played(agent, mdp, hp, n_steps: int, key, state=None):
    """The agent's state after ``n_steps`` uniformly random actions on ``mdp`` (``update`` only), with a plan due."""
    spec = spec_of(mdp, 500_000)
    state = agent.init(key, spec, hp) if state is None else state
    A = int(np.sum(np.asarray(mdp.action_mask)))

    def body(c, k):
        obs, env_state, st = c
        k_a, k_s = jax.random.split(k)
        a = jax.random.randint(k_a, (), 0, A)
        obs2, env_state2, r, term, _, info = jaxmdp.step(k_s, env_state, a, mdp)
        tr = Transition(obs=obs, action=a, reward=r, next_obs=info["final_observation"], h=env_state.h,
                        terminated=term)
        return (obs2, env_state2, agent.update(st, tr)), None

    obs, env_state = jaxmdp.reset(jax.random.fold_in(key, 1), mdp)
    (_, _, state), _ = jax.lax.scan(jax.jit(body), (obs, env_state, state), jax.random.split(key, n_steps))
    return state.replace(plan_due=jnp.ones((), bool))
