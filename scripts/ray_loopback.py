"""A two-node Ray cluster with token authentication on 127.0.0.1, for the scripts that measure Ray (a context manager).

    from ray_loopback import loopback_cluster
    with loopback_cluster(cpus_per_node=1) as cluster:   # cluster.address "127.0.0.1:PORT", cluster.env for a driver
        subprocess.run([... "--backend", "ray", "--address", cluster.address], env=cluster.env)

The same cluster as tests/test_ray_cluster.py: a helper process starts a head and a second
node as Ray's own multi-node tests do (``ray start`` replaces 127.0.0.1 with the machine's
outward address), every server listening on 127.0.0.1 only, ``RAY_AUTH_MODE=token`` with a
token generated here. A driver gets the token through its environment only (``cluster.env``:
``RAY_AUTH_TOKEN``, no ``RAY_AUTH_MODE``; the study turns token mode on itself). The nodes are
stopped in a finally, then any process of this cluster still alive (each names the cluster's
own temp folder) is killed by its id; nothing else is touched.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

NODES = """\
import sys
from ray._private.node import Node
from ray._private.parameter import RayParams

port, temp_dir, cpus = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
common = dict(node_ip_address="127.0.0.1", num_cpus=cpus, num_gpus=0, temp_dir=temp_dir, include_dashboard=False,
              object_store_memory=80 * 1024 * 1024, min_worker_port=0, max_worker_port=0)
nodes = []
try:
    head = Node(RayParams(**common, gcs_server_port=port), head=True, shutdown_at_exit=True, spawn_reaper=True)
    nodes.append(head)
    nodes.append(Node(RayParams(**common, gcs_address=head.gcs_address, include_log_monitor=False, node_manager_port=0,
                                dashboard_agent_listen_port=None), head=False, shutdown_at_exit=True, spawn_reaper=True))
    print("READY", head.gcs_address, flush=True)
    sys.stdin.read()  # until the driver script closes it
finally:
    for node in reversed(nodes):
        node.kill_all_processes(check_alive=False, allow_graceful=True)
"""

# Ray maps a loopback address to the machine's outward one unless told this is no multi-node setup.
LOOPBACK = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}


@dataclass
class Cluster:
    address: str
    env: dict[str, str]
    start_s: float
    nodes: int = 2
    cpus_per_node: int = 1
    strays_killed: list[int] = field(default_factory=list)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _cluster_processes(temp_dir: str) -> list:
    import psutil  # a dependency of ray

    found = []
    for proc in psutil.process_iter(["pid", "cmdline"]):
        if proc.pid != os.getpid() and any(temp_dir in part for part in (proc.info["cmdline"] or [])):
            found.append(proc)
    return found


def driver_env(token: str | None = None) -> dict[str, str]:
    """This process's environment without any RAY_ setting, plus loopback, the token (if any) and the repository on PYTHONPATH."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env.update(LOOPBACK, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if token is not None:
        env["RAY_AUTH_TOKEN"] = token
    return env


@contextlib.contextmanager
def loopback_cluster(cpus_per_node: int = 1, start_timeout: float = 120.0) -> Iterator[Cluster]:
    token = secrets.token_hex(32)
    temp_dir = tempfile.mkdtemp(prefix="csray", dir="/tmp")  # short: Ray's socket paths must fit 107 characters
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env.update(LOOPBACK, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=token)
    start = time.perf_counter()
    helper = subprocess.Popen([sys.executable, "-c", NODES, str(_free_port()), temp_dir, str(cpus_per_node)], env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              start_new_session=True)
    cluster = None
    try:
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.append(helper.stdout.readline()), daemon=True)
        reader.start()
        reader.join(start_timeout)
        if not (lines and lines[0].startswith("READY 127.0.0.1:")):
            raise RuntimeError(f"the loopback Ray cluster did not start in {start_timeout:.0f} s: {lines}")
        cluster = Cluster(address=lines[0].split()[1], env=driver_env(token), start_s=time.perf_counter() - start,
                          cpus_per_node=cpus_per_node)
        yield cluster
    finally:
        helper.stdin.close()
        try:
            helper.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(helper.pid, signal.SIGKILL)  # the helper's own session: only this cluster
            helper.wait(timeout=10)
        deadline = time.monotonic() + 10
        while _cluster_processes(temp_dir) and time.monotonic() < deadline:
            time.sleep(0.2)
        for proc in _cluster_processes(temp_dir):  # only this cluster's processes: they name its temp folder
            proc.kill()
            if cluster is not None:
                cluster.strays_killed.append(proc.pid)
        shutil.rmtree(temp_dir, ignore_errors=True)
