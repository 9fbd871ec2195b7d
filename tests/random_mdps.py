"""Random small MDPs for the property tests (Hypothesis strategies) and independent numpy solvers for them.

A :class:`Draw` holds an MDP as small integers (transition weights, rewards in steps of ``1 / denom``, Beta
concentrations, start weights), so that a falsifying example prints as a constructor call that can be pasted into an
``@example(...)`` regression case, and so that Hypothesis shrinks towards fewer states, fewer successors and equal
rewards. The strategy's knobs reach the corner cases: absorbing states, deterministic and sparse rows (hence MDPs
with several closed classes and multichain policies), tied rewards (``denom = 4``), Beta rewards, several start
states and episodic horizons from 1.

Compilation dominates the cost of these tests, so every draw is padded to one canonical shape per setting
(:data:`S_PAD`, :data:`A_PAD`, successor lists of :data:`K_PAD`, episodes of static length :data:`H_PAD` with the
drawn horizon traced): the library's jitted functions compile once per module, not once per example.

The numpy solvers work in float64 on the real states and actions and share no code with the library: discounted
optimal values and gains by enumerating every deterministic stationary policy (at most ``3^5 = 243``), a policy's
gain from its chain's closed classes (stationary distributions on each, absorption probabilities from the transient
states), finite-horizon values by backward induction with explicit loops.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
from hypothesis import strategies as st

import jaxmdp

#: Canonical shape of every draw: states, actions, successor-list length, static episode length.
S_PAD, A_PAD, K_PAD, H_PAD = 5, 3, 5, 4


@dataclasses.dataclass(frozen=True)
class Draw:
    """An MDP as integers: ``T[s][a][t]`` proportional to ``weights[s][a][t]``, transition reward
    ``rewards[s][a][t] / denom`` (a Beta of that mean and concentration ``conc[s][a][t]`` where ``conc > 0``, else a
    point mass), ``P0`` proportional to ``p0``, ``horizon`` (``None``: continuous)."""

    weights: list
    rewards: list
    denom: int
    p0: list
    horizon: int | None = None
    conc: list | None = None

    @property
    def n_states(self) -> int:
        return len(self.weights)

    @property
    def n_actions(self) -> int:
        return len(self.weights[0])

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(T, R, P0)`` in float64: the kernel, the mean rewards ``R = sum_t T * reward_mean`` and the start
        distribution."""
        W = np.asarray(self.weights, np.float64)
        T = W / W.sum(-1, keepdims=True)
        R = (T * self.reward_mean()).sum(-1)
        p0 = np.asarray(self.p0, np.float64)
        return T, R, p0 / p0.sum()

    def reward_mean(self) -> np.ndarray:
        return np.asarray(self.rewards, np.float64) / self.denom

    def mdp(self, dtype=np.float32) -> jaxmdp.MDP:
        """The MDP built by :func:`jaxmdp.custom_mdp` (unpadded)."""
        T, _, P0 = self.arrays()
        conc = None if self.conc is None else np.asarray(self.conc, np.float64)
        return jaxmdp.custom_mdp(T, P0=P0, H=self.horizon, reward_mean=self.reward_mean(), reward_conc=conc,
                                 dtype=dtype)

    def padded(self, S: int = S_PAD, A: int = A_PAD, K: int = K_PAD, H: int = H_PAD) -> jaxmdp.MDP:
        """The MDP padded to the canonical shape (``H`` only for an episodic draw; start lists of ``S`` entries),
        without its labels and with ``stochastic_rewards`` True exactly when the draw came from a strategy with Beta
        rewards (True is always correct: point masses are sampled as their value), so that every draw of a strategy
        has the same static fields and one jitted function serves them all."""
        m = jaxmdp.pad(self.mdp(), S, A, K, H=H if self.horizon is not None else None, n_starts=S)
        return m.strip().replace(stochastic_rewards=self.conc is not None)


