"""The evaluation as tasks (akc_drake.evaluation.tasks): bit-identical results in-process, on a LocalCluster of
1 and 2 workers and through a real `dask scheduler` address; a bad clip fails alone."""

from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np
import pytest

from akc_drake.evaluation.experiment import ExperimentConfig, render_sessions
from akc_drake.evaluation.report import nan_to_none
from akc_drake.evaluation.tasks import (
    config_from_plain,
    config_to_plain,
    evaluate_tasks,
    session_from_plain,
    session_to_plain,
)

pytest.importorskip("akc_drake.systems.depth_camera_source")

#: Two short clips (Motion I and II, 2 cycles each) at a small image size: fast, and every method runs.
CONFIG = dict(motions=("I", "II"), cycles=2, width=160, height=120, calibration_frames=20, seed=3)


def digest(ev) -> dict:
    """Every number of an evaluation except wall-clock measurements, as exact bytes / JSON text."""
    h = hashlib.sha256()
    for name, run in sorted(ev.runs.items()):
        h.update(name.encode())
        s = run.session
        for k in ("t", "raw", "visibility", "pixels", "truth", "cycle_starts"):
            h.update(np.ascontiguousarray(getattr(s, k)).tobytes())
        for m, r in sorted(run.methods.items()):
            h.update(m.encode() + r.estimates.tobytes())
            if r.status is not None:
                h.update("|".join(r.status.tolist()).encode())
        for d in (run.weight_runs, run.calibration_runs):
            for k, v in sorted(d.items()):
                h.update(k.encode() + v.tobytes())
    tables = {t.key: (t.rows, t.columns, t.ours.tolist()) for t in ev.tables if t.key != "table3"}
    doc = {
        "results": ev.results,
        "ranges": ev.arm_length_range_cm,
        "calibrations": {k: d.as_dict() for k, d in ev.calibrations.items()},
        "tables": tables,
    }
    return {"arrays": h.hexdigest(), "json": json.dumps(nan_to_none(doc), sort_keys=True)}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The in-process task run (renders into a fresh cache) and the classic run_experiment on its sessions."""
    cache = tmp_path_factory.mktemp("render-cache")
    cfg = ExperimentConfig(**CONFIG)
    ev = evaluate_tasks(cfg, scheduler="inprocess", cache=cache, progress=False)
    return cfg, cache, ev


def test_plain_round_trips(reference):
    cfg, _, ev = reference
    assert config_from_plain(json.loads(json.dumps(config_to_plain(cfg)))) == cfg
    named = dataclasses.replace(cfg, motion_file="walk.bvh", joint_names={"left_shoulder": "upper_arm.L"})
    assert config_from_plain(json.loads(json.dumps(config_to_plain(named)))) == named
    s = ev.runs["I"].session
    back = session_from_plain(session_to_plain(s))
    assert back.motion == "I" and back.intrinsics == s.intrinsics
    np.testing.assert_array_equal(back.raw, s.raw)
    np.testing.assert_array_equal(back.cycle_starts, s.cycle_starts)


def test_tasks_equal_the_in_process_experiment(reference):
    """The task path runs the same code: identical to run_experiment on the same (cached) sessions."""
    cfg, cache, ev = reference
    import akc_drake.evaluation.experiment as ex
    from akc_drake.evaluation import cache as cache_mod

    # render_sessions goes through the same cache: nothing renders again.
    calls = []
    real = cache_mod.render_uncached
    try:
        cache_mod.render_uncached = lambda spec, progress=None: calls.append(spec) or real(spec, progress)
        sessions = render_sessions(cfg, cache=cache)
    finally:
        cache_mod.render_uncached = real
    assert calls == []
    classic = ex.run_experiment(cfg, sessions)
    assert digest(classic) == digest(ev)
    assert [r["motion"] for r in ev.results][:1] == ["I"] and len(ev.results) == 2 * len(cfg.methods) * 6


def test_local_cluster_1_and_2_workers_bit_identical(reference):
    cfg, cache, ev = reference
    ref = digest(ev)
    one = evaluate_tasks(cfg, scheduler="local", n_workers=1, cache=cache, progress=False)
    assert digest(one) == ref
    # Two workers, rendering again in the workers (no cache): the renders are identical too.
    two = evaluate_tasks(cfg, scheduler="local", n_workers=2, cache=False, progress=False)
    assert digest(two) == ref
    assert not one.failures and not two.failures


class _Killer:
    def __init__(self):
        import threading

        self.pid = None
        self.event = threading.Event()

    def wait(self, timeout):
        return self.event.wait(timeout)


def kill_worker_running(address: str, key_prefixes: tuple[str, ...]) -> _Killer:
    """A thread that SIGKILLs the first worker seen processing a task whose key starts with a prefix."""
    import os
    import signal
    import threading
    import time

    from distributed import Client

    k = _Killer()

    def run():
        with Client(address, timeout="20s", set_as_default=False) as c:
            pids = c.run(os.getpid)
            end = time.monotonic() + 60
            while time.monotonic() < end:
                for worker, keys in c.processing().items():
                    if any(str(key).startswith(key_prefixes) for key in keys):
                        time.sleep(0.3)  # well inside the task
                        k.pid = pids[worker]
                        os.kill(k.pid, signal.SIGKILL)
                        k.event.set()
                        return
                time.sleep(0.02)

    threading.Thread(target=run, daemon=True).start()
    return k


def test_scheduler_address_bit_identical_and_a_bad_clip_fails_alone(reference, tmp_path):
    from dask_cluster import dask_cluster

    from akc_drake.evaluation.tasks import session_specs

    cfg, cache, ev = reference
    ref = digest(ev)
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"not a session")
    specs = session_specs(cfg)
    clips = {"I": {"spec": specs["I"]}, "broken": {"session_npz": str(bad)}, "II": {"spec": specs["II"]}}
    with dask_cluster(tmp_path / "cluster", 2) as cluster:
        got = evaluate_tasks(cfg, scheduler=cluster.address, cache=cache, progress=False)
        assert digest(got) == ref
        lines = []
        partial = evaluate_tasks(
            cfg, scheduler=cluster.address, cache=cache, progress=False, clips=clips, log=lines.append
        )
        # The sweep's grid chunks through the same address: the same objectives as in this process.
        from akc_drake.evaluation.sweep import SweepGrid, evaluate_points

        s = ev.runs["II"].session
        data = {"II": (s.raw[:30], s.truth[:30])}
        pts = SweepGrid(w1=(0.0, 2.0), w2=(4.0, 14.0), w3=(12.0,), s=(0.8, 1.0)).points()
        local = evaluate_points(pts, data, ev.dims, "inprocess")["II"]
        remote = evaluate_points(pts, data, ev.dims, cluster.address, chunks=3)["II"]
        assert remote.tobytes() == local.tobytes()
        # A worker killed while it runs a clip (rendering without the cache, so the task takes a while):
        # the scheduler reruns the clip on the other worker and the evaluation is the same.
        killed = kill_worker_running(cluster.address, ("I-", "II-"))
        survived = evaluate_tasks(cfg, scheduler=cluster.address, cache=False, progress=False)
        assert killed.wait(60) and killed.pid in {p.pid for p in cluster.workers}
        assert sum(p.poll() is None for p in cluster.workers) == 1
        assert not survived.failures and digest(survived) == ref
    assert list(partial.runs) == ["I", "II"]
    assert [f.label for f in partial.failures] == ["broken"]
    assert len(lines) == 1 and lines[0].startswith(f"clip broken: UserError: {bad}: not a session .npz file (")
    assert digest(partial) == ref
    doc = partial.to_json()
    assert doc["failures"] == [{"clip": "broken", "error": lines[0].split(": ", 1)[1], "attempts": 1}]
