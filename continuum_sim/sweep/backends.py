"""Where variants run: local worker processes, one shared model in-process, or Ray.

Every backend takes the pending variants and calls ``on_result(variant, result)`` in the
driver as each one finishes; the driver alone writes records, so a remote Ray worker
never needs the sweep folder. No backend decides what a variant computes: that is
``worker.evaluate_payload`` (processes, Ray) or ``static.evaluate_static_shared``
(shared model), and tests check they agree bit for bit.

Ray is a ``RaySession``: a study connects once, whatever the number of ``run`` calls, and
keeps one warm worker per CPU (``RayWorker``) for all of them; a refused connection is
one line naming its cause (authentication, versions, an unreachable address).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import re
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from ..configio import ConfigError, to_dict
from ..lifetime import die_with, mark_starter
from .spec import SweepSpec, Variant
from .worker import describe, evaluate_payload, warm_up

OnResult = Callable[[Variant, dict[str, Any]], None]


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def payload(spec: SweepSpec, variant: Variant, run_root: str | None) -> dict[str, Any]:
    """What a worker needs for one variant, as plain data."""
    return {
        "config": to_dict(spec.config_for(variant)),
        "evaluation": spec.evaluation.to_dict(),
        "run_dir": None if run_root is None else os.path.join(run_root, variant.variant_id),
    }


# ------------------------------------------------------------------ local processes
def worker_init(driver_pid: int) -> None:
    """Pool initializer: never outlive the driver (a SIGKILLed sweep leaves no orphan workers), then warm up.

    Ctrl-C is the driver's to handle (a terminal sends it to the whole process group; each
    worker would print a traceback): workers ignore SIGINT and the driver stops them.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with(driver_pid)  # the forkserver is the parent; the driver is what must be alive
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))  # deep models (200 segments per section)
    warm_up()


@contextlib.contextmanager
def _stopped_on_interrupt(pool: ProcessPoolExecutor) -> Iterator[ProcessPoolExecutor]:
    """``with pool``, except that Ctrl-C/SIGTERM kills the workers at once instead of waiting for their variants
    (finished variants are already recorded; the rest run again on resume)."""
    try:
        yield pool
    except BaseException as exc:
        if not isinstance(exc, Exception):
            for process in list((getattr(pool, "_processes", None) or {}).values()):  # private: no public kill
                process.kill()
            pool.shutdown(wait=False, cancel_futures=True)
        else:
            pool.shutdown(wait=True)
        raise
    pool.shutdown(wait=True)


def _executor(workers: int) -> ProcessPoolExecutor:
    # forkserver: workers fork from a server that has already imported MuJoCo and
    # dm_control, so a worker starts in milliseconds and never inherits driver threads.
    context = multiprocessing.get_context("forkserver")
    mark_starter()  # the forkserver (a child of this driver) exits the moment the driver is gone
    context.set_forkserver_preload(["continuum_sim.sweep.forkserver_guard", "continuum_sim.sweep.worker", "continuum_sim.sweep.static"])
    return ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=worker_init, initargs=(os.getpid(),))


def run_processes(spec: SweepSpec, variants: Sequence[Variant], workers: int, run_root: str | None, on_result: OnResult) -> None:
    """One variant per task on a pool of ``workers`` processes.

    If a worker dies (segfault, out of memory), the pool breaks and every unfinished
    task with it; those variants are then re-run one at a time in fresh single-worker
    pools, so only the variant that kills its process is recorded as failed.
    """
    remaining = list(variants)
    with _stopped_on_interrupt(_executor(workers)) as pool:
        remaining = _drain(pool, spec, remaining, workers, run_root, on_result)
    for variant in remaining:  # after a crash: isolate each unfinished variant
        with _stopped_on_interrupt(_executor(1)) as pool:
            left = _drain(pool, spec, [variant], 1, run_root, on_result)
        for dead in left:
            on_result(dead, _failed("worker process died (crash or out of memory) while evaluating this variant"))


def _drain(pool, spec: SweepSpec, variants: list[Variant], workers: int, run_root, on_result: OnResult) -> list[Variant]:
    """Run ``variants`` on ``pool`` keeping ~2 tasks per worker queued; returns unfinished ones."""
    queue = list(reversed(variants))
    running: dict[Any, Variant] = {}
    try:
        while queue or running:
            while queue and len(running) < 2 * workers:
                variant = queue.pop()
                running[pool.submit(evaluate_payload, payload(spec, variant, run_root))] = variant
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                variant = running.pop(future)
                on_result(variant, future.result())
    except BrokenProcessPool:
        return [v for v in running.values()] + list(reversed(queue))
    return []


