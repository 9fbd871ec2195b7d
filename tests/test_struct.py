"""jaxmdp.struct: frozen pytree dataclasses with static fields, the rules of flax.struct without flax (the core
install does not bring flax; the deep agents' extra does)."""

from __future__ import annotations

import dataclasses
import json
import pickle
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import REPO
from jaxmdp import struct


class Counts(struct.PyTreeNode):
    visits: jax.Array
    rewards: jax.Array
    n_states: int = struct.field(pytree_node=False)
    label: str = struct.field(pytree_node=False, default="counts")
    scale: float = 1.0


class Extended(Counts):
    bonus: jax.Array = 0.0
    kind: str = struct.field(pytree_node=False, default="ext")


@struct.dataclass
class Decorated:
    x: jax.Array
    size: int = struct.field(pytree_node=False, default=3)


@struct.dataclass(kw_only=True)
class KeywordOnly:
    x: jax.Array
    size: int = struct.field(pytree_node=False)


def _counts(n_states=2, visits=None, **kw):
    visits = jnp.arange(4.0) if visits is None else visits
    return Counts(visits, jnp.ones(3), n_states, **kw)


def test_data_fields_are_leaves_in_order_and_static_fields_are_in_the_treedef():
    c = _counts(label="a", scale=2.5)
    leaves, treedef = jax.tree.flatten(c)
    assert len(leaves) == 3
    np.testing.assert_array_equal(leaves[0], c.visits)
    np.testing.assert_array_equal(leaves[1], c.rewards)
    assert leaves[2] == 2.5
    assert treedef.node_data() == (Counts, (2, "a"))  # the static values, in field order
    back = jax.tree.unflatten(treedef, leaves)
    assert type(back) is Counts and back.n_states == 2 and back.label == "a" and back.scale == 2.5
    np.testing.assert_array_equal(back.visits, c.visits)
    # Static values are compared (and hashed) with the treedef.
    assert jax.tree.structure(_counts(n_states=3)) != treedef
    assert jax.tree.structure(_counts(label="a")) == treedef
    assert hash(jax.tree.structure(_counts(label="a"))) == hash(treedef)
    # tree maps reach the data fields only.
    doubled = jax.tree.map(lambda x: x * 2, c)
    assert doubled.n_states == 2 and doubled.label == "a" and doubled.scale == 5.0
    np.testing.assert_array_equal(doubled.visits, 2 * c.visits)


def test_replace_frozen_and_defaults():
    c = _counts()
    assert c.label == "counts" and c.scale == 1.0  # defaults, static and data
    d = c.replace(n_states=5, scale=3.0)
    assert (d.n_states, d.scale, c.n_states, c.scale) == (5, 3.0, 2, 1.0)
    assert d.visits is c.visits
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.n_states = 4
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.visits = jnp.zeros(4)
    with pytest.raises(TypeError):
        c.replace(missing=1)
    # Keyword and positional construction, as dataclasses; a keyword-only class refuses positions.
    kw = Counts(visits=c.visits, rewards=c.rewards, n_states=2)
    assert jax.tree.structure(kw) == jax.tree.structure(c)
    assert KeywordOnly(x=1.0, size=2).size == 2
    with pytest.raises(TypeError):
        KeywordOnly(1.0, 2)
    # The decorator: the same rules; a class already made is returned as it is.
    dec = Decorated(jnp.ones(2))
    assert dec.size == 3 and dec.replace(size=4).size == 4
    assert jax.tree.structure(dec).node_data() == (Decorated, (3,))
    with pytest.raises(dataclasses.FrozenInstanceError):
        dec.x = 0
    assert struct.dataclass(Decorated) is Decorated and struct.dataclass(Counts) is Counts


def test_field_metadata():
    f = {f.name: f for f in dataclasses.fields(Counts)}
    assert f["n_states"].metadata["pytree_node"] is False and f["visits"].metadata.get("pytree_node", True) is True
    g = struct.field(pytree_node=False, metadata={"unit": "s"}, default=1)
    assert dict(g.metadata) == {"unit": "s", "pytree_node": False} and g.default == 1


def test_a_subclass_inherits_the_fields_and_adds_its_own():
    e = Extended(jnp.arange(2.0), jnp.ones(2), 4, bonus=jnp.array(0.5))
    assert [f.name for f in dataclasses.fields(Extended)] == [
        "visits", "rewards", "n_states", "label", "scale", "bonus", "kind"]
    leaves, treedef = jax.tree.flatten(e)
    assert len(leaves) == 4 and float(leaves[3]) == 0.5  # visits, rewards, scale, bonus
    assert treedef.node_data() == (Extended, (4, "counts", "ext"))
    assert isinstance(e, Counts) and isinstance(e.replace(kind="x"), Extended)
    with pytest.raises(dataclasses.FrozenInstanceError):
        e.bonus = 1.0