@st.composite
def draws(draw, episodic: bool, *, max_states: int = S_PAD, max_actions: int = A_PAD, max_horizon: int = H_PAD,
          beta_rewards: bool = False) -> Draw:
    """A random :class:`Draw` of 1 to ``max_states`` states and 1 to ``max_actions`` actions (see the module
    docstring for the knobs); ``beta_rewards`` lets some transitions have Beta rewards."""
    S = draw(st.integers(1, max_states), label="S")
    A = draw(st.integers(1, max_actions), label="A")
    rows = draw(st.sampled_from(["deterministic", "sparse", "dense"]), label="rows")
    weight_values = {"deterministic": [0], "sparse": [0, 0, 0, 1, 2], "dense": [1, 2, 3]}[rows]
    absorbing = draw(st.lists(st.sampled_from([False, False, False, True]), min_size=S, max_size=S),
                     label="absorbing")
    weights = []
    for s in range(S):
        per_action = []
        for _ in range(A):
            if absorbing[s]:
                row = [int(t == s) for t in range(S)]
            else:
                row = draw(st.lists(st.sampled_from(weight_values), min_size=S, max_size=S))
                if sum(row) == 0:  # deterministic rows, and sparse rows that drew no successor: one successor
                    row[draw(st.integers(0, S - 1))] = 1
            per_action.append(row)
        weights.append(per_action)
    denom = draw(st.sampled_from([4, 97]), label="denom")  # 4: many tied rewards
    lo = 1 if beta_rewards else 0
    hi = denom - 1 if beta_rewards else denom
    rewards = [[draw(st.lists(st.integers(lo, hi), min_size=S, max_size=S)) for _ in range(A)] for _ in range(S)]
    conc = None
    if beta_rewards:
        conc = [[draw(st.lists(st.sampled_from([0, 0, 2, 5]), min_size=S, max_size=S)) for _ in range(A)]
                for _ in range(S)]
    p0 = draw(st.lists(st.integers(0, 2), min_size=S, max_size=S), label="p0")
    if sum(p0) == 0:
        p0[0] = 1
    horizon = draw(st.integers(1, max_horizon), label="horizon") if episodic else None
    return Draw(weights, rewards, denom, p0, horizon, conc)


# ---------------------------------------------------------------------------------------------------------------
# Independent numpy solvers (float64, real states and actions only)
# ---------------------------------------------------------------------------------------------------------------


def deterministic_policies(S: int, A: int):
    """Every deterministic stationary policy as an ``[S]`` array of actions."""
    for actions in itertools.product(range(A), repeat=S):
        yield np.asarray(actions)


def chain(T: np.ndarray, R: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(P_pi, r_pi)`` of a deterministic policy."""
    states = np.arange(T.shape[0])
    return T[states, actions], R[states, actions]


def discounted_optimal(T: np.ndarray, R: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Q*, V*)`` by enumeration: ``V* = max_pi (I - gamma P_pi)^{-1} r_pi`` state by state (an optimal
    deterministic stationary policy attains the maximum everywhere at once)."""
    S, A, _ = T.shape
    V = np.full(S, -np.inf)
    for pi in deterministic_policies(S, A):
        P, r = chain(T, R, pi)
        V = np.maximum(V, np.linalg.solve(np.eye(S) - gamma * P, r))
    return R + gamma * T @ V, V


def reachability(P: np.ndarray) -> np.ndarray:
    """``reach[i, j]``: ``j`` can be reached from ``i`` in zero or more steps of the graph ``P > 0``."""
    S = P.shape[0]
    reach = (P > 0) | np.eye(S, dtype=bool)
    for _ in range(S):
        reach = reach | ((reach.astype(int) @ reach.astype(int)) > 0)
    return reach


def chain_gain(P: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Gain ``P* r`` of a Markov reward chain from every state: on each closed class the stationary distribution's
    average reward; from a transient state the absorption-weighted gains of the classes."""
    S = P.shape[0]
    reach = reachability(P)
    recurrent = np.array([all(reach[j, i] for j in range(S) if reach[i, j]) for i in range(S)])
    g = np.zeros(S)
    done = np.zeros(S, bool)
    for i in range(S):
        if recurrent[i] and not done[i]:
            C = np.flatnonzero(reach[i] & reach[:, i])
            n = len(C)
            M = np.vstack([P[np.ix_(C, C)].T - np.eye(n), np.ones((1, n))])
            mu = np.linalg.lstsq(M, np.r_[np.zeros(n), 1.0], rcond=None)[0]
            g[C] = mu @ r[C]
            done[C] = True
    tr = np.flatnonzero(~recurrent)
    if tr.size:
        rec = np.flatnonzero(recurrent)
        g[tr] = np.linalg.solve(np.eye(tr.size) - P[np.ix_(tr, tr)], P[np.ix_(tr, rec)] @ g[rec])
    return g


def optimal_gain_vector(T: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``g*(s) = max_pi g_pi(s)`` over deterministic stationary policies (Puterman Thm. 9.1.8: one such policy is
    optimal from every state at once)."""
    S, A, _ = T.shape
    return np.max([chain_gain(*chain(T, R, pi)) for pi in deterministic_policies(S, A)], axis=0)


def finite_horizon_optimal(T: np.ndarray, R: np.ndarray, H: int) -> np.ndarray:
    """``V*_h`` for ``h = 0..H`` (``[H + 1, S]``, ``V*_H = 0``) by backward induction with explicit loops."""
    S, A, _ = T.shape
    V = np.zeros((H + 1, S))
    for h in reversed(range(H)):
        for s in range(S):
            V[h, s] = max(R[s, a] + sum(T[s, a, t] * V[h + 1, t] for t in range(S)) for a in range(A))
    return V
