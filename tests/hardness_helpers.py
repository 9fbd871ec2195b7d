"""Independent numpy computations (float64, brute force) used by the hardness tests."""

from __future__ import annotations

import itertools

import numpy as np

import jaxmdp


def deterministic_policies(S: int, A: int):
    for actions in itertools.product(range(A), repeat=S):
        yield np.asarray(actions)


def policy_hitting_times(P: np.ndarray, e: int) -> np.ndarray:
    """Expected hitting times of ``e`` under the chain ``P`` (``inf`` where ``e`` is not reached almost surely)."""
    S = P.shape[0]
    ok = np.ones(S, bool)
    changed = True
    while changed:  # states from which every positive-probability step stays in ok (or hits e) and e is reachable
        changed = False
        reach = np.zeros(S, bool)
        reach[e] = True
        grow = True
        while grow:
            new = reach | (ok & ((P[:, reach] > 0).any(1)))
            grow = bool((new != reach).any())
            reach = new
        leak = ((P > 0) & ~(ok | (np.arange(S) == e))[None, :]).any(1)
        new_ok = ok & reach & ~leak
        new_ok[e] = True
        if (new_ok != ok).any():
            ok, changed = new_ok, True
    h = np.full(S, np.inf)
    idx = [s for s in range(S) if ok[s] and s != e]
    h[e] = 0.0
    if idx:
        Q = P[np.ix_(idx, idx)]
        h[idx] = np.linalg.solve(np.eye(len(idx)) - Q, np.ones(len(idx)))
    return h


def brute_force_diameter(T: np.ndarray) -> float:
    """``max_{s != e} min_pi E[T^pi(s -> e)]`` by enumerating all deterministic stationary policies."""
    S, A, _ = T.shape
    best = np.full((S, S), np.inf)
    for pol in deterministic_policies(S, A):
        P = T[np.arange(S), pol]
        for e in range(S):
            best[:, e] = np.minimum(best[:, e], policy_hitting_times(P, e))
    off = ~np.eye(S, dtype=bool)
    return float(best[off].max())


def time_augmented(T: np.ndarray, R: np.ndarray, P0: np.ndarray, H: int):
    """The explicit time-augmented continuous MDP on the reachable pairs: ``(T_aug, R_aug, pairs)``."""
    S, A, _ = T.shape
    reach = [set(np.nonzero(P0 > 0)[0].tolist())]
    for _ in range(1, H):
        reach.append({int(t) for s in reach[-1] for a in range(A) for t in np.nonzero(T[s, a] > 0)[0]})
    pairs = [(h, s) for h in range(H) for s in sorted(reach[h])]
    index = {p: i for i, p in enumerate(pairs)}
    N = len(pairs)
    Ta = np.zeros((N, A, N))
    Ra = np.zeros((N, A))
    for i, (h, s) in enumerate(pairs):
        Ra[i] = R[s]
        if h < H - 1:
            for t in np.nonzero(T[s].sum(0) > 0)[0]:
                Ta[i, :, index[(h + 1, int(t))]] = T[s, :, t]
        else:
            for s0 in np.nonzero(P0 > 0)[0]:
                Ta[i, :, index[(0, int(s0))]] = P0[s0]
    return Ta, Ra, pairs


def discounted_optimal_values(T: np.ndarray, R: np.ndarray, gamma: float, iters: int = 20_000) -> np.ndarray:
    """Plain float64 value iteration run far past convergence."""
    V = np.zeros(T.shape[0])
    for _ in range(iters):
        V_new = (R + gamma * T @ V).max(1)
        if np.max(np.abs(V_new - V)) < 1e-13:
            return V_new
        V = V_new
    return V


def deep_sea(n: int) -> jaxmdp.MDP:
    """Continuous DeepSea of size ``n`` built by hand: the triangle ``0 <= x <= y < n`` from the top-left corner,
    LEFT/RIGHT move one column and one row down, the bottom row returns to the start (paper App. C)."""
    states = [(x, y) for y in range(n) for x in range(y + 1)]
    index = {s: i for i, s in enumerate(states)}
    S = len(states)
    T = np.zeros((S, 2, S))
    R = np.zeros((S, 2))
    for (x, y), i in index.items():
        if y == n - 1:
            T[i, :, 0] = 1.0
            R[i, 1] = 1.0 if x == n - 1 else 0.0
        else:
            T[i, 0, index[(max(x - 1, 0), y + 1)]] = 1.0
            T[i, 1, index[(min(x + 1, y + 1), y + 1)]] = 1.0
    return jaxmdp.custom_mdp(T, R)


def reference_fixture_mdp(z) -> tuple[jaxmdp.MDP, np.ndarray | None]:
    """A fixture's MDP built with ``custom_mdp`` from its arrays (reward distributions from its entries), and the
    reference's episodic-graph order for episodic fixtures."""
    T = z["T"]
    mean = np.zeros(T.shape)
    conc = np.zeros(T.shape)
    for s, a, t, d, args, mu in zip(
        z["reward_entry_s"], z["reward_entry_a"], z["reward_entry_next_s"], z["reward_entry_dist"],
        z["reward_entry_args"], z["reward_entry_mean"],
    ):
        mean[s, a, t] = mu
        if str(d) == "beta":
            conc[s, a, t] = args[0] + args[1]
    H = int(z["H"]) if "H" in z else None
    m = jaxmdp.custom_mdp(T, None, z["P0"], H=H, reward_mean=mean, reward_conc=conc)
    return m, (z["episodic_graph_nodes"] if H is not None else None)


#: The reference's stored measures (index.json keys) and the relative tolerance of the colosseum variants against them.
REFERENCE_KEYS = ("diameter", "value_norm", "sum_reciprocals_suboptimality_gaps")
REFERENCE_RTOL = 1e-3


def assert_matches_reference(values, entries) -> None:
    """``values``: per :data:`REFERENCE_KEYS`, an array over ``entries`` (reference index entries) to match."""
    for name, got in zip(REFERENCE_KEYS, values):
        expected = np.array([e[name] for e in entries])
        np.testing.assert_allclose(np.asarray(got), expected, rtol=REFERENCE_RTOL, atol=1e-6, err_msg=name)

def normalize_by_hand(x: np.ndarray) -> np.ndarray:
    """Paper App. E with the 0.5 rule of docs/measures.md §6.5, entry by entry: ``(x - min) / (max - min)`` over all
    finite entries; 0.5 for every finite entry when ``max - min < 1e-4``; NaN for non-finite entries."""
    x = np.asarray(x, np.float64)
    out = np.full(x.shape, np.nan)
    finite = np.isfinite(x)
    if not finite.any():
        return out
    lo, hi = x[finite].min(), x[finite].max()
    for idx in zip(*np.nonzero(finite)):
        out[idx] = 0.5 if hi - lo < 1e-4 else (x[idx] - lo) / (hi - lo)
    return out
