"""A sweep over a Dask ``distributed`` cluster: the grid cut into contiguous blocks, each
swept by :func:`fitting.sweep` on a worker (with that worker's own devices), and put back
together in order (:func:`sweep_on_cluster`; the client: :func:`fitting.open_cluster_client`).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

import jaxtube as jt

from .._bench.rig import TubeModel
from .result import SweepResult, SweepSettings
from .sweep import checked_specimens, sweep

#: The per-point fields of a :class:`SweepResult` (the others are its settings).
POINT_FIELDS = tuple(f.name for f in dataclasses.fields(SweepResult)
                     if not f.metadata.get("static", False))


def sweep_on_cluster(client, law: jt.AbstractMomentLaw | TubeModel, pressure, radius, length,
                     tip_load, settings: SweepSettings = SweepSettings(),
                     blocks: int | None = None, progress: bool = False) -> SweepResult:
    """:func:`fitting.sweep` of the same arguments, its points cut into ``blocks`` contiguous
    blocks (default: one per worker of ``client``'s cluster) swept on the cluster's workers.

    The result is the one-process sweep's, point for point (each block is solved by the same
    compiled chunk program); ``devices`` counts the devices of every block, ``seconds`` is the
    wall time of the whole. A bad specimen raises ``ValueError`` as :func:`fitting.sweep`
    does, before anything is sent."""
    from distributed import as_completed  # the study extra, loaded on use

    arrays = checked_specimens(pressure, radius, length, tip_load)
    shape = arrays[0].shape
    flat = [a.reshape(-1) for a in arrays]
    count = flat[0].size
    blocks = min(blocks or len(client.scheduler_info()["workers"]) or 1, count)
    edges = np.linspace(0, count, blocks + 1).astype(int)
    started = time.perf_counter()
    futures = {client.submit(sweep, law, *(a[lo:hi] for a in flat), settings, pure=False): k
               for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:]))}
    parts: list = [None] * blocks
    bar = None
    if progress:
        from tqdm.auto import tqdm  # lazy: only a sweep that shows progress needs it

        bar = tqdm(total=blocks, desc=f"sweep ({count} points, {blocks} blocks)", unit="block")
    try:
        for future in as_completed(futures):
            parts[futures[future]] = future.result()
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    fields = {name: np.concatenate([getattr(p, name).reshape(-1) for p in parts]).reshape(shape)
              for name in POINT_FIELDS}
    return SweepResult(**fields, settings=settings, devices=sum(p.devices for p in parts),
                       seconds=time.perf_counter() - started, route=parts[0].route)
