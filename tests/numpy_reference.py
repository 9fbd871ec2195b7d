"""Independent numpy computations used as references by the indicator, runner and agent tests."""

from __future__ import annotations

import itertools

import numpy as np


def finite_horizon_eval(T, R, pi, H):
    """``V_0`` of a policy ``pi[H, S, A]`` (or ``[S, A]``) by backward induction with explicit loops."""
    S, A, _ = T.shape
    pi = np.broadcast_to(pi, (H, S, A))
    V = np.zeros(S)
    for h in reversed(range(H)):
        Vn = np.zeros(S)
        for s in range(S):
            for a in range(A):
                Vn[s] += pi[h, s, a] * (R[s, a] + T[s, a] @ V)
        V = Vn
    return V


def finite_horizon_optimal(T, R, H, sign=1.0):
    """``V*_0`` (``sign=1``) or the minimal ``V_0`` (``sign=-1``) by backward induction with max / min."""
    V = np.zeros(T.shape[0])
    for _ in range(H):
        Q = R + T @ V
        V = Q.max(-1) if sign > 0 else Q.min(-1)
    return V


def gain_ergodic(T, R, pi):
    """Gain of a stationary policy whose chain has one recurrent class (stationary distribution, least squares)."""
    S = T.shape[0]
    P = np.einsum("sa,sat->st", pi, T)
    r = (pi * R).sum(-1)
    M = np.vstack([P.T - np.eye(S), np.ones((1, S))])
    mu = np.linalg.lstsq(M, np.r_[np.zeros(S), 1.0], rcond=None)[0]
    return float(mu @ r)


def gain_from(T, R, pi, s, n_iter=20000):
    """Gain of a stationary policy from state ``s`` by Cesàro averaging of ``P^n r`` (any chain)."""
    P = np.einsum("sa,sat->st", pi, T)
    r = (pi * R).sum(-1)
    d = np.zeros(T.shape[0])
    d[s] = 1.0
    total = 0.0
    for _ in range(n_iter):
        total += d @ r
        d = d @ P
    return total / n_iter


def one_hot(actions, A):
    return np.eye(A)[np.asarray(actions)]


def all_deterministic_gains(T, R):
    """Gains of every deterministic stationary policy of an MDP whose policies are all ergodic."""
    S, A, _ = T.shape
    return np.array([gain_ergodic(T, R, one_hot(c, A)) for c in itertools.product(range(A), repeat=S)])


def reachability(P):
    """Reflexive-transitive closure of ``P > 0`` (Warshall's algorithm)."""
    reach = (P > 0) | np.eye(len(P), dtype=bool)
    for k in range(len(P)):
        reach |= reach[:, [k]] & reach[[k], :]
    return reach


def gth_elimination(P):
    """Scalar Grassmann-Taksar-Heyman elimination in float64 with explicit loops, positions ``S-1 .. 1``: returns
    ``M`` (``M[:k, k]`` the column divided by ``s_k``, ``M[k, :k]`` the row at its elimination) and ``s``."""
    M, S = np.array(P, np.float64), len(P)
    s = np.zeros(S)
    for k in range(S - 1, 0, -1):
        s[k] = sum(M[k, j] for j in range(k))
        if s[k] > 0:
            M[:k, k] /= s[k]
            for i in range(k):
                for j in range(k):
                    M[i, j] += M[i, k] * M[k, j]
        else:
            M[:k, k] = 0.0
    return M, s


def chain_gain(P, r):
    """``P* r`` in float64: recurrent classes from the closure, each class's stationary distribution by GTH on the
    class alone (:func:`gth_elimination`, then ``pi_k = sum_{j<k} pi_j M[j, k]``), and the transient states'
    absorption by a linear solve ``(I - P_TT) g_T = P_TR g_R``."""
    P, r = np.asarray(P, np.float64), np.asarray(r, np.float64)
    S = len(P)
    reach = reachability(P)
    recurrent = np.all(~reach | reach.T, axis=1)
    g = np.zeros(S)
    done = np.zeros(S, bool)
    for s in np.flatnonzero(recurrent):
        if done[s]:
            continue
        members = np.flatnonzero(reach[s] & reach[:, s])
        M, _ = gth_elimination(P[np.ix_(members, members)])
        pi = np.zeros(len(members))
        pi[0] = 1.0
        for k in range(1, len(members)):
            pi[k] = pi[:k] @ M[:k, k]
        g[members] = pi @ r[members] / pi.sum()
        done[members] = True
    T = np.flatnonzero(~recurrent)
    if len(T):
        R_ = np.flatnonzero(recurrent)
        g[T] = np.linalg.solve(np.eye(len(T)) - P[np.ix_(T, T)], P[np.ix_(T, R_)] @ g[R_])
    return g


def discounted_optimum(T, R, gamma):
    """Optimal ``V*``, ``Q*`` of a dense model ``T[S, A, S]``, ``R[S, A]`` (``-inf`` for unavailable actions) in
    float64: policy iteration with exact evaluation and a ``1e-12`` switching rule, checked by its Bellman residual."""
    T, R = np.asarray(T, np.float64), np.asarray(R, np.float64)
    S = R.shape[0]
    s = np.arange(S)
    pi = R.argmax(-1)
    for _ in range(1000):
        V = np.linalg.solve(np.eye(S) - gamma * T[s, pi], R[s, pi])
        Q = R + gamma * T @ V
        switch = Q.max(-1) > Q[s, pi] + 1e-12 * (1 + np.abs(V).max())
        if not switch.any():
            break
        pi = np.where(switch, Q.argmax(-1), pi)
    assert np.max(np.abs(Q.max(-1) - V)) <= 1e-9 * (1 + np.abs(V).max())  # V = max_a Q(V): V is V*
    return V, Q
