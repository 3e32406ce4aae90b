"""Physical effects that a pure bending-spring model lacks (PHYSICS.md section 5).

An effect is a small immutable object (an ``equinox.Module``) whose fields are its
parameters. Each parameter has a *null value*, where the effect vanishes and the model is
exactly the model without it, and bounds. The class lists them in ``parameters``
(:class:`EffectParameter`). An effect acts on one specimen of a test rig through
:meth:`Effect.apply`, which receives the specimen's :class:`jaxtube.StructureParameters`
and returns modified ones: it may change the bending or torsion law, add loads or masses,
or switch on degrees of freedom the rig provides (``features``: ``"shear"`` adds a shear
strain to every segment, ``"clamp_spring"`` a rotational spring between the clamp and the
tube).

Built-in effects (names as the diagnosis reports them):

- ``shear`` (:class:`Shear`): Fichter shear deformation, section shear stiffness
  ``S = p pi r^2 + k G A`` (Fichter 1966; Le van & Wielgosz 2005); parameter the shear
  flexibility ``u = 1 / (2 pi k G t)`` [m/N], null 0 (rigid in shear).
- ``reinforcement`` (:class:`Reinforcement`): bending stiffness that does not depend on
  pressure, ``EI_r`` [N m^2] in parallel with the law (tape, seams); null 0.
- ``clamp_compliance`` (:class:`ClampCompliance`): rotational spring at the support,
  compliance ``c`` [rad/(N m)], null 0 (rigid clamp).
- ``self_weight`` (:class:`SelfWeight`): mass per length ``m`` [kg/m] under gravity, null 0;
  measured deflections stay zeroed at the unloaded (self-weighted) shape.

A new effect is a subclass with its fields, ``name``, ``parameters`` and ``apply``; see
the README for a worked example.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

import jaxtube as jt


@dataclasses.dataclass(frozen=True)
class EffectParameter:
    """One effect parameter: ``name`` (the field), ``unit``, ``null`` (effect vanishes),
    ``lower``/``upper`` bounds and a ``typical`` magnitude (a scale for the optimiser)."""

    name: str
    unit: str
    null: float
    lower: float
    upper: float
    typical: float


@dataclasses.dataclass(frozen=True)
class RigSpecimen:
    """What an effect sees of the rig and specimen (numbers may be traced).

    pressure [Pa], radius [m], length [m]; ``tube``: index of the specimen tube in the
    structure's tubes; ``clamp``: index of the clamp-spring tube or None; ``clamp_length``:
    that tube's length [m] (its joint's tributary length is half of it); ``tip_node``: the
    global index of the loaded tip node; ``gravity``: [3] m/s^2.
    """

    pressure: object
    radius: object
    length: object
    tube: int
    clamp: int | None
    clamp_length: object
    tip_node: int = -1
    gravity: object = (0.0, 0.0, -9.81)


class Effect(eqx.Module):
    """Base class of effects. Subclasses define fields (the parameters), the class
    attributes ``name``, ``parameters`` and optionally ``features``, and :meth:`apply`."""

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[EffectParameter, ...]] = ()
    features: ClassVar[frozenset[str]] = frozenset()

    def apply(self, params: jt.StructureParameters,
              specimen: RigSpecimen) -> jt.StructureParameters:
        """The specimen's structure parameters with this effect included."""
        raise NotImplementedError

    def values(self) -> dict[str, float]:
        return {p.name: getattr(self, p.name) for p in self.parameters}

    @classmethod
    def null(cls) -> Effect:
        """The effect at its null values (the model without it)."""
        return cls(**{p.name: p.null for p in cls.parameters})


def _replace_tube_law(laws: tuple, index: int, law) -> tuple:
    return tuple(law if i == index else old for i, old in enumerate(laws))


class Reinforcement(Effect):
    """Pressure-independent bending stiffness in parallel with the law."""

    name: ClassVar[str] = "reinforcement"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("stiffness", "N m^2", 0.0, 0.0, 1e4, 10.0),)
    stiffness: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        law = jt.ReinforcedLaw(params.bending_laws[specimen.tube], self.stiffness)
        return eqx.tree_at(lambda p: p.bending_laws, params,
                           _replace_tube_law(params.bending_laws, specimen.tube, law))


