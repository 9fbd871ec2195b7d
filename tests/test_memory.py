"""The memory check before a run: XLA's memory analysis, the limit, and the runner refusing a program too large."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import agents
import jaxmdp
from jaxmdp import runner
from jaxmdp.experiment import memory


def _compiled(n: int, m: int):
    return jax.jit(lambda x: jnp.sin(x @ x.T) @ x).lower(jnp.ones((n, m), jnp.float32)).compile()


def test_program_bytes_counts_arguments_outputs_and_temporaries():
    # x: 200 x 300 float32 (240 000 bytes) in, the 200 x 300 product out, the 200 x 200 Gram matrix in between.
    need = memory.program_bytes(_compiled(200, 300))
    assert 240_000 + 240_000 <= need <= 240_000 + 240_000 + 2 * 160_000
    assert memory.program_bytes(_compiled(400, 300)) > need  # grows with the arguments


def test_check_fits_raises_below_the_need_and_passes_above():
    prog = _compiled(200, 300)
    need = memory.program_bytes(prog)
    assert memory.check_fits([("f", prog)], 1, limit=need) == need
    with pytest.raises(memory.ProgramTooLarge, match=r"the f program needs .* KiB .* available; try less") as err:
        memory.check_fits([("f", prog)], 1, limit=need - 1, remedy="try less")
    assert err.value.needed == need and err.value.available == need - 1
    assert isinstance(err.value, MemoryError)
    # Host devices share one memory: two shards need twice one shard's bytes.
    with pytest.raises(memory.ProgramTooLarge, match="2 host devices together"):
        memory.check_fits([("f", prog)], 2, limit=2 * need - 1)


def test_available_bytes_on_this_host_is_positive_and_below_physical_memory():
    avail = memory.available_bytes()
    assert avail is not None and 0 < avail
    import os

    assert avail <= os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def test_runner_refuses_before_running_and_writes_nothing(tmp_path):
    mdp = jaxmdp.make("RiverSwim", size=5, episodic=False, seed=0)
    agent = agents.get("random_continuous")
    g = runner.product([mdp], [agent.default_hparams], seeds=[0, 1])
    csv_file = tmp_path / "run.csv"
    with pytest.raises(runner.ProgramTooLarge, match="run fewer than its 2 members per call"):
        runner.run(agent, g, 100, log_period=50, csv_path=csv_file, memory_limit=1)
    assert not csv_file.exists()
    with pytest.raises(ValueError, match="memory_limit"):
        runner.run(agent, g, 100, memory_limit=0)
    result = runner.run(agent, g, 100, log_period=50, memory_limit=2**40)  # a generous limit changes nothing
    np.testing.assert_array_equal(result.values, runner.run(agent, g, 100, log_period=50).values)
