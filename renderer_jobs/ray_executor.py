"""The Ray executor of :mod:`renderer_jobs.jobs`: the same jobs as the local pool (:mod:`renderer_jobs.local_executor`), as Ray tasks on a
cluster (one CPU and a one-thread Dr.Jit pool per task, so Ray packs as many tasks as a node has
cores). Imported only when ``--executor ray`` is asked for."""

from __future__ import annotations

import socket

from illumix.renderer_jobs.jobs import JobError, Plan, ProgressFn, _scene_payload, run_job

#: times Ray runs a task again after its worker or node died (system failures only)
MAX_RETRIES = 4


def _check_reachable(address: str | None, timeout: float = 5.0) -> None:
    """Fail fast on a ``HOST:PORT`` cluster address nobody listens at: ``ray.init`` would retry it
    without limit (measured: still retrying after 5 minutes)."""
    host, sep, port = (address or "").rpartition(":")
    if not sep or not host or not port.isdigit() or "://" in address:
        return  # "auto", "ray://…" or no address: Ray's own resolution
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as exc:
        raise JobError(f"cannot reach the Ray cluster at {address}: {exc.strerror or exc}; start its head "
                       f"(`ray start --head --node-ip-address {host} --port {port}`) or give the right --address")


def _run_on_node(*args) -> dict:
    """:func:`run_job`, its summary naming the node that ran it."""
    import ray

    return {**run_job(*args), "node": ray.util.get_node_ip_address()}


def run_ray(plan_: Plan, store_path: str, settings_dict: dict, address: str | None,
             on_done: ProgressFn, ray_init: dict | None = None, overwrite: bool = False) -> list[dict]:
    try:
        import ray
    except ImportError:
        raise JobError("the ray executor needs Ray: pip install 'illumix[ray]'") from None
    if not ray.is_initialized():
        _check_reachable(address)
        try:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False, **(ray_init or {}))
        except Exception as exc:  # ConnectionError, or ValueError for a malformed address
            where = f"at {address}" if address else "(no --address: a new local instance)"
            raise JobError(f"cannot start or reach the Ray cluster {where}: {type(exc).__name__}: {exc}") from None
    # One CPU per task and a one-thread Dr.Jit pool in it: Ray packs as many tasks as a node has cores.
    # A task whose node is lost is run again elsewhere (MAX_RETRIES); run_job skips a cube that its
    # lost attempt had already published, so no cube is written twice.
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=False)(_run_on_node)
    payloads = {n: ray.put(_scene_payload(s)) for n, s in plan_.scenes.items()}
    results: list[dict] = []
    for phase in (plan_.view_jobs, plan_.cube_jobs):
        refs = {remote.remote(payloads[j.scene], j, store_path, settings_dict, 1, overwrite): j
                for j in phase}
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1)
            for ref in done:
                job = refs.pop(ref)
                try:
                    r = ray.get(ref)
                except Exception as exc:
                    on_done(job, None, exc)
                    for other in refs:
                        ray.cancel(other)
                    raise JobError(f"{job.label}: {exc}") from exc
                results.append(r)
                on_done(job, r, None)
    return results