class SelfWeight(Effect):
    """Self-weight of the tube, a distributed dead load (gravity along -z)."""

    name: ClassVar[str] = "self_weight"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("mass_per_length", "kg/m", 0.0, 0.0, 50.0, 0.3),)
    mass_per_length: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        mass = params.mass_per_length.at[specimen.tube].set(self.mass_per_length)
        return eqx.tree_at(lambda p: p.mass_per_length, params, mass)


class ClampCompliance(Effect):
    """A rotational spring between the rig's clamp and the tube root."""

    name: ClassVar[str] = "clamp_compliance"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("compliance", "rad/(N m)", 0.0, 0.0, 1.0, 1e-4),)
    features: ClassVar[frozenset[str]] = frozenset({"clamp_spring"})
    compliance: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        return set_clamp_compliance(params, specimen, self.compliance)


class Shear(Effect):
    """Fichter shear deformation, ``S = p pi r^2 + r / u`` with ``u = 1 / (2 pi k G t)``."""

    name: ClassVar[str] = "shear"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("flexibility", "m/N", 0.0, 0.0, 1.0, 1e-4),)
    features: ClassVar[frozenset[str]] = frozenset({"shear"})
    flexibility: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        return set_shear_flexibility(params, self.flexibility)


# Rigid limits used when a rig provides a degree of freedom whose effect is at its null value:
# a compliance / flexibility this small changes forces by less than 1e-5 (relative; tested).
RIGID_CLAMP_COMPLIANCE = 1e-9  # rad/(N m)
RIGID_SHEAR_FLEXIBILITY = 1e-10  # m/N


def set_clamp_compliance(params, specimen: RigSpecimen, compliance):
    """Clamp-spring tube laws for a rotational compliance ``compliance`` [rad/(N m)]: a joint
    of tributary length ``l`` and law ``EI`` has rotational stiffness ``EI / l``."""
    tributary = 0.5 * specimen.clamp_length
    stiffness = tributary / (compliance + RIGID_CLAMP_COMPLIANCE)
    spring = jt.LinearLaw(stiffness)
    return eqx.tree_at(
        lambda p: (p.bending_laws, p.torsion_laws), params,
        (_replace_tube_law(params.bending_laws, specimen.clamp, spring),
         _replace_tube_law(params.torsion_laws, specimen.clamp, spring)))


def set_shear_flexibility(params, flexibility):
    value = jnp.full_like(params.shear_flexibility, flexibility + RIGID_SHEAR_FLEXIBILITY)
    return eqx.tree_at(lambda p: p.shear_flexibility, params, value)


BUILT_IN_EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls for cls in (Shear, Reinforcement, ClampCompliance, SelfWeight)}


def resolve_effect(text: str) -> type[Effect]:
    """A built-in effect by name, or a user's ``path/to/file.py:ClassName`` (clear errors)."""
    if text in BUILT_IN_EFFECTS:
        return BUILT_IN_EFFECTS[text]
    path, sep, class_name = text.rpartition(":")
    if not sep or not path.endswith(".py"):
        raise ValueError(f"effect {text!r}: expected one of {sorted(BUILT_IN_EFFECTS)} or "
                         "path/to/file.py:ClassName")
    import importlib.util
    from pathlib import Path

    file = Path(path)
    if not file.is_file():
        raise ValueError(f"effect {text!r}: file {file} not found")
    spec = importlib.util.spec_from_file_location(f"jaxtube_user_effect_{file.stem}", file)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as error:  # the user's file: report, do not crash
        raise ValueError(f"effect {text!r}: importing {file} failed: {error}") from error
    cls = getattr(module, class_name, None)
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise ValueError(f"effect {text!r}: {file} has no Effect subclass {class_name!r}")
    if not cls.name or not cls.parameters:
        raise ValueError(f"effect {text!r}: {class_name} must set 'name' and 'parameters'")
    return cls
