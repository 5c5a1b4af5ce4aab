"""Run independent tasks in this process, on this machine's cores or on a Dask cluster, with the same results.

One call, :func:`run_tasks`, maps a module-level function over a list of plain inputs and returns the
results in input order:

* ``scheduler="inprocess"``: a plain loop in this process (debugging, tests, ``--jobs 1``);
* ``scheduler="local"`` (the commands' default): a :class:`distributed.LocalCluster` of ``n_workers``
  worker *processes* (one thread each, default: one per core) on 127.0.0.1, started and stopped by the call;
* ``scheduler="tcp://HOST:PORT"``: an existing Dask cluster (``dask scheduler`` plus ``dask worker`` on any
  machines that have the same akc-drake version installed; the call checks that version on every worker).

The contract that keeps it safe to leave the machine:

* ``fn`` is a module-level function of the package (pickled by reference: the workers import it), called as
  ``fn(item)`` with ``item`` made of plain values (str, numbers, lists, dicts, numpy arrays);
* it returns plain values too (dicts, lists, str, numbers, None, numpy arrays of numbers or text). Anything
  else (an object of our package, a numpy object array) fails the task with a clear message instead of
  crossing the wire: the results never depend on unpickling our classes on the client.

Faults:

* an exception in ``fn`` (a bad clip, a missing file) fails only its own task: the call returns a
  :class:`TaskFailure` in its slot, with a one-line message, and the other tasks complete. Such a failure is
  deterministic, so it is not retried.
* a worker that dies mid-task (killed, out of memory, a crash in native code): the scheduler reschedules its
  tasks on the other workers (up to ``distributed.scheduler.allowed-failures`` times, 3 by default; a
  ``LocalCluster``'s nanny also restarts the worker). When the scheduler gives up on a task
  (``KilledWorker``) or loses it, :func:`run_tasks` submits it again, up to ``retries`` more times, before
  reporting it as a :class:`TaskFailure`.

A progress bar (tqdm, on stderr) counts finished tasks. To run several batches on the same workers (a local
cluster started once, workers that keep their imports), open the scheduler once::

    with open_scheduler("local", n_workers=2) as sched:
        first = run_tasks(fn, items, scheduler=sched)
        second = run_tasks(other_fn, more_items, scheduler=sched)
"""

from __future__ import annotations

import logging
import os
import sys
import time
import traceback
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from akc_drake.errors import UserError

#: The scheduler names :func:`run_tasks` accepts besides a ``tcp://HOST:PORT`` address.
SCHEDULERS = ("local", "inprocess")

#: Seconds to wait for a cluster's scheduler to answer, and for its first worker.
CONNECT_TIMEOUT_S = 15.0


@dataclass(frozen=True)
class TaskFailure:
    """A task that did not produce a result.

    Attributes:
        index: the task's position in ``items``.
        label: its name (from ``labels``, else ``"task <index>"``).
        error: one line: the exception type and message (or what happened to the worker).
        traceback: the full traceback text when there is one ("" otherwise), for a log file.
        attempts: how many times the task was submitted.
    """

    index: int
    label: str
    error: str
    traceback: str = ""
    attempts: int = 1

    def line(self) -> str:
        """``"<label>: <error>"``, the line a report prints."""
        return f"{self.label}: {self.error}"

    def as_dict(self) -> dict:
        return {"index": self.index, "label": self.label, "error": self.error, "attempts": self.attempts}


def failures(results: Sequence[Any]) -> list[TaskFailure]:
    """The :class:`TaskFailure` entries of a :func:`run_tasks` result, in order."""
    return [r for r in results if isinstance(r, TaskFailure)]


