"""Tests of the task executor (akc_drake.evaluation.executor): in-process, LocalCluster, faults.

The functions the workers run are module-level here; Dask's spawned workers import this module (pytest's
``sys.path`` travels with them).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from akc_drake.errors import UserError
from akc_drake.evaluation.executor import TaskFailure, check_scheduler, failures, open_scheduler, run_tasks


def square_root(x: float) -> dict:
    """A task: fails (ValueError) on a negative input."""
    return {"x": x, "root": math.sqrt(x), "array": np.full(3, math.sqrt(x))}


class _NotPlain:
    pass


def returns_object(x):
    """A task that breaks the contract: returns an object of ours."""
    return _NotPlain()


def test_check_scheduler():
    assert check_scheduler("local") == "local"
    assert check_scheduler("inprocess") == "inprocess"
    assert check_scheduler("tcp://10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    for bad in ("", "tcp://nohost", "tcp://h:0", "http://h:8786", "cluster"):
        with pytest.raises(UserError, match="--scheduler"):
            check_scheduler(bad)


def test_inprocess_results_in_order_and_a_bad_task_fails_alone():
    seen = []
    res = run_tasks(
        square_root,
        [4.0, -1.0, 9.0],
        scheduler="inprocess",
        labels=["a", "bad", "c"],
        progress=False,
        on_result=lambda i, r: seen.append(i),
    )
    assert res[0]["root"] == 2.0 and res[2]["root"] == 3.0
    np.testing.assert_array_equal(res[2]["array"], [3.0, 3.0, 3.0])
    assert isinstance(res[1], TaskFailure)
    assert res[1].line() == "bad: ValueError: math domain error"
    assert "math.sqrt" in res[1].traceback
    assert failures(res) == [res[1]]
    assert seen == [0, 1, 2]
    assert run_tasks(square_root, [], scheduler="inprocess") == []


def test_results_must_be_plain_data():
    (res,) = run_tasks(returns_object, [1], scheduler="inprocess", progress=False)
    assert isinstance(res, TaskFailure)
    assert "_NotPlain, not plain data" in res.error


def test_argument_checks():
    with pytest.raises(ValueError, match="labels"):
        run_tasks(square_root, [1.0], scheduler="inprocess", labels=["a", "b"])
    with pytest.raises(ValueError, match="retries"):
        run_tasks(square_root, [1.0], scheduler="inprocess", retries=-1)
    with pytest.raises(ValueError, match="n_workers"):
        run_tasks(square_root, [1.0], scheduler="local", n_workers=0)
    with pytest.raises(ValueError, match="not open"):
        run_tasks(square_root, [1.0], scheduler=open_scheduler("local", 1))


def test_local_cluster_same_results_and_failure_line():
    items = [4.0, -1.0, 2.0, 9.0]
    ref = run_tasks(square_root, items, scheduler="inprocess", progress=False)
    with open_scheduler("local", 2) as sched:
        assert sched.workers() == 2 and sched.client is not None
        got = run_tasks(square_root, items, scheduler=sched, progress=False, timeout_s=120)
        again = run_tasks(square_root, items[:1], scheduler=sched, progress=False)  # same workers, reused
        assert again[0]["root"] == 2.0
    assert sched.client is None and sched.cluster is None  # stopped on exit
    for a, b in zip(ref, got, strict=True):
        if isinstance(a, TaskFailure):
            assert isinstance(b, TaskFailure) and b.line() == a.line() == "task 1: ValueError: math domain error"
        else:
            assert a["root"] == b["root"] and a["array"].tobytes() == b["array"].tobytes()


def slow_marked(item: dict) -> dict:
    """A task that leaves a marker ``<x>-<pid>`` in ``item["dir"]`` when it starts, then works for a while."""
    import os
    import time
    from pathlib import Path

    Path(item["dir"], f"{item['x']}-{os.getpid()}").touch()
    time.sleep(item["sleep"])
    return {"x": item["x"], "pid": os.getpid(), "y": float(item["x"]) ** 2}


def test_unreachable_scheduler_is_one_line(monkeypatch):
    import socket

    import akc_drake.evaluation.executor as ex

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(ex, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(UserError, match=rf"--scheduler tcp://127.0.0.1:{port}: cannot connect"):
        run_tasks(square_root, [1.0], scheduler=f"tcp://127.0.0.1:{port}", progress=False)


def run_killing_one_worker(cluster, markers: Path, n: int = 6, **kw):
    """``run_tasks(slow_marked, ...)`` on ``cluster`` while a thread SIGKILLs the first live worker that starts a
    task; returns (results, (task index, killed pid), pids of the workers alive before)."""
    import os
    import signal
    import threading
    import time

    markers.mkdir()
    alive = {p.pid for p in cluster.workers if p.poll() is None}
    killed: list[tuple[int, int]] = []

    def killer():
        end = time.monotonic() + 60
        while time.monotonic() < end and not killed:
            for m in sorted(markers.iterdir()):
                x, pid = (int(v) for v in m.name.split("-"))
                if pid in alive:
                    os.kill(pid, signal.SIGKILL)
                    killed.append((x, pid))
                    return
            time.sleep(0.02)

    th = threading.Thread(target=killer, daemon=True)
    th.start()
    items = [{"x": x, "dir": str(markers), "sleep": 0.6} for x in range(n)]
    res = run_tasks(slow_marked, items, scheduler=cluster.address, progress=False, timeout_s=90, **kw)
    th.join(timeout=5)
    assert killed, "no task started on a worker"
    return res, killed[0], alive


def test_scheduler_address_and_a_killed_worker(tmp_path):
    """A real `dask scheduler` + 2 `dask worker` processes: killing the worker running a task mid-way
    reschedules it on the other worker (the scheduler's own retry) and the run completes."""
    from dask_cluster import dask_cluster

    with dask_cluster(tmp_path / "cluster", 2) as cluster:
        res, (x_killed, pid_killed), pids = run_killing_one_worker(cluster, tmp_path / "markers")
        assert not failures(res), [f.line() for f in failures(res)]
        assert [r["y"] for r in res] == [float(x * x) for x in range(6)]
        # The task that was running on the killed worker finished on the other one.
        assert res[x_killed]["pid"] != pid_killed and res[x_killed]["pid"] in pids
        assert (tmp_path / "markers" / f"{x_killed}-{pid_killed}").exists()
        assert sum(p.poll() is None for p in cluster.workers) == 1


def test_retries_resubmit_what_the_scheduler_gives_up(tmp_path):
    """With a scheduler that gives up on a task at its first lost worker (allowed-failures 0): retries=0
    reports that task as one failure line and completes the rest; retries=2 resubmits it and completes all."""
    from dask_cluster import dask_cluster

    env = {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    with dask_cluster(tmp_path / "cluster", 3, extra_env=env) as cluster:
        res, (x_killed, _), _ = run_killing_one_worker(cluster, tmp_path / "m0", retries=0)
        # The task running on the killed worker (and any the scheduler had already queued there) fail, alone.
        bad = failures(res)
        assert x_killed in [f.index for f in bad] and len(bad) <= 2
        for f in bad:
            assert f.attempts == 1 and f.line().startswith(f"task {f.index}: KilledWorker:")
        assert all(r["y"] == float(i * i) for i, r in enumerate(res) if not isinstance(r, TaskFailure))

        res, (x_killed, pid_killed), _ = run_killing_one_worker(cluster, tmp_path / "m2", retries=2)
        assert not failures(res), [f.line() for f in failures(res)]
        assert [r["y"] for r in res] == [float(x * x) for x in range(6)]
        assert res[x_killed]["pid"] != pid_killed
