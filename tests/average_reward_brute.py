"""Independent float64 computations for the average-reward measures (bias span, Burnetas-Katehakis constant): every
deterministic policy's gain and bias by dense numpy solves, the solutions of the optimality equation among them, and
the KL projection by scipy's constrained minimiser. They share no code with the library."""

from __future__ import annotations

import itertools

import numpy as np
from scipy.optimize import minimize

import jaxmdp


def closed_classes(P: np.ndarray) -> list[np.ndarray]:
    """The recurrent classes of a stochastic matrix (reachability by repeated boolean products)."""
    S = P.shape[0]
    reach = (P > 0) | np.eye(S, dtype=bool)
    for _ in range(S):
        reach = reach | ((reach.astype(int) @ reach.astype(int)) > 0)
    recurrent = [s for s in range(S) if all(reach[t, s] for t in range(S) if reach[s, t])]
    classes = {tuple(t for t in recurrent if reach[s, t] and reach[t, s]) for s in recurrent}
    return [np.asarray(c) for c in sorted(classes)]


def is_unichain(T: np.ndarray) -> bool:
    """Every deterministic stationary policy has exactly one recurrent class."""
    S, A, _ = T.shape
    return all(len(closed_classes(T[np.arange(S), pol])) == 1 for pol in itertools.product(range(A), repeat=S))


def gain_bias(P: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray]:
    """Gain and bias of a unichain chain: ``mu`` from ``mu (I - P) = 0, sum mu = 1`` (least squares), ``g = mu r``,
    ``h = (I - P + 1 mu)^{-1} (r - g)`` (the bias with ``mu h = 0``)."""
    S = P.shape[0]
    M = np.vstack([(np.eye(S) - P).T, np.ones((1, S))])
    mu = np.linalg.lstsq(M, np.r_[np.zeros(S), 1.0], rcond=None)[0]
    g = float(mu @ r)
    h = np.linalg.solve(np.eye(S) - P + np.outer(np.ones(S), mu), r - g)
    return g, h


def optimality_solutions(T: np.ndarray, R: np.ndarray, atol: float = 1e-9) -> list[tuple[float, np.ndarray]]:
    """``(g, h)`` of every deterministic policy with one recurrent class whose gain and bias satisfy the
    average-reward optimality equation ``h + g = max_a (R + T h)``."""
    S, A, _ = T.shape
    out = []
    for pol in itertools.product(range(A), repeat=S):
        idx = np.arange(S), np.asarray(pol)
        if len(closed_classes(T[idx])) > 1:
            continue
        g, h = gain_bias(T[idx], R[idx])
        if np.max(np.abs((R + T @ h).max(1) - g - h)) <= atol:
            out.append((g, h))
    return out


def random_unichain(rng: np.random.Generator, S: int, A: int, sparsity: float) -> tuple[np.ndarray, np.ndarray]:
    """``(T, R)`` of a random unichain MDP (kernels kept sparse with probability ``1 - sparsity`` per entry; drawn
    again until unichain)."""
    while True:
        T = rng.random((S, A, S)) * (rng.random((S, A, S)) < sparsity)
        T[np.arange(S)[:, None], np.arange(A)[None, :], rng.integers(0, S, (S, A))] += 0.1
        T /= T.sum(-1, keepdims=True)
        if is_unichain(T):
            return T, rng.random((S, A))


def kl_projection(p: np.ndarray, x: np.ndarray, mu: float, allowed: np.ndarray) -> float:
    """``min KL(p || q)`` over laws ``q`` on the ``allowed`` points with ``q . x >= mu`` (primal, SLSQP); ``inf`` when
    no allowed law reaches ``mu``."""
    if p @ x >= mu:
        return 0.0
    if x[allowed].max() <= mu:
        return np.inf
    on = p > 0
    idx = np.flatnonzero(allowed)
    top = idx[np.argmax(x[idx])]
    # Start inside the feasible set: p moved towards the best allowed point just past the threshold.
    w = (mu - p @ x) / (x[top] - p @ x)
    w += 0.05 * (1.0 - w)
    q0 = (1 - w) * p
    q0[top] += w
    q0 = np.clip(q0[idx], 1e-9, None)
    q0 /= q0.sum()

    def kl(q):
        full = np.zeros_like(p)
        full[idx] = q
        return float(np.sum(p[on] * np.log(p[on] / np.maximum(full[on], 1e-300))))

    cons = [{"type": "eq", "fun": lambda q: q.sum() - 1.0}, {"type": "ineq", "fun": lambda q: q @ x[idx] - mu}]
    res = minimize(kl, q0, method="SLSQP", bounds=[(1e-12, 1.0)] * len(idx), constraints=cons,
                   options={"ftol": 1e-14, "maxiter": 500})
    # A stop on "positive directional derivative" is a line search that cannot improve: accepted when feasible (a
    # feasible point's KL is at least the minimum, so an early stop can fail a comparison, never pass a wrong one).
    assert res.success or (abs(res.x.sum() - 1) < 1e-8 and res.x @ x[idx] >= mu - 1e-8), res.message
    return float(res.fun)


def burnetas_katehakis(T: np.ndarray, R: np.ndarray, support: str, gap_tol: float = 1e-7) -> tuple[float, float]:
    """``(C_kl, C_reciprocal)``: ``sum Delta* / K`` over the critical pairs and ``sum 1 / Delta*`` over the pairs with
    a gap, from the first optimality-equation solution of the enumeration."""
    S, A, _ = T.shape
    g, h = optimality_solutions(T, R)[0]
    delta = g + h[:, None] - R - T @ h
    c_kl = c_rec = 0.0
    for s in range(S):
        for a in range(A):
            if delta[s, a] <= gap_tol:
                continue
            c_rec += 1.0 / delta[s, a]
            p = T[s, a]
            allowed = p > 0 if support == "transition" else np.ones(S, bool)
            K = kl_projection(p, h, g + h[s] - R[s, a], allowed)
            if np.isfinite(K):
                c_kl += delta[s, a] / K
    return c_kl, c_rec


def mdp(T: np.ndarray, R: np.ndarray) -> jaxmdp.MDP:
    return jaxmdp.custom_mdp(T, R)