def _failed(reason: str) -> dict[str, Any]:
    return {"status": "failed", "metrics": {}, "error": reason, "wall_s": None, "cpu_s": None, "host": None, "pid": None}


# ------------------------------------------------------------------ shared model
def run_shared(spec: SweepSpec, variants: Sequence[Variant], workers: int, on_result: OnResult, progress: bool = False) -> None:
    """Static evaluations in-process: one compiled model per structure, rollout threads."""
    import socket

    from tqdm import tqdm

    from .static import evaluate_static_shared, structural_paths

    configs = [spec.config_for(v) for v in tqdm(variants, desc="preparing variants", unit="variant", leave=False, mininterval=0.5,
                                                 disable=not progress or len(variants) < 20_000, file=sys.stderr, dynamic_ncols=True)]
    host, pid = socket.gethostname(), os.getpid()
    start, cpu_start = time.perf_counter(), time.process_time()
    structural = [i for i, path in enumerate(spec.paths) if path in structural_paths(spec.paths)]
    keys = [tuple(v.params[i][1] for i in structural) for v in variants]  # = structure_key grouping, without it
    for indices, results in evaluate_static_shared(configs, spec.evaluation, nthread=workers, keys=keys):
        now, cpu_now = time.perf_counter(), time.process_time()
        share = (now - start) / len(indices)  # a batch's wall and CPU time, shared by its variants
        cpu_share = (cpu_now - cpu_start) / len(indices)
        start, cpu_start = now, cpu_now
        for i, result in zip(indices, results):
            if isinstance(result, Exception):
                out = {"status": "failed", "metrics": getattr(result, "metrics", {}), "error": describe(result)}
            else:
                out = {"status": "ok", "metrics": result, "error": None}
            on_result(variants[i], {**out, "wall_s": share, "cpu_s": cpu_share, "host": host, "pid": pid})


# --------------------------------------------------------------------------- Ray
class _CapturedStderr:
    """What was written to file descriptor 2 inside ``captured_stderr()``: Ray's C++ client logs there, past ``sys.stderr``."""

    text = ""


@contextlib.contextmanager
def captured_stderr() -> Iterator[_CapturedStderr]:
    """File descriptor 2 into a temporary file for the duration; its text in the yielded object afterwards.

    Ray's client logs a line per connection retry (20 for an address that is not Ray, or a
    cluster that refuses the token); those lines must not flood a study's terminal, but they
    are the only place that names the cause, so they are kept for ``connection_error``.
    """
    import tempfile

    captured = _CapturedStderr()
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield captured
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield captured
        finally:
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.text = sink.read(1 << 20).decode("utf-8", "replace")


def _resolve(host: str, port: int) -> Any:
    """The first TCP address of ``host:port``, or the ``OSError`` resolving it raised."""
    try:
        return socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except OSError as exc:
        return exc


CONNECT_TIMEOUT_S = 10.0  # how long the TCP probe of a Ray address may take


def probe_address(address: str, timeout: float | None = None) -> None:
    """Refuse a Ray address whose host:port does not accept a TCP connection within ``timeout``.

    ``auto`` / ``local`` (Ray's own discovery) pass through; ``ray://host:port`` and
    ``host:port`` are probed.
    """
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    if address in ("auto", "local"):
        return
    target = address.removeprefix("ray://")
    host, sep, port_text = target.rpartition(":")
    if not sep or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ConfigError("--address", f"must be host:port, ray://host:port, auto or local (got {address[:80]!r})")
    # Name resolution ignores socket timeouts: resolve in a helper thread and stop waiting after ``timeout``.
    resolved: list[Any] = []
    resolver = threading.Thread(
        target=lambda: resolved.append(_resolve(host.strip("[]"), int(port_text))), daemon=True, name="resolve-ray-address"
    )
    resolver.start()
    resolver.join(timeout)
    if not resolved:
        raise ConfigError("--address", f"cannot resolve {host[:80]!r} within {timeout:g} s")
    if isinstance(resolved[0], OSError):
        raise ConfigError("--address", f"cannot resolve {host[:80]!r} ({resolved[0].strerror or resolved[0]})")
    family, kind, proto, _, sockaddr = resolved[0]
    try:
        with socket.socket(family, kind, proto) as sock:
            sock.settimeout(timeout)
            sock.connect(sockaddr)
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        raise ConfigError(
            "--address", f"cannot reach a Ray cluster at {address[:80]!r} ({reason} after at most {timeout:g} s)"
        ) from None


