"""Physical effects that a pure bending-spring model lacks (docs/physics.md, section 5).

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
docs/guides/effects.md for a worked example.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

import jaxtube as jt

from .._user_files import import_user_file


@dataclasses.dataclass(frozen=True)
class EffectParameter:
    """One effect parameter: ``name`` (the field), ``unit``, ``null`` (effect vanishes),
    ``lower``/``upper`` bounds and a ``typical`` value (a physically typical size: where
    :func:`fitting.fit` starts the parameter, the diagnosis' second starting point, and by
    its magnitude a scale); ``plausible``: the range ``(low, high)``
    the parameter takes in real rigs and tubes (None: no range is known), and
    ``plausible_source``: where that range comes from. The diagnosis does not name an effect
    whose fitted size falls outside it."""

    name: str
    unit: str
    null: float
    lower: float
    upper: float
    typical: float
    plausible: tuple[float, float] | None = None
    plausible_source: str = ""


@dataclasses.dataclass(frozen=True)
class RigSpecimen:
    """What an effect sees of the rig and specimen (numbers may be traced).

    pressure [Pa], radius [m], length [m]; ``tube``: index of the specimen tube in the
    structure's tubes; ``clamp``: index of the clamp-spring tube or None; ``clamp_length``:
    that tube's length [m] (its joint's tributary length is half of it); ``tip_node``: the
    global index of the loaded tip node; ``gravity``: [3] m/s^2; ``reference_pressure``
    [Pa], ``reference_radius`` [m]: the specimen at which the fitted pivot coordinates are
    referenced (the data's geometric mean; None outside a fit).
    """

    pressure: object
    radius: object
    length: object
    tube: int
    clamp: int | None
    clamp_length: object
    tip_node: int = -1
    gravity: object = (0.0, 0.0, -9.81)
    reference_pressure: object = None
    reference_radius: object = None


class Effect(eqx.Module):
    """Base class of effects. Subclasses define fields (the parameters), the class
    attributes ``name``, ``parameters`` and optionally ``features``, ``kind``,
    ``separated_by`` and ``signature``, and :meth:`apply`.

    Class attributes:
        name: how the diagnosis reports it.
        parameters: :class:`EffectParameter` per field, in order.
        features: rig degrees of freedom it needs (``"shear"``, ``"clamp_spring"``).
        kind: ``"physical"`` (a physical effect) or ``"model_structure"`` (an extension of
            the law's form, such as ``radius_scaling``; such an effect also defines
            :meth:`law_for_every_specimen`).
        forms: the pivot scaling forms (``"paper"``, ``"separate"``) it acts on.
        separated_by: specimen quantities (``"pressure"``, ``"radius"``, ``"length"``) along
            which this effect's signature differs from the bending law's: data that vary
            them tell it apart. The diagnosis names them when the effect is confounded.
        signature: one sentence on how the effect shows in force-deflection curves.
        loads_at_rest: whether the effect can load the specimen before the test load (a
            weight): the rig then solves the specimen's unloaded shape and measures the
            deflections from it (:meth:`fitting._bench.rig.CantileverRig.curve`). True
            unless the effect only changes stiffness or compliance, so that the unloaded
            specimen stays straight and the rig's program needs no unloaded solve.
    """

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[EffectParameter, ...]] = ()
    features: ClassVar[frozenset[str]] = frozenset()
    kind: ClassVar[str] = "physical"
    forms: ClassVar[tuple[str, ...]] = ("paper", "separate")
    separated_by: ClassVar[tuple[str, ...]] = ()
    signature: ClassVar[str] = ""
    loads_at_rest: ClassVar[bool] = True

    def apply(self, params: jt.StructureParameters,
              specimen: RigSpecimen) -> jt.StructureParameters:
        """The specimen's structure parameters with this effect included."""
        raise NotImplementedError

    def law_for_every_specimen(self, law: jt.SplineLaw, reference_radius: float
                               ) -> jt.SplineLaw:
        """A model-structure extension folded into ``law``: one law that is, at every
        pressure and radius, what :meth:`apply` makes of ``law`` there (``reference_radius``
        [m]: the fit's). Physical effects are not part of the law and do not define it."""
        raise NotImplementedError(f"{self.name} is not part of the bending law")

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
        EffectParameter(
            "stiffness", "N m^2", 0.0, 0.0, 1e4, 10.0, plausible=(0.0, 500.0),
            plausible_source="a seam or tape strip of width w at the extreme fibre adds "
            "about 2 E t w r^2: 1-100 N m^2 for fabric E t ~ 150 kN/m, w = 1-5 cm and "
            "r = 50-150 mm; 500 N m^2 would be a stiff batten, not a seam"),)
    separated_by: ClassVar[tuple[str, ...]] = ("pressure", "radius")
    signature: ClassVar[str] = ("stiffness that does not grow with p r^3: relatively larger at "
                                "low pressure and small radius, delays wrinkling")
    loads_at_rest: ClassVar[bool] = False
    stiffness: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        law = jt.ReinforcedLaw(params.bending_laws[specimen.tube], self.stiffness)
        return eqx.tree_at(lambda p: p.bending_laws, params,
                           _replace_tube_law(params.bending_laws, specimen.tube, law))


