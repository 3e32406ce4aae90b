"""Many independent solves as one compiled program, split over devices: the batch that pays.

``jax.vmap`` of a Newton solve does not pay on a CPU: one Newton pass of a 20-segment tube
costs about the same per member batched as alone (204 us alone, 193-245 us per member in
batches of 64-256, ``experiments/profile_batch_pieces.py``), so a batch only adds the
lockstep of its members' while-loops (1,000 curves: 55-58 s batched, 33-39 s as a Python
loop of single curves, docs/performance.md). What does pay on a CPU is its cores: the
members split over devices (``jax.shard_map``, no communication between devices, each
running its own members to their own convergence) and, on each CPU device, solved one after
another inside the program (``jax.lax.map``: no dispatch per member, no lockstep). On other
devices (GPUs) each device's members are one ``vmap``, which fills their lanes.

Several CPU devices in one process come from XLA's flag
``--xla_force_host_platform_device_count=N`` in ``XLA_FLAGS``, set before JAX starts (see
docs/guides/solver.md, "Many solves at once"). One after another on CPU devices is also what
keeps jaxlib 0.10.2 from a deadlock: the batched LU of a ``vmap`` of dense-route solves
splits its batch over XLA's CPU thread pool and waits for the pieces, and when every pool
thread runs a device's program nothing runs them (found 2026-12-05 with ``gdb``:
``lapack_dgetrf_ffi`` -> ``ParallelBatchMap`` -> ``BlockingCounter::Wait`` on both pool
threads).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec


def each_member(fn: Callable, *args, sequential: bool | None = None):
    """``fn`` of each member along the leading axis of ``args``, inside a traced program:
    one after another (``jax.lax.map``) on a CPU, one ``vmap`` elsewhere (module docstring:
    a CPU gains nothing from a ``vmap`` of solves, and jaxlib 0.10.2 can deadlock in one).

    Args:
        fn: a function of one member's arguments. args: PyTrees of arrays ``[B, ...]``.
        sequential: one after another or not; ``None``: whether JAX's default backend is
            the CPU.

    Returns ``fn``'s outputs stacked over the members ``[B, ...]``."""
    if sequential is None:
        sequential = jax.default_backend() == "cpu"
    if sequential:
        return jax.lax.map(lambda member: fn(*member), args)
    return jax.vmap(fn)(*args)


def map_members(fn: Callable, devices=None) -> Callable:
    """``fn`` over the leading (member) axis of its arguments, as one jitted program.

    Args:
        fn: a function of PyTrees of arrays for one member (e.g. one ``jt.solve_path``);
            every leaf of every argument of the returned function carries the members on
            its leading axis ``[B, ...]``.
        devices: the devices to split the members over (default: all of
            ``jax.devices()``); one device runs them all.

    Returns:
        ``g(*args) -> outputs`` with every output leaf stacked over the members ``[B, ...]``,
        each member's result equal to ``fn`` of that member alone (one after another on CPU
        devices, a ``vmap`` per device elsewhere). With several devices the member count is
        padded to a multiple of theirs by repeating the last member (the padding is
        dropped). Each member reports its own convergence (a ``Solution``'s flags).
    """
    devices = tuple(jax.devices() if devices is None else devices)
    on_cpu = devices[0].platform == "cpu"

    def local(*args):
        return each_member(fn, *args, sequential=on_cpu)

    if len(devices) == 1:
        one = jax.jit(local)

        def run_on_one(*args):
            _member_count(args)
            return one(*args)

        return run_on_one
    mesh = Mesh(np.asarray(devices), ("members",))
    split = jax.jit(jax.shard_map(local, mesh=mesh, in_specs=PartitionSpec("members"),
                                  out_specs=PartitionSpec("members"), check_vma=False))
    sharding = NamedSharding(mesh, PartitionSpec("members"))

    def run(*args):
        count = _member_count(args)
        padded = -(-count // len(devices)) * len(devices)

        def pad(x):
            x = jnp.asarray(x)
            extra = jnp.repeat(x[-1:], padded - count, axis=0)
            return jax.device_put(jnp.concatenate([x, extra]), sharding)

        out = split(*jax.tree.map(pad, args))
        return jax.tree.map(lambda y: y[:count], out)

    return run


def _member_count(args) -> int:
    """The members' count, the leading axis every argument leaf shares; a clear error if
    there is none, it is empty, or the leaves disagree."""
    leaves = jax.tree.leaves(args)
    if not leaves or any(jnp.ndim(x) == 0 for x in leaves):
        raise ValueError("map_members: every argument needs a leading member axis [B, ...]; "
                         "got a scalar or no array.")
    counts = {jnp.shape(x)[0] for x in leaves}
    if len(counts) != 1:
        raise ValueError(f"map_members: the arguments' leading (member) axes differ: "
                         f"{sorted(counts)}.")
    count = counts.pop()
    if count == 0:
        raise ValueError("map_members: no members (the leading axis is empty).")
    return count
