"""scripts/bench_psrl_draw_floor.py: the Gamma variates that exact episodic PSRL draws in the full benchmark."""

import numpy as np

from hardness.benchmark import run, sets
from script_loader import load_script

floor = load_script("bench_psrl_draw_floor")


def test_draw_counts_are_episodes_times_padded_rows():
    """Unpadded: sum over MDPs and seeds of ``n_steps / H x S^2 A`` with the reference's cached ``S`` and ``H`` (the
    suite's data, not the built MDPs); padded: each batch's largest ``S`` and ``A``, never less; 8 buckets pad less
    than 4 and as much as 1 bucket pads most."""
    n_steps, seeds = 1000, len(floor.FULL["seeds"])
    counts = {n: floor.draw_counts(n_steps=n_steps, n_buckets=n) for n in (1, 4, 8)}
    own = 0.0
    for set_name in floor.SETTINGS:
        for inst in sets.instances(set_name):
            A = floor.seed0_mdps(set_name)[inst.label].n_actions
            own += seeds * n_steps / inst.entry.H * inst.entry.n_states**2 * A
    padded = {}
    for n, rows in counts.items():
        assert len({r["batch"] for r in rows}) == len(rows) == n * len(floor.SETTINGS)
        assert sum(r["members"] for r in rows) == 40 * seeds
        np.testing.assert_allclose(sum(r["gammas_own"] for r in rows), own, rtol=1e-12)
        assert all(r["gammas_padded"] >= r["gammas_own"] * (1 - 1e-12) for r in rows)
        padded[n] = sum(r["gammas_padded"] for r in rows)
    assert padded[1] > padded[4] > padded[8] > own
    # One bucket per setting: every member padded to the setting's largest S and A.
    for set_name in floor.SETTINGS:
        row = next(r for r in counts[1] if r["batch"].startswith(run._slug(set_name)))
        mdps = list(floor.seed0_mdps(set_name).values())
        S, A = max(m.n_states for m in mdps), max(m.n_actions for m in mdps)
        episodes = sum(seeds * n_steps / m.H for m in mdps)
        np.testing.assert_allclose(row["gammas_padded"], episodes * S * S * A, rtol=1e-12)


def test_padding_factor_is_one_unbucketed_and_the_single_buckets_by_hand():
    for set_name in ("episodic communicating", "continuous ergodic"):
        mdps = list(floor.seed0_mdps(set_name).values())
        np.testing.assert_allclose(floor.padding_factor(set_name, len(mdps)), 1.0, rtol=1e-12)
        S, A = max(m.n_states for m in mdps), max(m.n_actions for m in mdps)
        H = [m.H if m.episodic else 1 for m in mdps]
        want = sum(S * S * A / h for h in H) / sum(m.n_states**2 * m.n_actions / h for m, h in zip(mdps, H))
        np.testing.assert_allclose(floor.padding_factor(set_name, 1), want, rtol=1e-12)
        assert floor.padding_factor(set_name, 1) > floor.padding_factor(set_name, 4) > floor.padding_factor(set_name, 8)