class SelfWeight(Effect):
    """Self-weight of the tube, a distributed dead load (gravity along -z)."""

    name: ClassVar[str] = "self_weight"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter(
            "mass_per_length", "kg/m", 0.0, 0.0, 50.0, 0.3, plausible=(0.0, 1.5),
            plausible_source="kite leading-edge tubes and struts weigh about 0.05-0.5 kg/m "
            "(fabric ~ 0.1-0.2 kg/m^2 over 2 pi r plus bladder and seams); coated "
            "inflatable-beam fabrics (~ 0.5-1 kg/m^2) reach about 1.5 kg/m at r = 0.2 m"),)
    separated_by: ClassVar[tuple[str, ...]] = ("length", "pressure")
    signature: ClassVar[str] = ("a root moment w g L^2 / 2 already there at zero load: early "
                                "wrinkling of long, low-pressure tubes")
    mass_per_length: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        mass = params.mass_per_length.at[specimen.tube].set(self.mass_per_length)
        return eqx.tree_at(lambda p: p.mass_per_length, params, mass)


class ClampCompliance(Effect):
    """A rotational spring between the rig's clamp and the tube root."""

    name: ClassVar[str] = "clamp_compliance"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter(
            "compliance", "rad/(N m)", 0.0, 0.0, 1.0, 1e-4, plausible=(0.0, 5e-3),
            plausible_source="bench clamps of inflated tubes (a collar or strap around the "
            "fabric) rotate by well under a degree per 10 N m: rotational stiffness above "
            "about 200 N m/rad"),)
    features: ClassVar[frozenset[str]] = frozenset({"clamp_spring"})
    separated_by: ClassVar[tuple[str, ...]] = ("length",)
    signature: ClassVar[str] = ("a deflection c P L^2 that grows like L^2, not L^3, and stays "
                                "linear while the tube wrinkles")
    loads_at_rest: ClassVar[bool] = False
    compliance: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        return set_clamp_compliance(params, specimen, self.compliance)


class Shear(Effect):
    """Fichter shear deformation, ``S = p pi r^2 + r / u`` with ``u = 1 / (2 pi k G t)``."""

    name: ClassVar[str] = "shear"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter(
            "flexibility", "m/N", 0.0, 0.0, 1.0, 1e-4, plausible=(0.0, 1e-3),
            plausible_source="u = 1 / (2 pi k G t) with k ~ 0.5 and woven-fabric in-plane "
            "shear stiffness G t of about 0.3-100 kN/m (bias-free woven cloth is soft in "
            "shear; coated airbeam fabrics are stiffer)"),)
    features: ClassVar[frozenset[str]] = frozenset({"shear"})
    separated_by: ClassVar[tuple[str, ...]] = ("length", "pressure")
    signature: ClassVar[str] = ("a compliance L / (p pi r^2 + k G A) that grows like L, not "
                                "L^3: relatively larger for short tubes at low pressure")
    loads_at_rest: ClassVar[bool] = False
    flexibility: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        return set_shear_flexibility(params, self.flexibility)


