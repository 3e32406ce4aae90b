"""Loads and support motions as functions of time.

A :class:`DynamicLoad` adds ``f(t) * pattern`` to the dead node forces; a
:class:`SupportMotion` moves a supported tube node by ``f(t) * displacement``.
``f`` is a time function: :class:`StepFunction`, :class:`RampFunction`,
:class:`HarmonicFunction` or :class:`TableFunction` (dimensionless factors of time [s]).
The static loads of the parameters act throughout.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from .._structure.structure import Structure, StructureParameters


class AbstractTimeFunction(eqx.Module):
    """A dimensionless factor of time ``f(t)``; ``t`` [s], any shape."""

    @abc.abstractmethod
    def __call__(self, time: Array) -> Array:
        raise NotImplementedError


class StepFunction(AbstractTimeFunction):
    """``0`` before ``start`` [s], ``1`` from it on (a sudden load)."""

    start: Array = eqx.field(default=0.0, converter=jnp.asarray)

    def __call__(self, time):
        return jnp.where(time >= self.start, 1.0, 0.0)


class RampFunction(AbstractTimeFunction):
    """``0`` before ``start``, rising linearly to ``1`` over ``duration`` [s], then ``1``."""

    start: Array = eqx.field(default=0.0, converter=jnp.asarray)
    duration: Array = eqx.field(default=1.0, converter=jnp.asarray)

    def __call__(self, time):
        return jnp.clip((time - self.start) / self.duration, 0.0, 1.0)


class HarmonicFunction(AbstractTimeFunction):
    """``sin(2 pi frequency t + phase)``; ``frequency`` [Hz], ``phase`` [rad]."""

    frequency: Array = eqx.field(converter=jnp.asarray)
    phase: Array = eqx.field(default=0.0, converter=jnp.asarray)

    def __call__(self, time):
        return jnp.sin(2.0 * jnp.pi * self.frequency * time + self.phase)


class TableFunction(AbstractTimeFunction):
    """Linear interpolation in a table ``times [K]`` [s] (increasing), ``values [K]``; held
    constant outside it."""

    times: Array = eqx.field(converter=jnp.asarray)
    values: Array = eqx.field(converter=jnp.asarray)

    def __call__(self, time):
        return jnp.interp(time, self.times, self.values)


class DynamicLoad(eqx.Module):
    """Dead node forces ``f(t) * node_force`` [N], ``node_force [N, 3]`` over the tube
    nodes (as ``StructureParameters.node_force``)."""

    node_force: Array
    time_function: AbstractTimeFunction


class SupportMotion(eqx.Module):
    """A support (tube node of a support) moved by ``f(t) * displacement`` [m], ``[3]``.
    ``node`` is its global index (``Structure.node_id``)."""

    node: int = eqx.field(static=True)
    displacement: Array
    time_function: AbstractTimeFunction


def dynamic_load(structure: Structure, params: StructureParameters, forces: dict,
                 time_function: AbstractTimeFunction) -> DynamicLoad:
    """A :class:`DynamicLoad` from ``{"tube:index": [Fx, Fy, Fz], ...}`` [N]."""
    pattern = jnp.zeros_like(params.node_force)
    for ref, force in forces.items():
        pattern = pattern.at[structure.node_id(ref)].add(jnp.asarray(force, float))
    return DynamicLoad(node_force=pattern, time_function=time_function)


def parameters_at(params: StructureParameters, loads: tuple, motions: tuple,
                  time: Array) -> StructureParameters:
    """The parameters at ``time`` [s]: the dynamic loads added to the node forces and the
    support motions to the supported nodes' positions (which only the support constraints
    read; the reference geometry stays that of ``params``)."""
    force = params.node_force
    for load in loads:
        force = force + load.time_function(time) * load.node_force
    position = params.node_position
    for motion in motions:
        position = position.at[motion.node].add(motion.time_function(time) * motion.displacement)
    return eqx.tree_at(lambda p: (p.node_force, p.node_position), params, (force, position))