AUTH_HELP = "authentication failed: set RAY_AUTH_TOKEN or RAY_AUTH_TOKEN_PATH (ray get-auth-token on the head)"
_AUTH_MARKERS = ("Unauthenticated", "InvalidAuthToken", "AuthenticationError", "authentication token", "Authentication token")
_VERSIONS = re.compile(
    r"cluster was started with:\s*Ray:\s*(\S+)\s*Python:\s*(\S+).*?was started with:\s*Ray:\s*(\S+)\s*Python:\s*(\S+)", re.S
)


def connection_error(address: str | None, exc: BaseException, ray_log: str = "") -> str:
    """One line naming why ``ray.init`` failed: authentication, a version mismatch, or (else) Ray's own last word.

    ``ray_log``: what Ray wrote to stderr meanwhile (``captured_stderr``); a refused token shows
    only there, as one warning per retry, while the exception says "Failed to connect".
    """
    where = f"the Ray cluster at {address!r}" if address else "a local Ray instance"
    text = f"{type(exc).__name__}: {exc}\n{ray_log}"
    if any(marker in text for marker in _AUTH_MARKERS):
        given = [name for name in ("RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH") if os.environ.get(name)]
        detail = f"the cluster refused the token from {given[0]}" if given else "no token given"
        return f"cannot connect to {where}: {AUTH_HELP}; {detail}"
    versions = _VERSIONS.search(text)
    if versions or "Version mismatch" in text:
        if versions:
            ray_there, python_there, ray_here, python_here = versions.groups()
            detail = f"the cluster runs Ray {ray_there} on Python {python_there}, this machine Ray {ray_here} on Python {python_here}"
        else:
            detail = "Ray or Python differ between the cluster and this machine"
        return f"cannot connect to {where}: version mismatch: {detail}; install the same versions here and on every node"
    said = [line.strip() for line in ray_log.splitlines() if line.strip() and " INFO " not in line]
    last = f" (Ray: {' '.join(said[-1].split())[:200]})" if said else ""
    return f"cannot connect to {where}: {describe(exc)}{last}"


def _token_mode_from_environment() -> str | None:
    """Token authentication on for this driver when a token is given but ``RAY_AUTH_MODE`` is not; returns the old value.

    Ray sends a token to an explicit address only under ``RAY_AUTH_MODE=token``; a token put in
    ``RAY_AUTH_TOKEN`` / ``RAY_AUTH_TOKEN_PATH`` is meant to be used, so setting it is enough here.
    """
    old = os.environ.get("RAY_AUTH_MODE")
    if old is None and (os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH")):
        os.environ["RAY_AUTH_MODE"] = "token"
        if "ray" in sys.modules:  # Ray reads its configuration once; re-read it (as Ray does when it enables the mode itself)
            with contextlib.suppress(Exception):
                import ray._raylet

                ray._raylet.Config.initialize("")  # type: ignore[attr-defined]  # compiled module, no stubs
    return old


class RayWorker:
    """One warm worker slot on the cluster (a Ray actor): imports the package once, then evaluates variants one by one.

    A variant's recorded cost (``evaluate_payload``'s wall and CPU time) therefore never includes
    a worker's start-up (process, runtime environment, imports); ``RaySession`` reports that apart.
    """

    def __init__(self) -> None:
        start = time.perf_counter()
        sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))  # deep models, as in the local workers
        warm_up()
        self.startup_s = time.perf_counter() - start

    def ready(self) -> tuple[str, int, float]:
        return socket.gethostname(), os.getpid(), self.startup_s

    def evaluate(self, payload: dict[str, Any]) -> dict[str, Any]:
        return evaluate_payload(payload)


def _log_stderr(line: str) -> None:
    from tqdm import tqdm

    tqdm.write(line, file=sys.stderr)  # above any progress bar


PER_WORKER = 2  # variants queued on a worker: the next one is there when it finishes one


