"""Where variants run: local worker processes, one shared model in-process, or Ray.

Every backend takes the pending variants and calls ``on_result(variant, result)`` in the
driver as each one finishes; the driver alone writes records, so a remote Ray worker
never needs the sweep folder. No backend decides what a variant computes: that is
``worker.evaluate_payload`` (processes, Ray) or ``static.evaluate_static_shared``
(shared model), and tests check they agree bit for bit.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
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
@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """File descriptor 2 to /dev/null for the duration (C++ logging bypasses ``sys.stderr``)."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


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


def run_ray(
    spec: SweepSpec,
    variants: Sequence[Variant],
    workers: int | None,
    address: str | None,
    run_root: str | None,
    on_result: OnResult,
) -> None:
    """One Ray task per variant on the cluster at ``address`` (a local one if None).

    The driver ships this ``continuum_sim`` package to the workers (runtime_env
    ``py_modules``), so the cluster runs exactly the driver's code; its Python needs
    the dependencies (MuJoCo, dm_control, numpy, scipy).
    """
    try:
        import ray
    except ImportError:
        raise ConfigError("--backend", "ray is not installed; install it with pip install 'continuum_sim[ray]'") from None
    import continuum_sim

    runtime_env = {"py_modules": [continuum_sim], "env_vars": {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}}
    init_kwargs: dict[str, Any] = {"runtime_env": runtime_env, "log_to_driver": False}
    if address is None:
        init_kwargs.update(num_cpus=workers or default_workers(), include_dashboard=False)
    else:
        probe_address(address)  # an unreachable cluster is one line in seconds, not a hang
        init_kwargs["address"] = address
    try:
        with _quiet_stderr():  # Ray's C++ client logs a line per connection retry (20 for an address that is not Ray)
            ray.init(**init_kwargs)
    except ConnectionError as exc:
        raise ConfigError("--address", f"cannot connect to a Ray cluster at {address!r}: {describe(exc)}") from None
    try:
        capacity = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=1)(evaluate_payload)
        queue = list(reversed(variants))
        running: dict[Any, Variant] = {}
        while queue or running:
            while queue and len(running) < 2 * capacity:
                variant = queue.pop()
                running[task.remote(payload(spec, variant, run_root))] = variant
            done, _ = ray.wait(list(running), num_returns=1)
            for ref in done:
                variant = running.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - worker crash, node lost, ...
                    result = _failed(f"ray task failed: {describe(exc)}")
                on_result(variant, result)
    finally:
        ray.shutdown()