class RadiusScaling(Effect):
    """Model-structure extension: the pivots' radius exponent freed from the paper's ``3 B``.

    The paper's scaling ``y_i = A_i (p r^3)^B_i`` ties the radius exponent of every pivot
    to three times its pressure exponent. The separate form ``y_i = A_i p^B_i r^C_i``
    frees it (the tension-field tube, for instance, has curvature pivots
    ``kappa_w = p / (2 E t)`` independent of r: ``C = 0``, ``B = 1``). This candidate
    nests the paper form in the separate form with one extra exponent per coordinate,
    ``C_i = 3 B_i + D`` (``D_kappa`` for every curvature pivot, ``D_M`` for every moment
    pivot; null 0 is the paper form): each pivot increment is multiplied by
    ``(r / r_ref)^D`` at the specimen radius ``r`` (``r_ref`` the fit's reference radius,
    so ``D`` does not move the pivots at the reference specimen). Per-pivot ``C_i`` is
    ``--form separate``. Acts on a :class:`jaxtube.SplineLaw` of the paper form.
    Typical sizes: ``D_kappa = -3`` (the tension-field tube's wrinkling curvature
    ``p / (2 E t)``, ``B = 1`` and no r), ``D_M`` small (its moments scale as ``p r^3``).
    """

    name: ClassVar[str] = "radius_scaling"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("curvature_radius_excess", "-", 0.0, -4.0, 4.0, -3.0),
        EffectParameter("moment_radius_excess", "-", 0.0, -4.0, 4.0, 0.1))
    kind: ClassVar[str] = "model_structure"
    forms: ClassVar[tuple[str, ...]] = ("paper",)
    separated_by: ClassVar[tuple[str, ...]] = ("radius",)
    signature: ClassVar[str] = ("pivots that scale with the radius differently from (p r^3)^B: "
                                "curves at different radii misfit in opposite directions")
    loads_at_rest: ClassVar[bool] = False
    curvature_radius_excess: jnp.ndarray = eqx.field(converter=jnp.asarray)
    moment_radius_excess: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        law = params.bending_laws[specimen.tube]
        if not isinstance(law, jt.SplineLaw) or law.curvature_radius_exponent is not None:
            raise TypeError("radius_scaling acts on a paper-form SplineLaw, got "
                            f"{type(law).__name__}")
        if specimen.reference_radius is None:
            raise ValueError("radius_scaling needs the fit's reference radius")
        ratio = specimen.radius / specimen.reference_radius
        law = eqx.tree_at(lambda old: (old.curvature_scale, old.moment_scale), law,
                          (law.curvature_scale * ratio**self.curvature_radius_excess,
                           law.moment_scale * ratio**self.moment_radius_excess))
        return eqx.tree_at(lambda p: p.bending_laws, params,
                           _replace_tube_law(params.bending_laws, specimen.tube, law))

    def law_for_every_specimen(self, law, reference_radius):
        """The separate form: increments ``A_i (p r^3)^B_i (r / r_ref)^D`` are
        ``(A_i r_ref^-D) p^B_i r^(3 B_i + D)``."""
        if law.curvature_radius_exponent is not None:
            raise ValueError("radius_scaling acts on a paper-form SplineLaw")
        return jt.SplineLaw(
            curvature_scale=law.curvature_scale * reference_radius**-self.curvature_radius_excess,
            curvature_exponent=law.curvature_exponent,
            curvature_radius_exponent=3.0 * law.curvature_exponent
            + self.curvature_radius_excess,
            moment_scale=law.moment_scale * reference_radius**-self.moment_radius_excess,
            moment_exponent=law.moment_exponent,
            moment_radius_exponent=3.0 * law.moment_exponent + self.moment_radius_excess,
            residual_stiffness_ratio=law.residual_stiffness_ratio,
            linear_share=law.linear_share, pivots_per_regime=law.pivots_per_regime)


