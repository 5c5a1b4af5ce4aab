"""A real Dask cluster for tests: ``dask scheduler`` and ``dask worker`` subprocesses on 127.0.0.1.

The scheduler picks a free port (``--port 0``) and writes its address to a scheduler file in a temporary
folder, so parallel test runs never collide; every process is torn down (terminate, then kill) on exit.
Workers run without a nanny, so killing a worker's process is the worker dying (nothing restarts it).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

TESTS_DIR = Path(__file__).resolve().parent
DASK = Path(sys.executable).with_name("dask")


def _wait(pred, timeout: float, what: str, procs=()):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return
        for p in procs:
            if p.poll() is not None:
                raise RuntimeError(f"{what}: process {p.args[:3]} exited with {p.returncode}")
        time.sleep(0.05)
    raise TimeoutError(f"{what}: not ready after {timeout:g} s")


class Cluster:
    """The running cluster: ``address``, ``workers`` (Popen, one per worker)."""

    def __init__(self, folder: Path, extra_env: dict | None = None):
        self.folder = folder
        self.scheduler_file = folder / "scheduler.json"
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []
        self.address = ""
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(TESTS_DIR), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        env["DASK_DISTRIBUTED__WORKER__DAEMON"] = "False"
        env.update(extra_env or {})
        self.env = env

    def _popen(self, args, log: str) -> subprocess.Popen:
        out = open(self.folder / log, "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(
            [str(DASK), *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=self.env,
            cwd=self.folder,
            start_new_session=True,
        )
        out.close()
        return p

    def start_scheduler(self, timeout: float = 30.0) -> None:
        self.scheduler = self._popen(
            [
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--dashboard-address",
                "127.0.0.1:0",
                "--no-show",
                "--scheduler-file",
                str(self.scheduler_file),
            ],
            "scheduler.log",
        )

        def ready():
            try:
                self.address = json.loads(self.scheduler_file.read_text())["address"]
                return True
            except (OSError, ValueError, KeyError):
                return False

        _wait(ready, timeout, "dask scheduler", [self.scheduler])

    def add_worker(self) -> subprocess.Popen:
        name = f"w{len(self.workers)}"
        p = self._popen(
            [
                "worker",
                self.address,
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
                "--name",
                name,
                "--host",
                "127.0.0.1",
                "--local-directory",
                str(self.folder / name),
            ],
            f"{name}.log",
        )
        self.workers.append(p)
        return p

    def wait_for_workers(self, n: int, timeout: float = 60.0) -> None:
        from distributed import Client

        with Client(self.address, timeout="20s", set_as_default=False) as c:
            c.wait_for_workers(n, timeout=timeout)

    def close(self) -> None:
        for p in [*self.workers, self.scheduler]:
            if p is not None and p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGTERM)
                except ProcessLookupError:
                    pass
        for p in [*self.workers, self.scheduler]:
            if p is None:
                continue
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                p.wait(timeout=10)

    def logs(self) -> str:
        return "\n".join(f"== {f.name}\n{f.read_text(errors='replace')[-3000:]}" for f in self.folder.glob("*.log"))


@contextmanager
def dask_cluster(folder: Path, n_workers: int, extra_env: dict | None = None):
    """A scheduler and ``n_workers`` single-threaded workers on 127.0.0.1, torn down on exit.

    ``extra_env`` sets environment variables of the processes (e.g. Dask settings as ``DASK_...``).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    c = Cluster(folder, extra_env)
    try:
        c.start_scheduler()
        for _ in range(n_workers):
            c.add_worker()
        c.wait_for_workers(n_workers)
        yield c
    except BaseException:
        print(c.logs(), file=sys.stderr)
        raise
    finally:
        c.close()
