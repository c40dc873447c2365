"""Where a study's evaluations run: the sweep's worker processes or Ray, fed one generation at a time.

Both run ``sweep.worker.evaluate_payload`` (the sweep's worker: a failing evaluation is a
result with its named failure, never an exception), and call ``on_result`` in the driver as
each evaluation finishes, which records it before anything else happens.

* local: one pool of the sweep's forkserver workers for the whole study (``sweep.backends``:
  workers die with the driver, ignore Ctrl-C), so a worker's warm caches serve every
  generation. A worker that dies breaks the pool; the evaluations then in flight are re-run
  through ``backends.run_processes`` (one at a time in fresh pools), so only the one that
  kills its process is recorded as failed, and the study goes on with a new pool.
* ray: one ``backends.RaySession`` for the whole study (connected once, at the first
  generation, with warm workers kept across generations; its package shipping and failure
  handling), so the same spec runs on a cluster.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from ..sweep import backends
from ..sweep.spec import SweepSpec, Variant
from ..sweep.worker import evaluate_payload

OnResult = Callable[[Variant, dict[str, Any]], None]


class LocalPool:
    """The sweep's process pool (``backends._executor``: forkserver workers that die with the driver), kept for the whole study."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool: Any = None

    def run(self, spec: SweepSpec, variants: Sequence[Variant], on_result: OnResult) -> None:
        """Evaluate ``variants``; ``on_result`` as each finishes (all queued at once: the pool keeps its workers busy)."""
        if self._pool is None:
            self._pool = backends._executor(self.workers)  # private there: the sweep opens one pool per list
        running = {self._pool.submit(evaluate_payload, backends.payload(spec, v, None)): v for v in variants}
        try:
            while running:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    on_result(running.pop(future), future.result())
        except BrokenProcessPool:
            self.close()  # the next generation opens a fresh pool
            backends.run_processes(spec, list(running.values()), 1, None, on_result)  # isolates the one that kills its worker

    def close(self, abort: bool = False) -> None:
        """Shut the pool down; ``abort`` (Ctrl-C, SIGTERM): kill the workers now, as ``sweep.backends`` does."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if abort:
            for process in list((getattr(pool, "_processes", None) or {}).values()):  # private: no public kill
                process.kill()
            pool.shutdown(wait=False, cancel_futures=True)
        else:
            pool.shutdown(wait=True)


class RayPool:
    """One ``backends.RaySession`` (local Ray instance or the cluster at ``address``) for every generation of the study."""

    def __init__(self, workers: int | None, address: str | None) -> None:
        self.workers, self.address = workers, address
        self.session = backends.RaySession(workers, address)

    @property
    def worker_startup_s(self) -> float | None:
        """Seconds to start the warm workers (not part of any evaluation's cost); None before the first generation."""
        return self.session.worker_startup_s

    def run(self, spec: SweepSpec, variants: Sequence[Variant], on_result: OnResult) -> None:
        self.session.run(spec, variants, None, on_result)

    def close(self, abort: bool = False) -> None:  # noqa: ARG002 - a Ray session stops the same way either way
        self.session.close()


@contextlib.contextmanager
def open_pool(backend: str, workers: int | None, address: str | None) -> Iterator[LocalPool | RayPool]:
    pool: LocalPool | RayPool = RayPool(workers, address) if backend == "ray" else LocalPool(workers or backends.default_workers())
    try:
        yield pool
    except BaseException as exc:
        pool.close(abort=not isinstance(exc, Exception))
        raise
    pool.close()
