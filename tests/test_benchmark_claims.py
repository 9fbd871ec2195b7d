"""Claims on a shared benchmark folder, merged plans and shards (no JAX program runs here; the runs of several
processes on one folder and of shards are in tests/test_benchmark_run.py)."""

import json
import subprocess
import sys
import time

import pytest

from hardness.benchmark import claims, plans, shards
from hardness.benchmark.plans import Batch


class Clock:
    """A monotonic clock the test moves."""

    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _elsewhere(c: claims.Claims) -> claims.Claims:
    """``c`` posing as a process of another machine."""
    c.host, c.machine = "elsewhere", "elsewhere/boot/pid:[1]"
    return c


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _events(out, batch_id):
    return [line.split()[1] for line in (out / "runs" / f"{batch_id}.log").read_text().splitlines()]


def test_a_claim_is_exclusive_logged_and_dropped(tmp_path):
    with claims.Claims(tmp_path) as a, _elsewhere(claims.Claims(tmp_path)) as b:
        assert a.take("x") and a.take("x")  # taking again what it holds
        assert not b.take("x")
        held = json.loads((tmp_path / "runs" / "x.claim").read_text())
        assert (held["host"], held["pid"], held["beat"]) == (a.host, a.pid, 0) and held["machine"] == claims.machine()
        assert b.take("y") and not a.take("y")
        a.drop("x", "finished")
        assert not (tmp_path / "runs" / "x.claim").exists()
        assert b.take("x")
    # leaving the context drops what is still held
    assert not list((tmp_path / "runs").glob("*.claim"))
    assert _events(tmp_path, "x") == ["claimed", "finished", "claimed", "dropped"]


def test_another_machine_s_claim_is_taken_over_only_after_its_heartbeat_stopped_for_stale_s(tmp_path):
    clock = Clock()
    with _elsewhere(claims.Claims(tmp_path)) as holder, claims.Claims(tmp_path, stale_s=10, heartbeat_s=1,
                                                                      clock=clock) as taker:
        assert holder.take("x")
        for _ in range(5):  # a beating holder keeps its claim however long the taker watches
            assert not taker.take("x")
            clock.t += 9
            holder.beat()
        assert not taker.take("x")  # the beat changed since the last look: the stale time starts again
        clock.t += 9.9
        assert not taker.take("x")
        clock.t += 0.1  # 10 s of the taker's clock without a beat
        assert taker.take("x")
        assert json.loads((tmp_path / "runs" / "x.claim").read_text())["pid"] == taker.pid
        holder.beat()  # the old holder finds its claim gone and does not overwrite the new one
        assert holder.lost == ["x"] and "x" not in holder.held
        assert json.loads((tmp_path / "runs" / "x.claim").read_text())["pid"] == taker.pid
    assert _events(tmp_path, "x") == ["claimed", "took", "dropped"]


def test_a_claim_of_a_process_gone_from_this_machine_is_taken_over_at_once(tmp_path):
    (tmp_path / "runs").mkdir()
    dead = _dead_pid()
    with claims.Claims(tmp_path, clock=Clock()) as c:
        for batch, pid, token in (("a", dead, "t"), ("b", c.pid, "not-ours")):  # b: an earlier process, same pid
            (tmp_path / "runs" / f"{batch}.claim").write_text(json.dumps(dict(
                host=c.host, machine=c.machine, pid=pid, token=token, started="", beat=3)))
            assert c.take(batch)
        # a live process of this machine (this test's parent) keeps its claim until its beat stops for stale_s
        (tmp_path / "runs" / "c.claim").write_text(json.dumps(dict(
            host=c.host, machine=c.machine, pid=claims.os.getppid(), token="t", started="", beat=0)))
        assert not c.take("c")
        (tmp_path / "runs" / "d.claim").write_text("{half a claim")  # unreadable: stale like a silent holder
        assert not c.take("d")
        c.clock.t += claims.STALE_S
        assert c.take("c") and c.take("d")
    assert _events(tmp_path, "a")[0] == "took"


def test_the_heartbeat_thread_beats_while_a_claim_is_held(tmp_path):
    with claims.Claims(tmp_path, heartbeat_s=0.02, stale_s=1) as c:
        assert c.take("x")
        deadline = time.monotonic() + 20
        while json.loads((tmp_path / "runs" / "x.claim").read_text())["beat"] < 3:
            assert time.monotonic() < deadline, "no heartbeat"
            time.sleep(0.01)
    with pytest.raises(ValueError, match="heartbeat_s must be positive and below stale_s"):
        claims.Claims(tmp_path, heartbeat_s=5, stale_s=5)


def _settings(**over):
    s = dict(sets=["A"], agents={"A": ["q", "r"]}, seeds=[0, 1], n_steps=100, log_periods={"A": 10},
             hparams_source="tuned", hparams={"q": {"x": "1"}, "r": {}}, agent_variant="paper", n_buckets=2,
             max_members=None, n_records=100, agent_buckets={}, emission=None, variant="paper", only=None)
    s.update(over)
    return s