class UnwrinkledLinearity(Effect):
    """Model-structure extension: the unwrinkled regime linear up to near the onset.

    With one pivot in the unwrinkled regime, the spline's first piece is the odd cubic
    ``M = a k + b k^3``, which bends over its whole range. A membrane tube is linear until
    it wrinkles (``EI = pi E t r^3`` up to ``kappa_w``; docs/physics.md, sections 1.1 and
    2.3), then softens at once. The law's ``linear_share`` ``s`` keeps it linear up to
    ``s k_1`` and bends it only on ``[s k_1, k_1]`` (:class:`jaxtube.SplineLaw`); null 0 is
    the paper's spline. ``s`` is dimensionless, so a self-similar tube (the tension-field
    tube's shape in ``kappa / kappa_w``, ``M / M_w`` is the same at every pressure and
    radius) has one ``s``. Typical size 0.8 (a tube that stays linear to near the
    onset); the bound 0.95 keeps the bend from becoming a kink.
    """

    name: ClassVar[str] = "unwrinkled_linearity"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("linear_share", "-", 0.0, 0.0, 0.95, 0.8),)
    kind: ClassVar[str] = "model_structure"
    signature: ClassVar[str] = ("curves straighter than the model at first, then softening "
                                "more abruptly near the wrinkling onset, at every pressure "
                                "and radius alike")
    loads_at_rest: ClassVar[bool] = False
    linear_share: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        law = params.bending_laws[specimen.tube]
        if not isinstance(law, jt.SplineLaw):
            raise TypeError(f"unwrinkled_linearity acts on a SplineLaw, got {type(law).__name__}")
        return eqx.tree_at(lambda p: p.bending_laws, params,
                           _replace_tube_law(params.bending_laws, specimen.tube,
                                             self.law_for_every_specimen(law, None)))

    def law_for_every_specimen(self, law, reference_radius):
        """The share is the same at every specimen (dimensionless)."""
        return eqx.tree_at(lambda old: old.linear_share, law,
                           jnp.broadcast_to(self.linear_share, law.linear_share.shape))


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

#: Candidates of the diagnosis besides the physical effects (model-structure extensions).
MODEL_EXTENSIONS: dict[str, type[Effect]] = {
    cls.name: cls for cls in (RadiusScaling, UnwrinkledLinearity)}


def resolve_effect(text: str) -> type[Effect]:
    """A built-in effect by name, or a user's ``path/to/file.py:ClassName`` (clear errors).

    A user's file is imported once per resolved path and class name, so the same effect
    named twice (the API and the CLI in one process) is the same class and the models built
    with it share their compilation."""
    if text in BUILT_IN_EFFECTS:
        return BUILT_IN_EFFECTS[text]
    if text in MODEL_EXTENSIONS:
        return MODEL_EXTENSIONS[text]
    path, sep, class_name = text.rpartition(":")
    if not sep or not path.endswith(".py"):
        raise ValueError(f"effect {text!r}: expected one of "
                         f"{sorted(BUILT_IN_EFFECTS) + sorted(MODEL_EXTENSIONS)} or "
                         "path/to/file.py:ClassName")
    file = Path(path)
    if not file.is_file():
        raise ValueError(f"effect {text!r}: file {file} not found")
    return _user_effect(str(file.resolve()), file.stat().st_mtime_ns, class_name)


@functools.lru_cache(maxsize=32)
def _user_effect(path: str, modified: int, class_name: str) -> type[Effect]:
    file = Path(path)
    text = f"{path}:{class_name}"
    cls = getattr(import_user_file(file, text), class_name, None)
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise ValueError(f"effect {text!r}: {file} has no Effect subclass {class_name!r}")
    if not cls.name or not cls.parameters:
        raise ValueError(f"effect {text!r}: {class_name} must set 'name' and 'parameters'")
    return cls