def check_scheduler(scheduler: str) -> str:
    """Validate a ``--scheduler`` value: "local", "inprocess" or "tcp://HOST:PORT".

    Raises:
        UserError: naming the value and what is accepted.
    """
    s = str(scheduler).strip()
    if s in SCHEDULERS:
        return s
    if s.startswith("tcp://"):
        hostport = s.split("://", 1)[1]
        host, _, port = hostport.rpartition(":")
        if host and port.isdigit() and 0 < int(port) < 65536:
            return s
    raise UserError(f"--scheduler {scheduler!r}: expected local, inprocess or tcp://HOST:PORT")


# ============================================================================================ worker side
def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split())
    name = type(exc).__name__
    return f"{name}: {msg}" if msg else name


def _plain_problem(value, where: str = "result", depth: int = 0) -> str | None:
    """Why ``value`` is not plain data (None when it is)."""
    if depth > 20:
        return f"{where} is nested too deeply"
    if value is None or isinstance(value, (bool, int, float, str, bytes, np.number, np.bool_)):
        return None
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            return f"{where} is a numpy array of Python objects"
        return None
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, (str, int)):
                return f"{where} has a key of type {type(k).__name__}"
            p = _plain_problem(v, f"{where}[{k!r}]", depth + 1)
            if p:
                return p
        return None
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            p = _plain_problem(v, f"{where}[{i}]", depth + 1)
            if p:
                return p
        return None
    return f"{where} is a {type(value).__module__}.{type(value).__name__}, not plain data"


def _run_one(fn: Callable, item) -> dict:
    """Call ``fn(item)`` on a worker; an exception becomes a plain error record (not a Dask error, no retry)."""
    try:
        value = fn(item)
    except Exception as e:  # noqa: BLE001 - every failure of a task is reported, none stops the others
        return {"ok": False, "error": _one_line(e), "traceback": traceback.format_exc()}
    problem = _plain_problem(value)
    if problem:
        return {"ok": False, "error": f"TypeError: {problem}", "traceback": ""}
    return {"ok": True, "value": value}


def _worker_info() -> dict:
    """What a worker runs (checked by the client against its own)."""
    import akc_drake

    return {"akc_drake": akc_drake.__version__, "python": ".".join(map(str, sys.version_info[:2]))}


# ============================================================================================ client side
def run_tasks(
    fn: Callable,
    items: Sequence,
    *,
    scheduler: str = "local",
    n_workers: int | None = None,
    desc: str = "tasks",
    labels: Sequence[str] | None = None,
    retries: int = 2,
    progress: bool = True,
    timeout_s: float | None = None,
    on_result: Callable[[int, Any], None] | None = None,
) -> list:
    """``[fn(item) for item in items]`` on the chosen scheduler; a failed task gives a :class:`TaskFailure`.

    Args:
        fn: a module-level function (importable by the workers) taking one plain argument and returning
            plain data (see the module docstring).
        items: the tasks' inputs (plain data).
        scheduler: "inprocess", "local" or "tcp://HOST:PORT" (see the module docstring), or an open
            :class:`Scheduler` (from :func:`open_scheduler`) to run several calls on the same workers.
        n_workers: worker processes of the local cluster (default: ``os.cpu_count()``, at most one per
            task); ignored otherwise.
        desc: the progress bar's label.
        labels: a name per task for the progress bar and failure lines (default ``"task <i>"``).
        retries: resubmissions of a task whose workers died (after the scheduler's own rescheduling).
        progress: show the progress bar (stderr).
        timeout_s: give up waiting after this long (None: wait as long as the tasks take); unfinished tasks
            become :class:`TaskFailure` entries.
        on_result: called ``on_result(index, result_or_failure)`` in this process as each task finishes.

    Returns:
        One entry per item, in order: ``fn(item)``'s value, or a :class:`TaskFailure`.

    Raises:
        UserError: a bad scheduler value, a cluster that cannot be reached or has no workers, or workers
            with another akc-drake version.
    """
    items = list(items)
    if labels is None:
        labels = [f"task {i}" for i in range(len(items))]
    labels = [str(x) for x in labels]
    if len(labels) != len(items):
        raise ValueError(f"labels has {len(labels)} entries for {len(items)} items")
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise ValueError(f"retries must be an integer >= 0, got {retries!r}")
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1):
        raise ValueError(f"n_workers must be a positive integer, got {n_workers!r}")
    if not isinstance(scheduler, Scheduler):
        scheduler = check_scheduler(scheduler)
    if not items:
        return []
    if not isinstance(scheduler, Scheduler):
        n = n_workers
        if scheduler == "local":
            n = max(1, min(n or os.cpu_count() or 1, len(items)))
        with open_scheduler(scheduler, n) as sched:
            return run_tasks(
                fn,
                items,
                scheduler=sched,
                desc=desc,
                labels=labels,
                retries=retries,
                progress=progress,
                timeout_s=timeout_s,
                on_result=on_result,
            )
    if scheduler.client is None and scheduler.name != "inprocess":
        raise ValueError(f"the {scheduler.name} scheduler is not open: use it in a 'with open_scheduler(...)' block")
    from tqdm import tqdm

    bar = tqdm(total=len(items), desc=desc, unit="task", file=sys.stderr, disable=not progress, dynamic_ncols=True)
    with bar:
        if scheduler.client is None:
            return _run_inprocess(fn, items, labels, bar, on_result)
        return _run_dask(fn, items, labels, scheduler.client, retries, bar, timeout_s, on_result)


