"""Property tests: the hardness measures do not change when the states are relabelled or the MDP is padded, on random
MDPs (tests/random_mdps.py; Hypothesis profiles in tests/hypothesis_profiles.py).

``hardness.measures`` (diameter, value norm, sum of reciprocal gaps) of a draw padded to the canonical shape (5
states, 3 actions) is compared with the same draw with its real states permuted (:func:`jaxmdp.permute_states`), and
with the draw padded further (7 states, 4 actions, 7 successors, episodes of static length 5; padding states and
actions and a longer static ``H``, the member keeping its own horizon).

``variant="paper"`` is exact (up to float32 and the diameter's certificate), hence invariant to both. The reference's
procedures (``variant="colosseum"``) are invariant to padding (padding states come last and are skipped, padded
actions copy action 0), but not to relabelling: its value iteration sweeps the states in index order (Gauss-Seidel)
and stops at ``eps = 1e-3``, so a relabelled MDP stops at another iterate, its episodic diameter exits early in the
order of the state indices, and its episodic continuous form sends the reset mass to the row numbered like the start
state (docs/measures.md §3-4). For continuous MDPs the test checks instead that both labellings stay within the
error that the stopping rule allows around the exact values (bounds derived at :func:`_colosseum_bounds`).
"""

from __future__ import annotations

import dataclasses

import hypothesis_profiles
import jax
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import hardness
import jaxmdp
from jaxmdp.episodic import ContinuousForm, continuous_form, stack_continuous_forms
from random_mdps import H_PAD, S_PAD, Draw, discounted_optimal, draws

examples = hypothesis_profiles.examples

#: The further padded shape.
S_BIG, A_BIG, K_BIG, H_BIG = 7, 4, 7, 5
GAMMA = 0.99
#: float32 agreement of two computations of one exact measure (values up to 1 / (1 - gamma) = 100).
RTOL, ATOL = 2e-4, 2e-4


def _padded_form(mdp: jaxmdp.MDP, S: int, H: int) -> ContinuousForm:
    """The reference's continuous form of an episodic ``mdp`` with rows padded to ``S H`` (the padding of
    :func:`jaxmdp.episodic.stack_continuous_forms`), so that one program serves every draw."""
    cf = continuous_form(mdp)
    A, K = cf.succ.shape[1:]
    N = S * H
    empty = ContinuousForm(succ=np.zeros((N, A, K), np.int32), succ_p=np.zeros((N, A, K), np.float32),
                           R=np.zeros((N, A), np.float32), pair_h=np.zeros(N, np.int32),
                           pair_s=np.zeros(N, np.int32), row_mask=np.zeros(N, bool), action_mask=np.ones(A, bool))
    return jax.tree.map(lambda x: x[0], stack_continuous_forms([cf, empty]))


def _measures(mdp: jaxmdp.MDP, variant: str, S: int, H: int) -> dict[str, np.ndarray]:
    cf = _padded_form(mdp, S, H) if variant == "colosseum" and mdp.episodic else None
    out = hardness.measures(mdp, GAMMA, variant=variant, continuous_form=cf)
    return {name: np.asarray([float(r.value), float(r.converged)]) for name, r in
            (("diameter", out.diameter), ("value_norm", out.value_norm),
             ("sum_reciprocal_gaps", out.sum_reciprocal_gaps))}


def _assert_same(a: dict, b: dict, what: str, rtol: float = RTOL, atol: float = ATOL) -> None:
    for name in a:
        (va, ca), (vb, cb) = a[name], b[name]
        assert ca == cb, f"{what}: {name} converged {ca} vs {cb}"
        if np.isinf(va) or np.isinf(vb):
            assert va == vb, f"{what}: {name} {va} vs {vb}"
        else:
            assert abs(va - vb) <= atol + rtol * abs(va), f"{what}: {name} {va} vs {vb}"


