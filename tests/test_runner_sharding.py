"""A planning agent's members split over several host devices (shard_map): each shard plans its members exactly
when they ask (every member's plan count is its own period's), and the records equal one device's; members that the
devices do not divide are padded with copies whose results are dropped, and a padded run's checkpoint holds the real
members only.

That a Q-learning member's records are the same alone and in a batch on two devices is
tests/test_properties_runner.py's property (on random MDPs). The device count of the CPU backend is fixed when JAX
starts, so the check runs in a subprocess started with ``XLA_FLAGS=--xla_force_host_platform_device_count=2``.
"""

from __future__ import annotations

import textwrap

from jaxmdp.experiment import runner

from progress_run import run_on_host_devices

SCRIPT = textwrap.dedent(
    """
    import json
    import jax, numpy as np
    import jaxmdp
    from jaxmdp.experiment import runner
    from test_runner import SCRIPTED, ScriptedHParams

    assert jax.local_device_count() == 2
    out = {}
    # Members 0-1 and 2-3 plan at different periods, on different shards (the default: every device that divides
    # the batch).
    hps = [ScriptedHParams(plan_every=5), ScriptedHParams(plan_every=7)]
    g = runner.product([jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, randomize_actions=False)], hps,
                       seeds=[0, 1])
    res = runner.run(SCRIPTED[True], g, 400, n_records=4)
    one = runner.run(SCRIPTED[True], g, 400, n_records=4, shards=1)
    out["values_equal"] = bool(np.array_equal(one.values, res.values))
    out["plans"] = res.agent_state.plans.tolist()
    print(json.dumps(out))
    """
)


def test_two_shards_equal_one():
    out = run_on_host_devices(SCRIPT, 2)
    assert out["values_equal"], out
    assert out["plans"] == [1 + 399 // 5, 1 + 399 // 5, 1 + 399 // 7, 1 + 399 // 7]


PADDED = textwrap.dedent(
    """
    import json, pathlib, tempfile, warnings
    import agents
    import jax, numpy as np
    import jaxmdp
    from jaxmdp.experiment import runner
    from test_runner import SCRIPTED, ScriptedHParams

    assert jax.local_device_count() == 2
    out = {}
    # 3 members on two devices: padded to 4 (a copy of member 2), 2 per device, the copy's results dropped.
    hps = [ScriptedHParams(plan_every=5), ScriptedHParams(plan_every=7)]
    mdp = jaxmdp.make("RiverSwim", episodic=True, seed=0, size=5, randomize_actions=False)
    g = runner.product([mdp], hps, seeds=[0, 1, 2])
    g = g.take([1, 2, 3])
    out["shards"] = runner._n_shards(3, None)
    tmp = pathlib.Path(tempfile.mkdtemp())
    two = runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, csv_path=tmp / "two.csv")
    one = runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, shards=1, csv_path=tmp / "one.csv")
    out["values_equal"] = bool(np.array_equal(one.values, two.values)) and two.values.shape[1] == 3
    out["states_equal"] = all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(one.agent_state),
                                                                    jax.tree.leaves(two.agent_state)))
    out["constants_equal"] = all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(one.constants),
                                                                       jax.tree.leaves(two.constants)))
    out["csv_equal"] = [r.split(",")[:-1] for r in (tmp / "one.csv").read_text().splitlines()] == [
        r.split(",")[:-1] for r in (tmp / "two.csv").read_text().splitlines()]  # all but the speed column
    out["plans"] = two.agent_state.plans.tolist()
    out["expected_plans"] = [1 + 399 // int(p) for p in np.asarray(g.hparams.plan_every)]
    # A checkpoint made on two devices (padded) holds the 3 members and resumes on one device.
    ckpt = tmp / "run.ckpt.npz"
    runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, chunk_steps=100, checkpoint_path=ckpt,
               stop_after_chunks=2)
    with np.load(ckpt) as z:
        out["checkpoint_members"] = sorted({z[k].shape[0] for k in z.files if k.startswith("leaf") and z[k].ndim})
    rest = runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, chunk_steps=100, checkpoint_path=ckpt,
                      shards=1)
    out["resumed_equal"] = bool(np.array_equal(one.values, rest.values))
    # And the reverse: a checkpoint of one device resumed on two, its members padded at load.
    ckpt = tmp / "one.ckpt.npz"
    runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, chunk_steps=100, checkpoint_path=ckpt,
               stop_after_chunks=2, shards=1)
    rest = runner.run(SCRIPTED[True], g, 400, n_records=4, log_period=20, chunk_steps=100, checkpoint_path=ckpt)
    out["resumed_padded_equal"] = bool(np.array_equal(one.values, rest.values))
    # The end-of-run warnings count the real members, not the copies (UCRL2 with one sweep per plan never converges).
    ucrl2 = agents.AGENTS["ucrl2"]
    capped = runner.product([jaxmdp.make("RiverSwim", episodic=False, seed=0, size=4)],
                            [ucrl2.default_hparams.replace(evi_max_iter=1)], seeds=[0, 1, 2])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        runner.run(ucrl2, capped, 200, log_period=50, n_records=2)
    out["warnings"] = [str(w.message) for w in caught if "plans_unconverged" in str(w.message)]
    print(json.dumps(out))
    """
)


def test_members_that_the_devices_do_not_divide_are_padded_and_their_copies_dropped():
    out = run_on_host_devices(PADDED, 2)
    assert out["shards"] == 2, out
    assert out["values_equal"] and out["states_equal"] and out["constants_equal"] and out["csv_equal"], out
    assert out["plans"] == out["expected_plans"] and len(set(out["plans"])) == 2, out
    assert out["checkpoint_members"] == [3] and out["resumed_equal"] and out["resumed_padded_equal"], out
    assert len(out["warnings"]) == 1 and "(3 of 3 members)" in out["warnings"][0], out


def test_the_default_shards_put_the_fewest_members_on_a_device_then_pad_the_fewest(monkeypatch):
    monkeypatch.setattr(runner.jax, "local_device_count", lambda: 8)
    shards = {n: runner._n_shards(n, None) for n in (1, 2, 3, 5, 7, 9, 16, 20, 23)}
    # members per device ceil(n / d) first, then padded members d * ceil(n / d)
    assert shards == {1: 1, 2: 2, 3: 3, 5: 5, 7: 7, 9: 5, 16: 8, 20: 7, 23: 8}
    assert runner._n_shards(6, 3) == 3