class RaySession:
    """One Ray connection and one set of warm workers for a whole study (``with RaySession(...) as ray:``).

    The study's driver opens it once and calls ``run`` as often as it has variants (the
    optimiser once per generation): connecting, shipping the package and starting workers
    happen once. It connects on the first ``run`` (a study with nothing left to run never
    connects) and logs ``ray: connected to ADDRESS (N CPUs)`` then, one line per study.

    The driver ships this ``continuum_sim`` package to the workers (runtime_env
    ``py_modules``), so the cluster runs exactly the driver's code; each node's Python needs
    the same Ray and Python versions and the dependencies (MuJoCo, dm_control, numpy, scipy).

    ``worker_startup_s``: seconds from starting the workers until the last was ready (not part
    of any variant's cost). A worker that dies (segfault, out of memory, node lost) is replaced;
    the variant it was running is tried once more, then recorded as failed.
    """

    def __init__(self, workers: int | None, address: str | None, log: Callable[[str], None] | None = None) -> None:
        self.workers, self.address = workers, address
        self.log = log or _log_stderr
        self.worker_startup_s: float | None = None
        self.cpus: int | None = None
        self._ray: Any = None
        self._auth_mode: str | None = None
        self._actors: dict[int, Any] = {}  # slot -> actor handle
        self._ready: set[int] = set()
        self._starting: dict[Any, int] = {}  # ready() ref -> slot
        self._startup_clock: float | None = None
        self._last_ready_s: float | None = None
        self._slots = 0

    def __enter__(self) -> RaySession:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------ connection
    def connect(self) -> None:
        """Connect (once): a refused connection is one ``ConfigError`` line naming its cause."""
        if self._ray is not None:
            return
        self._auth_mode = _token_mode_from_environment()
        try:
            import ray
        except ImportError:
            raise ConfigError("--backend", "ray is not installed; install it with pip install 'continuum_sim[ray]'") from None
        import continuum_sim

        runtime_env = {"py_modules": [continuum_sim], "env_vars": {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}}
        init_kwargs: dict[str, Any] = {"runtime_env": runtime_env, "log_to_driver": False}
        if self.address is None:
            init_kwargs.update(num_cpus=self.workers or default_workers(), include_dashboard=False)
        else:
            probe_address(self.address)  # an unreachable cluster is one line in seconds, not a hang
            init_kwargs["address"] = self.address
        failure: Exception | None = None
        with captured_stderr() as ray_log:
            try:
                ray.init(**init_kwargs)
            except Exception as exc:  # noqa: BLE001 - classified below, from the exception and Ray's log
                failure = exc
        if failure is not None:
            self._restore_auth_mode()
            raise ConfigError("--address" if self.address else "--backend", connection_error(self.address, failure, ray_log.text)) from None
        self._ray = ray
        self.cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        where = self.address or ray.get_runtime_context().gcs_address
        self.log(f"ray: connected to {where} ({self.cpus} CPUs)")

    def _restore_auth_mode(self) -> None:
        if self._auth_mode is None:
            os.environ.pop("RAY_AUTH_MODE", None)
        else:
            os.environ["RAY_AUTH_MODE"] = self._auth_mode

    # ------------------------------------------------------------ workers
    def _start_workers(self) -> None:
        cpus = self.cpus or 1  # set by connect
        self._slots = min(self.workers, cpus) if self.workers else cpus
        if self.workers and self.workers > self._slots:
            self.log(f"ray: --workers {self.workers} > the cluster's {self.cpus} CPUs; starting {self._slots} workers")
        self._startup_clock = time.perf_counter()
        for slot in range(self._slots):
            self._start_worker(slot)

    def _start_worker(self, slot: int) -> None:
        actor = self._ray.remote(num_cpus=1, max_restarts=0)(RayWorker).remote()
        self._actors[slot] = actor
        self._starting[actor.ready.remote()] = slot

    def _worker_started(self, ref: Any) -> None:
        slot = self._starting.pop(ref)
        try:
            self._ray.get(ref)
        except Exception as exc:  # noqa: BLE001 - its node lacks a dependency, runtime env failed, ...
            self._actors.pop(slot, None)
            if not self._actors:
                raise ConfigError("--address" if self.address else "--backend", f"no Ray worker could start: {describe(exc)}") from None
            self.log(f"ray: a worker could not start ({describe(exc)[:200]}); going on with {len(self._actors)}")
        else:
            self._ready.add(slot)
            if self._startup_clock is not None:
                self._last_ready_s = time.perf_counter() - self._startup_clock
        if not self._starting:
            self._report_startup()

    def _report_startup(self) -> None:
        """``worker_startup_s`` (once): until the last worker was ready, or the last ready one when the study ended first."""
        if self.worker_startup_s is not None or self._last_ready_s is None:
            return
        self.worker_startup_s = self._last_ready_s
        ready = f"{len(self._ready)}" if not self._starting else f"{len(self._ready)} of {len(self._ready) + len(self._starting)}"
        rest = "" if not self._starting else "; the rest were still starting when the study ended"
        self.log(f"ray: {ready} workers ready in {self.worker_startup_s:.1f} s (worker_startup_s; not part of any variant's cost){rest}")

    def _replace_worker(self, slot: int) -> None:
        self._ready.discard(slot)
        actor = self._actors.pop(slot, None)
        if actor is not None:
            with contextlib.suppress(Exception):
                self._ray.kill(actor)
        self._start_worker(slot)

    # ------------------------------------------------------------ variants
    def run(self, spec: SweepSpec, variants: Sequence[Variant], run_root: str | None, on_result: OnResult) -> None:
        """Evaluate ``variants`` on the warm workers; ``on_result`` in the driver as each finishes."""
        if not variants:
            return
        self.connect()
        if not self._actors:
            self._start_workers()
        ray = self._ray
        queue = list(reversed(variants))
        deaths: dict[str, int] = {}
        running: dict[Any, tuple[int, Variant]] = {}
        on_worker: dict[int, list[Any]] = {}  # slot -> its refs in submission order (a worker runs them in that order)
        while queue or running:
            for slot in sorted(self._ready):
                mine = on_worker.setdefault(slot, [])
                while queue and len(mine) < PER_WORKER:
                    variant = queue.pop()
                    ref = self._actors[slot].evaluate.remote(payload(spec, variant, run_root))
                    running[ref] = (slot, variant)
                    mine.append(ref)
            done, _ = ray.wait(list(running) + list(self._starting), num_returns=1)
            ref = done[0]
            if ref in self._starting:
                self._worker_started(ref)
                continue
            slot, variant = running.pop(ref)
            try:
                result = ray.get(ref)
            except ray.exceptions.RayActorError as exc:  # the worker died: crash, out of memory, node lost
                self._worker_died(slot, [variant if r == ref else running.pop(r)[1] for r in on_worker.pop(slot)],
                                  queue, deaths, on_result, exc)
                continue
            except Exception as exc:  # noqa: BLE001 - the result could not come back (serialisation, ...)
                result = _failed(f"ray task failed: {describe(exc)}")
            on_worker[slot].remove(ref)
            on_result(variant, result)

    def _worker_died(self, slot: int, lost: list[Variant], queue: list[Variant], deaths: dict[str, int],
                     on_result: OnResult, exc: BaseException) -> None:
        """A worker died with ``lost`` on it (in submission order: the first was running, the rest only queued).

        The running one is tried once more on another worker, then recorded as failed; the
        queued ones go back to the front of the queue; the slot gets a fresh worker.
        """
        running, waiting = lost[0], lost[1:]
        queue.extend(reversed(waiting))
        deaths[running.variant_id] = deaths.get(running.variant_id, 0) + 1
        if deaths[running.variant_id] >= 2:
            on_result(running, _failed(f"ray worker died (crash, out of memory or node lost) while evaluating this variant: {describe(exc)[:300]}"))
        else:
            queue.append(running)
        self.log(f"ray: a worker died ({type(exc).__name__}); starting another")
        self._replace_worker(slot)

    def close(self) -> None:
        """Stop the workers and disconnect (a local instance stops with it)."""
        ray, self._ray = self._ray, None
        if ray is None:
            return
        self._report_startup()
        self._actors.clear()
        self._ready.clear()
        self._starting.clear()
        try:
            ray.shutdown()
        finally:
            self._restore_auth_mode()


@contextlib.contextmanager
def study_session(backend: str, workers: int | None, address: str | None) -> Iterator[RaySession | None]:
    """A study's one Ray session (None for the local backend), closed when the study ends.

    With an address it connects at once, so a refused connection (token, versions) stops
    the study before its folder is touched; a local instance starts with the first variant.
    """
    if backend != "ray":
        yield None
        return
    with RaySession(workers, address) as session:
        if address is not None:
            session.connect()
        yield session


def run_ray(
    spec: SweepSpec,
    variants: Sequence[Variant],
    workers: int | None,
    address: str | None,
    run_root: str | None,
    on_result: OnResult,
) -> None:
    """``variants`` through a ``RaySession`` of their own (a driver with several lists keeps one session instead)."""
    with RaySession(workers, address) as session:
        session.run(spec, variants, run_root, on_result)