def test_pickle_round_trip():
    for x in (_counts(label="p", scale=0.5), Extended(jnp.arange(2.0), jnp.ones(2), 4), Decorated(jnp.ones(2), 7)):
        y = pickle.loads(pickle.dumps(x))
        assert type(y) is type(x)
        assert jax.tree.structure(y) == jax.tree.structure(x)
        for a, b in zip(jax.tree.leaves(x), jax.tree.leaves(y)):
            np.testing.assert_array_equal(a, b)


def test_jit_retraces_on_a_new_static_value_only():
    traces = []

    @jax.jit
    def f(c):
        traces.append(c.n_states)
        return c.visits.sum() * c.n_states + c.scale

    assert float(f(_counts())) == 13.0
    assert float(f(_counts(visits=jnp.ones(4), scale=2.0))) == 10.0  # new data: the same program
    assert traces == [2]
    assert float(f(_counts(n_states=3))) == 19.0  # a new static value: traced again
    assert traces == [2, 3]
    f(_counts(n_states=2, visits=jnp.zeros(4)))
    assert traces == [2, 3]


def test_the_same_pytree_as_a_flax_struct_twin():
    flax_struct = pytest.importorskip("flax.struct")

    class FlaxCounts(flax_struct.PyTreeNode):
        visits: jax.Array
        rewards: jax.Array
        n_states: int = flax_struct.field(pytree_node=False)
        label: str = flax_struct.field(pytree_node=False, default="counts")
        scale: float = 1.0

    class FlaxExtended(FlaxCounts):
        bonus: jax.Array = 0.0
        kind: str = flax_struct.field(pytree_node=False, default="ext")

    @flax_struct.dataclass(kw_only=True)
    class FlaxKeywordOnly:
        x: jax.Array
        size: int = flax_struct.field(pytree_node=False)

    args = (jnp.arange(3.0), jnp.ones(3), 5)
    for ours, theirs in ((Counts(*args, scale=2.0), FlaxCounts(*args, scale=2.0)),
                         (Extended(*args, bonus=jnp.ones(2)), FlaxExtended(*args, bonus=jnp.ones(2))),
                         (KeywordOnly(x=jnp.ones(2), size=4), FlaxKeywordOnly(x=jnp.ones(2), size=4))):
        ours_paths, ours_def = jax.tree_util.tree_flatten_with_path(ours)
        theirs_paths, theirs_def = jax.tree_util.tree_flatten_with_path(theirs)
        assert [p for p, _ in ours_paths] == [p for p, _ in theirs_paths]
        for (_, a), (_, b) in zip(ours_paths, theirs_paths):
            np.testing.assert_array_equal(a, b)
        assert ours_def.node_data()[1] == theirs_def.node_data()[1]
        assert ([(f.name, f.metadata.get("pytree_node", True), f.default, f.kw_only) for f in dataclasses.fields(ours)]
                == [(f.name, f.metadata.get("pytree_node", True), f.default, f.kw_only)
                    for f in dataclasses.fields(theirs)])
        assert repr(ours).split("(", 1)[1] == repr(theirs).split("(", 1)[1]
        changed = {"n_states": 6} if hasattr(ours, "n_states") else {"size": 6}
        assert (jax.tree.structure(ours.replace(**changed)).node_data()[1]
                == jax.tree.structure(theirs.replace(**changed)).node_data()[1])


def test_the_core_does_not_import_flax():
    """The MDPs, the measures, the tabular agents and the benchmark's entry points import none of the deep agents'
    dependencies, so the core install (which has none of them) runs them."""
    script = textwrap.dedent("""
        import jaxmdp, agents, hardness
        import hardness.measures, hardness.benchmark.run, hardness.benchmark.report, hardness.cli.benchmark
        import hardness.cli.sweep, hardness.analysis
        agents.get("q_learning_episodic"), agents.get("psrl_continuous"), agents.get("ucrl2")
        import json, sys; print(json.dumps(sorted(sys.modules)))
    """)
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True,
                         timeout=300, env={"PYTHONPATH": str(REPO), "JAX_PLATFORMS": "cpu", "PATH": "/usr/bin:/bin"})
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    heavy = ("flax", "optax", "orbax", "tensorstore", "distrax", "flashbax", "tensorflow_probability")
    assert "jaxmdp.struct" in loaded and "agents.ucrl2" in loaded
    assert not {m for m in loaded if m.split(".")[0] in heavy}
