"""RiverSwim (river_swim.py): validation of the parameters of the stochastic default rewards (docs/families.md §2.1)."""

import pytest

import jaxmdp

_EXPLICIT = dict(
    optimal_distribution=("beta", (9, 1)),
    sub_optimal_distribution=("beta", (1, 4)),
    other_distribution=("beta", (1, 49)),
)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        # Regression: these raised ZeroDivisionError / "Beta parameters must be positive" without naming the parameter.
        (dict(sub_optimal_mean_reward=0.0), r"^sub_optimal_mean_reward must lie in \(0, 1\)"),
        (dict(sub_optimal_mean_reward=-0.5), r"^sub_optimal_mean_reward must lie in \(0, 1\)"),
        (dict(optimal_mean_reward=1.0), r"^optimal_mean_reward must lie in \(0, 1\)"),
    ],
)
def test_stochastic_defaults_reject_means_outside_the_unit_interval(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4, make_reward_stochastic=True, **kwargs)


def test_explicit_distributions_do_not_depend_on_the_default_means():
    # Regression: with sub_optimal_mean_reward = 0 the unused defaults divided by zero.
    m = jaxmdp.make(
        "RiverSwim", episodic=False, seed=0, size=4, randomize_actions=False, make_reward_stochastic=True,
        sub_optimal_mean_reward=0.0, **_EXPLICIT,
    )  # fmt: skip
    # RIGHT (1) at the right end pays Beta(9, 1) (mean 0.9), LEFT (0) at the left end Beta(1, 4) (mean 0.2).
    assert float(m.R[3, 1]) == pytest.approx(0.9, abs=1e-7)
    assert float(m.R[0, 0]) == pytest.approx(0.2, abs=1e-7)
    assert float(m.R[1, 1]) == pytest.approx(0.02, abs=1e-7)
    assert m.info.param("sub_optimal_distribution") == "Beta(1, 4)"


def test_stochastic_defaults_at_valid_means():
    # Episodic: mu_s = 0.2 / size = 0.05, so sub-optimal Beta(1, 19), other Beta(1, 199); optimal Beta(1, 1/9).
    m = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=4, make_reward_stochastic=True)
    assert m.info.param("sub_optimal_distribution") == "Beta(1, 19)"
    assert m.info.param("other_distribution") == "Beta(1, 199)"
    assert m.info.param("optimal_distribution") == "Beta(1, 0.111111)"