class Scheduler:
    """Where tasks run, kept open across several :func:`run_tasks` calls (a context manager).

    Attributes:
        name: "inprocess", "local" or the cluster's address.
        client: the ``distributed.Client`` (None in-process).
        cluster: the ``LocalCluster`` this object started (None otherwise).
    """

    def __init__(self, scheduler: str = "local", n_workers: int | None = None):
        self.name = check_scheduler(scheduler)
        if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1):
            raise ValueError(f"n_workers must be a positive integer, got {n_workers!r}")
        self.n_workers = n_workers
        self.client = None
        self.cluster = None

    def __enter__(self) -> Scheduler:
        if self.name == "local":
            from distributed import Client

            self.cluster = _start_local(self.n_workers or os.cpu_count() or 1)
            self.client = Client(self.cluster, set_as_default=False)
        elif self.name != "inprocess":
            self.client = _connect(self.name)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def workers(self) -> int:
        """How many workers are connected (1 in-process)."""
        if self.client is None:
            return 1
        return len(self.client.scheduler_info(n_workers=-1).get("workers", {})) or 1


def open_scheduler(scheduler: str = "local", n_workers: int | None = None) -> Scheduler:
    """A :class:`Scheduler` to use in a ``with`` block: ``with open_scheduler("local", 2) as s: run_tasks(...,
    scheduler=s)``; a local cluster is started on entry and stopped on exit.

    Raises:
        UserError: a bad scheduler value, or a cluster that cannot be reached (on entry).
    """
    return Scheduler(scheduler, n_workers)


def _finish(index: int, record: dict, labels, attempts: int):
    if record.get("ok"):
        return record["value"]
    return TaskFailure(index, labels[index], record["error"], record.get("traceback", ""), attempts)


def _run_inprocess(fn, items, labels, bar, on_result) -> list:
    out = []
    n_failed = 0
    for i, item in enumerate(items):
        bar.set_postfix_str(labels[i], refresh=False)
        res = _finish(i, _run_one(fn, item), labels, 1)
        n_failed += isinstance(res, TaskFailure)
        out.append(res)
        if on_result is not None:
            on_result(i, res)
        bar.update(1)
    if n_failed:
        bar.set_postfix_str(f"{n_failed} failed", refresh=True)
    return out


def _start_local(n_workers: int):
    """A LocalCluster of single-threaded worker processes on 127.0.0.1, no dashboard, quiet logs."""
    from distributed import LocalCluster

    return LocalCluster(
        n_workers=n_workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        # No dashboard; the scheduler's own HTTP endpoints on a free port, not 8787 (another cluster may hold it).
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        silence_logs=logging.ERROR,
    )