def _batches(set_name, agents, buckets=2):
    return [dict(id=f"{set_name}.{a}.b{k}", key=f"{set_name}{a}{k}", set_name=set_name, agent=a,
                 members=[[f"M{k}", 0], [f"M{k}", 1]], whole=None) for a in agents for k in range(buckets)]


def test_plans_merge_agents_and_sets_and_refuse_another_protocol():
    full = {"settings": _settings(), "batches": _batches("A", ["q", "r"])}
    only_r = {"settings": _settings(agents={"A": ["r"]}, hparams={"r": {}}), "batches": _batches("A", ["r"])}
    # a call naming fewer agents keeps the folder's (and its order); a call naming more takes its own order
    assert plans.merge(full, only_r) == full
    assert plans.merge(only_r, full) == full
    r_then_q = plans.merge(only_r, {"settings": _settings(agents={"A": ["q"]}, hparams={"q": {"x": "1"}}),
                                    "batches": _batches("A", ["q"])})
    assert r_then_q["settings"]["agents"] == {"A": ["r", "q"]}
    assert [b["id"] for b in r_then_q["batches"]] == ["A.r.b0", "A.r.b1", "A.q.b0", "A.q.b1"]
    other_set = {"settings": _settings(sets=["B"], agents={"B": ["q"]}, log_periods={"B": 5},
                                       hparams={"q": {"x": "1"}}, agent_buckets={"q": 3}, n_buckets=2),
                 "batches": _batches("B", ["q"], 3)}
    with pytest.raises(ValueError, match=r"size buckets of q: 2 there, 3 here"):
        plans.merge(full, other_set)
    other_set["settings"]["agent_buckets"] = {}
    both = plans.merge(full, other_set)
    assert both["settings"]["sets"] == ["A", "B"] and both["settings"]["log_periods"] == {"A": 10, "B": 5}
    assert [b["id"] for b in both["batches"]] == [b["id"] for b in full["batches"] + _batches("B", ["q"], 3)]
    for change, message in ((dict(n_steps=200), "n_steps: 100 there, 200 here"),
                            (dict(seeds=[0]), r"seeds: \[0, 1\] there, \[0\] here"),
                            (dict(only=["RiverSwim"]), "only: None there"),
                            (dict(log_periods={"A": 20}), "log period of 'A': 10 there, 20 here"),
                            (dict(hparams={"q": {"x": "2"}, "r": {}}), "hyperparameters of q")):
        with pytest.raises(ValueError, match=f"another protocol .*{message}"):
            plans.merge(full, {"settings": _settings(**change), "batches": full["batches"]})


def test_plans_keep_a_split_batch_split_and_prefer_the_finished_version_when_merging_folders():
    full = {"settings": _settings(agents={"A": ["q"]}, hparams={"q": {"x": "1"}}), "batches": _batches("A", ["q"])}
    whole = full["batches"][1]
    parts = [dict(whole, id=f"{whole['id']}.s{j}", key=f"k{j}", members=[whole["members"][j]],
                  whole=whole["members"]) for j in range(2)]
    split = {"settings": full["settings"], "batches": [full["batches"][0], *parts]}
    assert {plans.root(p) for p in parts} == {plans.root(whole)}
    assert plans.merge(split, full) == split  # the folder's version of a root is kept
    assert plans.merge(full, split) == full
    finished = lambda b, k: b["id"] != whole["id"]  # noqa: E731 (only the parts have finished)
    assert plans.merge(full, split, finished=finished) == split


def test_shards_are_a_snake_over_the_plan_s_roots_and_bad_shards_are_refused():
    assert [shards.shard_of(k, 3) for k in range(8)] == [0, 1, 2, 2, 1, 0, 0, 1]
    batches = [plans.to_batch(b) for b in _batches("A", ["q", "r"], 3)]
    # a split batch's parts stay in the shard of the batch they came from, and the positions of the others hold
    parts = [Batch(f"{batches[1].id}.s{j}", f"k{j}", "A", "q", (batches[1].members[j],), batches[1].members)
             for j in range(2)]
    batches[1:2] = parts
    got = [[b.id for b in shards.share(batches, (i, 2))] for i in range(2)]
    # positions 0..5 (q.b0, q.b1, q.b2, r.b0, r.b1, r.b2) to shards 0, 1, 1, 0, 0, 1
    assert got == [["A.q.b0", "A.r.b0", "A.r.b1"], ["A.q.b1.s0", "A.q.b1.s1", "A.q.b2", "A.r.b2"]]
    assert shards.share(batches, (0, 1)) == batches
    for bad in ("3/2", "x", "2/2", "-1/2", "1/", "1/2/3", ""):
        with pytest.raises(ValueError, match=f"--shard must be i/N with integers 0 <= i < N.*got '{bad}'"):
            shards.parse_shard(bad)
    assert shards.parse_shard("1/4") == (1, 4)
    for bad in ((2, 2), (0, 0), ("0", 2), (True, 2), (1,), None):
        with pytest.raises(ValueError, match="shard must be"):
            shards.check_shard(bad)
