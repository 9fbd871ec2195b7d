"""The shipped tuned file (``jaxmdp-benchmark tune``, paper App. F): one entry per tunable agent with its provenance,
and the reference's cached values still available as ``hparams="reference"`` and as the search's ``reference``
candidate."""

import numpy as np
import pytest

from agents.search_spaces import SEARCH_SPACES
from hardness.benchmark import hparams

# The reference's cached (gin) values of the tabular agents, copied from its cached_hyperparameters configs.
CACHED = {
    "psrl_episodic": {"prior_mean": 0.41854463543357456, "transition_prior": 0.32345772625210756},
    "q_learning_episodic": {"c_1": 0.9415278732894797, "c_2": 0.013873778519317169, "min_at": 0.07263563483119442},
    "ucrl2": {"alpha_p": 0.9883750006754203, "alpha_r": 0.10294276593728004},
    "psrl_continuous": {"rewards_prior_mean": 0.23589883401606418, "psi_weight": 0.016737988780906453,
                        "omega_weight": 0.1104641036501887, "kappa_weight": 2.694052439968039,
                        "eta_weight": 1.3826913305347895e-07},
    "q_learning_continuous": {"h_weight": 0.942, "span_approx_weight": 0.014, "min_at": 0.073},
}


@pytest.mark.parametrize("name", sorted(SEARCH_SPACES))
def test_reference_source_gives_the_cached_values(name):
    hp = hparams.hparams_for(name, "reference")
    for field, value in CACHED[name].items():
        np.testing.assert_allclose(float(getattr(hp, field)), value, rtol=1e-6)


@pytest.mark.parametrize("name", sorted(SEARCH_SPACES))
def test_shipped_entry_has_provenance_and_the_reference_candidate(name):
    entry = hparams.load_tuned()[name]
    budget = entry["budget"]
    assert budget["reduced"] and budget["include_reference"] and budget["seeds"] == list(range(budget["n_seeds"]))
    assert len(entry["commit"]) == 40 and entry["run_s"] > 0
    if "wall_s" in entry:  # entries written before tune_agents recorded it lack it
        assert entry["wall_s"] >= entry["run_s"] + entry["compile_s"] - 0.2  # each rounded to 0.1 s
    labels = [c["label"] for c in entry["candidates"]]
    assert labels == [f"sample_{i}" for i in range(budget["n_candidates"])] + ["reference"]
    reference = entry["candidates"][-1]["values"]
    assert reference.keys() == CACHED[name].keys()
    np.testing.assert_allclose([reference[k] for k in CACHED[name]], list(CACHED[name].values()), rtol=1e-6)
    objectives = [c["objective"] for c in entry["candidates"]]
    assert entry["objective"] == min(objectives) and entry["candidates"][int(np.argmin(objectives))]["label"] == \
        entry["winner"]
    tuned = hparams.hparams_for(name, "tuned")
    for field, (low, high) in SEARCH_SPACES[name].items():
        assert float(getattr(tuned, field)) == pytest.approx(entry["values"][field], rel=1e-6)
        if entry["winner"] != "reference":  # the cached values may lie outside today's space
            assert low <= entry["values"][field] <= high
