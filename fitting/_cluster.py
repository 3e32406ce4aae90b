"""A Dask ``distributed`` client for work too large for one process: the diagnosis study's
designs (:func:`fitting.run_study`) and the sweep's grid (:func:`fitting.sweep_on_cluster`).

Dask is an optional dependency (the ``study`` extra, ``pip install '.[study]'``), imported
only when a cluster is asked for.
"""

from __future__ import annotations


def open_client(scheduler: str | None = None, workers: int = 1, processes: bool = True):
    """A :class:`distributed.Client`: on the scheduler at ``scheduler`` (an address such as
    ``tcp://host:8786``), else on a new :class:`distributed.LocalCluster` of ``workers``
    single-threaded workers (processes, or threads of this process when not
    ``processes``). Close it (it is a context manager) to stop a local cluster."""
    from distributed import Client, LocalCluster  # the study extra, loaded on use

    if scheduler is not None:
        return Client(scheduler)
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                           dashboard_address=":0")
    return Client(cluster)