def _connect(address: str):
    """A Client on an existing cluster, with its workers checked (present, same akc-drake version)."""
    from distributed import Client

    try:
        client = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s", set_as_default=False)
    except (OSError, TimeoutError) as e:
        raise UserError(f"--scheduler {address}: cannot connect ({_one_line(e)})") from None
    try:
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except TimeoutError:
            raise UserError(
                f"--scheduler {address}: no worker joined within {CONNECT_TIMEOUT_S:g} s "
                "(start one with: dask worker " + address + ")"
            ) from None
        _check_workers(client, address)
    except BaseException:
        client.close()
        raise
    return client


def _check_workers(client, address: str) -> None:
    import akc_drake

    try:
        infos = client.run(_worker_info)
    except Exception as e:  # noqa: BLE001 - a worker without the package fails here
        raise UserError(
            f"--scheduler {address}: a worker cannot run akc-drake ({_one_line(e)}); install akc-drake "
            f"{akc_drake.__version__} on every worker"
        ) from None
    for worker, info in sorted(infos.items()):
        if info.get("akc_drake") != akc_drake.__version__:
            raise UserError(
                f"--scheduler {address}: worker {worker} runs akc-drake {info.get('akc_drake')}, "
                f"this machine {akc_drake.__version__}; install the same version everywhere"
            )


def _run_dask(fn, items, labels, client, retries, bar, timeout_s, on_result) -> list:
    from distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    results: list = [None] * len(items)
    attempts = [0] * len(items)
    done = [False] * len(items)
    n_failed = 0
    live: dict = {}
    try:

        def submit(i):
            attempts[i] += 1
            f = client.submit(_run_one, fn, items[i], key=f"{_slug(labels[i])}-{i}-{attempts[i]}-{tag}", pure=False)
            live[f.key] = f
            return f

        index_of = {}
        futures = []
        for i in range(len(items)):
            f = submit(i)
            index_of[f.key] = i
            futures.append(f)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        pending = as_completed(futures, loop=client.loop, raise_errors=False, timeout=timeout_s)
        try:
            for fut in pending:
                i = index_of[fut.key]
                if fut.status == "finished":
                    res = _finish(i, fut.result(), labels, attempts[i])
                else:
                    exc = _future_error(fut)
                    if attempts[i] <= retries:
                        f2 = submit(i)
                        index_of[f2.key] = i
                        pending.add(f2)
                        live.pop(fut.key, None)
                        fut.release()
                        continue
                    res = TaskFailure(i, labels[i], exc, "", attempts[i])
                live.pop(fut.key, None)
                fut.release()
                results[i], done[i] = res, True
                n_failed += isinstance(res, TaskFailure)
                if on_result is not None:
                    on_result(i, res)
                bar.set_postfix_str(labels[i] + (f", {n_failed} failed" if n_failed else ""), refresh=False)
                bar.update(1)
                if deadline is not None and time.monotonic() > deadline:
                    break
        except TimeoutError:
            pass
        for i in range(len(items)):
            if not done[i]:
                msg = f"TimeoutError: not finished after {timeout_s:g} s"
                results[i] = TaskFailure(i, labels[i], msg, "", attempts[i])
                n_failed += 1
        if n_failed:
            bar.set_postfix_str(f"{n_failed} failed", refresh=True)
        return results
    finally:
        if live:  # timed out or interrupted: nothing keeps running on the cluster for us
            client.cancel(list(live.values()))


def _future_error(fut) -> str:
    """One line saying why a Dask future did not finish (a killed worker, a lost scheduler...)."""
    if fut.status == "cancelled":
        return "CancelledError: the cluster lost the task"
    try:
        exc = fut.exception(timeout=5)
    except Exception as e:  # noqa: BLE001
        return _one_line(e)
    return _one_line(exc) if exc is not None else f"task ended with status {fut.status}"


def _slug(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in label)[:60] or "task"
