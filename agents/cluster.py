"""Ray: start an embedded local cluster or join a running one, with the environment its workers
need.

Used by ``rbenvs-results --backend ray``, ``rbenvs-sweep`` and the RLlib recipe
(:mod:`rbenvs_agents.rllib`). Ray is imported here, lazily, and only after
:func:`rbenvs.extras.require` has checked the ``ray`` extra, so a missing Ray is the one-line
message of every other missing extra.

Every worker gets :func:`worker_env` through the job's runtime environment:

* ``NUMBA_NUM_THREADS=1``: numba sizes its thread pool from the cores of the machine, not from
  the CPUs Ray gave the task, so each worker would otherwise start one thread per core;
* ``RBENVS_CONFIGS``, when set here, so that the workers read the same scenes and
  hyperparameters as this process (on a cluster of several machines the folder must exist at
  the same path on each; the shipped configs need nothing).
"""

from __future__ import annotations

import os
from contextlib import contextmanager

from rbenvs.extras import require

__all__ = ["worker_env", "ray_cluster"]


def worker_env() -> dict[str, str]:
    """The environment variables every Ray worker of rbenvs gets."""
    env = {"NUMBA_NUM_THREADS": "1"}
    if os.environ.get("RBENVS_CONFIGS"):
        env["RBENVS_CONFIGS"] = os.path.abspath(os.environ["RBENVS_CONFIGS"])
    return env


@contextmanager
def ray_cluster(address: str | None = None, num_cpus: int | None = None):
    """Yield the ``ray`` module connected to a cluster, and disconnect at the end.

    ``address`` (``"auto"``, ``"ray://host:10001"``, ``"host:6379"``): join that cluster; None:
    start an embedded local cluster of ``num_cpus`` CPUs (None: every core), stopped on exit. If
    this process is already connected (``ray.is_initialized()``: a notebook, a test), that
    session is used as it is and left running; its workers should have :func:`worker_env`.
    """
    require("ray")
    if address is not None and num_cpus is not None:
        raise ValueError(
            "--num-cpus sizes the embedded local cluster; a cluster joined with --address has its "
            "own CPUs"
        )
    if num_cpus is not None and num_cpus < 1:
        raise ValueError(f"--num-cpus must be >= 1, got {num_cpus}")
    import logging

    import ray

    if ray.is_initialized():
        yield ray
        return
    options = {
        "runtime_env": {"env_vars": worker_env()},
        "include_dashboard": False,
        "logging_level": logging.WARNING,
    }
    if address is None:
        # Ray starts its workers at nice 15, to keep its own processes responsive; here they do
        # all of the command's work, and at nice 15 they yield to every other program on the
        # machine (measured: 0.56 of a core each beside one busy process on 2 cores), so they run
        # at the priority the serial backend runs at. A joined cluster keeps its own setting.
        ray.init(num_cpus=num_cpus, _system_config={"worker_niceness": 0}, **options)
    else:
        ray.init(address=address, **options)
    try:
        yield ray
    finally:
        ray.shutdown()
