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