def _colosseum_bounds(draw: Draw) -> dict[str, tuple[float, float]]:
    """Intervals that the colosseum value norm and gap sum of a continuous draw lie in, whatever the state order.

    The reference's Gauss-Seidel value iteration from ``V = 0`` with rewards in ``[0, 1]`` increases monotonically to
    ``V*`` and stops after the first sweep ``k`` with ``||V_k - V_{k-1}|| < eps``; the sweep is a ``gamma``-contraction,
    so ``||V_k - V*|| <= gamma eps / (1 - gamma) = err``. The ``Q`` of a state's last backup reads values between
    ``V_{k-1}`` and ``V_k``, so ``|Q - Q*| <= gamma (err + eps)`` and each gap ``max_a Q - Q(s, a)`` is within
    ``d = 2 gamma (err + eps)`` of the exact one. The value norm ``sqrt(sum_t P (V(t) - E[t, a])^2)`` (its centring
    ``E`` a weighted mean of ``V``) moves by at most ``2 err``. A float32 allowance is added to both."""
    T, R, _ = draw.arrays()
    Q, V = discounted_optimal(T, R, GAMMA)
    eps = 1e-3
    err = GAMMA * eps / (1 - GAMMA) + 1e-3
    d = 2 * GAMMA * (err + eps)
    gaps = V[:, None] - Q
    lo = np.sum(1 / (gaps + d + 0.1))
    hi = np.sum(1 / (np.maximum(gaps - d, 0) + 0.1))
    E = T @ V  # E[t, a]: expected next value of state t under action a
    S, A = R.shape
    norm = max(np.sqrt(T[s, a] @ (V - E[:, a]) ** 2) for s in range(S) for a in range(A))
    return {"value_norm": (max(norm - 2 * err, 0.0), norm + 2 * err), "sum_reciprocal_gaps": (lo, hi)}


def _check_colosseum_permuted(draw: Draw, base: dict, permuted: dict, paper_diameter: float) -> None:
    bounds = _colosseum_bounds(draw)
    deterministic = all(sum(w > 0 for w in row) == 1 for rows in draw.weights for row in rows)
    for what, m in (("base", base), ("permuted", permuted)):
        for name, (lo, hi) in bounds.items():
            v = m[name][0]
            if name == "value_norm" and deterministic:
                assert v == 0.0, f"{what}: value norm {v} of a deterministic MDP"
                continue
            assert lo - 1e-3 <= v <= hi + 1e-3, f"{what}: {name} {v} outside [{lo}, {hi}]"
        # Hitting times by value iteration from 0 grow towards the exact ones: never above the exact diameter.
        assert np.isinf(m["diameter"][0]) == np.isinf(paper_diameter), what
        if np.isfinite(paper_diameter):
            assert m["diameter"][0] <= paper_diameter * (1 + 1e-5) + 1e-4, f"{what}: {m['diameter'][0]}"


def _reset_quirk_refused(mdp: jaxmdp.MDP) -> bool:
    """Whether the reference's continuous form refuses this labelling: its reset quirk sends the reset mass to the row
    numbered like the start state, and there are fewer reachable pairs than that number (a ``ValueError`` of
    :func:`jaxmdp.episodic.continuous_form`)."""
    try:
        continuous_form(mdp)
    except ValueError as err:
        assert "reset_quirk" in str(err), err
        return True
    return False


@pytest.mark.parametrize("variant", ["paper", "colosseum"])
@pytest.mark.parametrize("episodic", [False, True], ids=["continuous", "episodic"])
# Found by the property (shrunk; the first version of this test computed the colosseum measures of relabelled episodic
# MDPs): relabelled, the only start state is state 1 and, with horizon 1, there is one reachable pair, so the
# reference's continuous form refuses the MDP (its reset quirk, jaxmdp.episodic.continuous_form).
@example(draw=Draw(weights=[[[1, 0]], [[1, 0]]], rewards=[[[0, 0]], [[0, 0]]], denom=4, p0=[1, 0], horizon=1),
         order=[1, 0, 2, 3, 4])
@given(draw=draws(episodic=True), order=st.permutations(range(S_PAD)))
@settings(max_examples=examples(10))
def test_measures_invariant_to_relabelling_and_padding(episodic: bool, variant: str, draw: Draw, order: list[int]):
    """(An episodic draw serves the continuous setting without its horizon; ``order`` permutes the real states in
    their relative order and keeps the padding states in place.)"""
    if not episodic:
        draw = dataclasses.replace(draw, horizon=None)
    perm = [p for p in order if p < draw.n_states] + list(range(draw.n_states, S_PAD))
    mdp = draw.padded()
    big_mdp = draw.padded(S_BIG, A_BIG, K_BIG, H_BIG)
    if variant == "colosseum" and episodic and _reset_quirk_refused(mdp):
        assert _reset_quirk_refused(big_mdp)  # padding changes neither the start indices nor the reachable pairs
        return
    base = _measures(mdp, variant, S_PAD, H_PAD)
    _assert_same(base, _measures(big_mdp, variant, S_BIG, H_BIG), "padded further")
    if variant == "paper":
        _assert_same(base, _measures(jaxmdp.permute_states(mdp, perm), variant, S_PAD, H_PAD),
                     f"states permuted by {perm}")
    elif not episodic:
        permuted = _measures(jaxmdp.permute_states(mdp, perm), variant, S_PAD, H_PAD)
        _check_colosseum_permuted(draw, base, permuted, _measures(mdp, "paper", S_PAD, H_PAD)["diameter"][0])
