"""Connections to Dask clusters: a running scheduler (tcp://HOST:8786) or a LocalCluster.

Dask is imported here, lazily: a render on this machine's own worker pool never loads it.
A connection is kept for the life of the process (the next render or animation frame
reuses the cluster's workers and their tracers); a LocalCluster ("local") is started on
first use with one single-threaded worker process per requested worker. Embree holds
Python's lock while it traces, so more threads in one worker would gain nothing.

A scheduler that cannot be reached fails within CONNECT_TIMEOUT with a ClusterError that
names the address; it never hangs.
"""

from __future__ import annotations

import atexit
import logging
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from distributed import Client

LOCAL = "local"  # the --cluster value that starts a LocalCluster on this machine
CONNECT_TIMEOUT = 5.0  # seconds: connecting to a scheduler on a LAN takes milliseconds
WORKER_WAIT = 30.0  # seconds a render waits for a scheduler without workers to get one

_clients: dict[tuple[str, int], Client] = {}


class ClusterError(RuntimeError):
    """The cluster cannot be used (unreachable, no workers); the message says which and why."""


def connect(address: str, workers: int = 1, timeout: float = CONNECT_TIMEOUT) -> Client:
    """A client of the cluster at `address`, or of a LocalCluster of `workers` processes for
    "local"; reused while it stays connected."""
    address = address.strip()
    key = (address, workers if address == LOCAL else 0)
    client = _clients.get(key)
    if client is not None and client.status == "running":
        return client
    client = _start_local(workers, timeout) if address == LOCAL else _connect_remote(address, timeout)
    _clients[key] = client
    return client


def _start_local(workers: int, timeout: float) -> Client:
    from distributed import Client, LocalCluster

    from .workers import spawning

    # Worker processes start with SIGINT ignored (inherited through spawn): a Ctrl-C sent to
    # the process group must reach this process only, which cancels the cluster's work. Nor
    # do they run this process's script again (workers.spawning).
    with spawning():
        # No dashboard (it needs bokeh); the scheduler's small HTTP server takes any free port.
        cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                               dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"},
                               silence_logs=logging.ERROR)
    return Client(cluster, timeout=timeout)


def _connect_remote(address: str, timeout: float) -> Client:
    from distributed import Client

    if "://" not in address:
        raise ClusterError(f"cluster {address!r}: expected 'local' or a scheduler address such as "
                           "tcp://HOST:8786")
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError) as error:  # distributed raises OSError on its own timeout
        raise ClusterError(f"cannot reach the Dask scheduler at {address} within {timeout:g} s "
                           f"({error}); is `dask scheduler` running there and the port open?") from None


def worker_addresses(client: Client) -> list[str]:
    return sorted(client.scheduler_info(n_workers=-1)["workers"])


def wait_for_a_worker(client: Client, address: str, timeout: float = WORKER_WAIT) -> None:
    """Return once the scheduler has a worker; a ClusterError after `timeout` seconds."""
    try:
        client.wait_for_workers(1, timeout=timeout)
    except TimeoutError:
        raise ClusterError(f"the Dask scheduler at {address} has no workers (waited {timeout:g} s); "
                           f"start some with `dask worker {address}`") from None


def describe(address: str, timeout: float = CONNECT_TIMEOUT) -> str:
    """One line on what a render with this cluster setting would use (Blender's Test button)."""
    address = address.strip()
    if not address:
        return "this machine's worker processes (no cluster set)"
    if address == LOCAL:
        return "a local Dask cluster, started at the first render (one process per worker)"
    client = connect(address, timeout=timeout)
    info = client.scheduler_info(n_workers=-1)["workers"]
    threads = sum(w.get("nthreads", 0) for w in info.values())
    hosts = sorted({w.get("host", "?") for w in info.values()})
    return (f"{address}: {len(info)} workers ({threads} threads) on {len(hosts)} hosts"
            + (f": {', '.join(hosts)}" if hosts else ""))


def shutdown_clusters() -> None:
    """Close every connection, and stop the LocalClusters this process started."""
    for client in list(_clients.values()):
        cluster = client.cluster
        try:
            client.close(timeout=5)
            if cluster is not None:
                cluster.close(timeout=5)
        except Exception:  # noqa: BLE001 - shutting down: a half-closed cluster is gone anyway
            pass
    _clients.clear()


atexit.register(shutdown_clusters)
