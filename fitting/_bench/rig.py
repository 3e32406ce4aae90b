"""The test rigs of measured data, as jaxtube models: predicted force at measured deflections.

A *rig* turns the specimen description of a measured curve (setup, pressure, radius,
length) into a jaxtube structure and a displacement-controlled load path, and predicts the
force at each measured deflection. All curves of one setup kind share one compiled
structure: the specimen numbers are parameters, so a whole data set is one program (on a
CPU its curves are solved one after another inside it, :meth:`CantileverRig.predict`).

``cantilever_tip`` (the bench test of Breukels & Ockels 2008): a straight tube along +x,
clamped at the root, its tip driven straight down (``-z``) by ``deflection`` from the
unloaded shape; the predicted force is the actuator's reaction along the drive direction,
i.e. the dead vertical tip load that holds the tip there (positive downwards). Displacement
control follows the collapse plateau, where force control fails.

Each curve is solved as one continuation path (``lax.scan``) through its deflections in
order of increasing magnitude; curves of different lengths are padded by repeating their
last deflection (padding carries zero weight and costs almost nothing: the solver is
already converged there).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .._data import MeasuredData
from .effects import RigSpecimen, set_clamp_compliance, set_shear_flexibility

#: Segments per tube in the calibration model. With the half-tributary clamp joint a
#: 12-segment chain is within about 0.1 % of the elastica tip deflection
#: (tests/test_beam_references.py checks the convergence); well below measurement noise.
DEFAULT_SEGMENTS = 12

DOWN = np.array([0.0, 0.0, -1.0])


class TubeModel(eqx.Module):
    """What a calibration fits: the laws of the tube and the effects (``fitting._bench.effects``).

    Attributes:
        bending_law: moment-curvature law of bending (any :class:`jaxtube.AbstractMomentLaw`).
        torsion_law: law of torsion (a cantilever with a vertical tip load does not twist).
        effects: tuple of :class:`fitting.Effect` instances, applied in order.
        reference: ``(pressure [Pa], radius [m])`` at which the fitted coordinates are
            referenced (effects such as ``radius_scaling`` see it), or None.
    """

    bending_law: jt.AbstractMomentLaw
    torsion_law: jt.AbstractMomentLaw = jt.LinearLaw(1.0)
    effects: tuple = ()
    reference: tuple | None = None


class CurveBatch(NamedTuple):
    """Measured curves as padded arrays, in continuation order. ``C`` curves, ``P`` points.

    pressure, radius, length: ``[C]`` [Pa, m, m]. deflection, force: ``[C, P]`` [m, N].
    weight: ``[C, P]`` (0 on padding). order: ``[C, P]`` index of each padded point in its
    curve's original point order (-1 on padding).
    """

    pressure: np.ndarray
    radius: np.ndarray
    length: np.ndarray
    deflection: np.ndarray
    force: np.ndarray
    weight: np.ndarray
    order: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        return self.order >= 0


def batch_curves(data: MeasuredData) -> CurveBatch:
    """Pad ``data``'s curves into a :class:`CurveBatch` (each curve ordered by |deflection|)."""
    kinds = {curve.setup_kind for curve in data}
    unsupported = kinds - {"cantilever_tip"}
    if unsupported:
        raise ValueError(f"{data.source}: setup kind(s) {sorted(unsupported)} cannot be fitted "
                         "yet; the calibration models 'cantilever_tip'.")
    width = max(curve.point_count for curve in data)
    count = len(data)
    deflection = np.zeros((count, width))
    force = np.zeros((count, width))
    weight = np.zeros((count, width))
    order = np.full((count, width), -1, dtype=np.int64)
    for c, curve in enumerate(data):
        idx = np.argsort(np.abs(curve.deflection), kind="stable")
        n = idx.size
        deflection[c, :n] = curve.deflection[idx]
        deflection[c, n:] = curve.deflection[idx[-1]]
        force[c, :n] = curve.force[idx]
        weight[c, :n] = curve.weight[idx]
        order[c, :n] = idx
    return CurveBatch(
        pressure=np.array([c.pressure for c in data]), radius=np.array([c.radius for c in data]),
        length=np.array([c.length for c in data]),
        deflection=deflection, force=force, weight=weight, order=order,
    )


def unpad(batch: CurveBatch, values: np.ndarray) -> list[np.ndarray]:
    """Per-curve arrays in each curve's original point order from padded ``[C, P, ...]``."""
    values = np.asarray(values)
    out = []
    for c in range(batch.order.shape[0]):
        keep = batch.order[c] >= 0
        curve_values = np.empty_like(values[c][keep])
        curve_values[batch.order[c][keep]] = values[c][keep]
        out.append(curve_values)
    return out


class RigPrediction(eqx.Module):
    """Model response at every padded point, ``[C, P]`` unless noted.

    force [N] (along the drive, positive downwards); converged (bool); iterations;
    joint_regime ``[C, P, J]`` (0 unwrinkled, 1 wrinkled, 2 collapsed; joint 0 is the
    clamp); joint_position ``[C, P, J]``: each joint's arc-length position over the length
    (0 at the clamp, 1 at the tip).
    """

    force: jax.Array
    converged: jax.Array
    iterations: jax.Array
    joint_regime: jax.Array
    joint_position: jax.Array


# Length of the clamp-spring tube, as a fraction of the specimen length (it lies behind the
# clamp, so the specimen keeps its length; its joint's tributary length is half of it).
CLAMP_FRACTION = 1e-3


@functools.lru_cache(maxsize=16)
def _unit_cantilever(segments: int, features: frozenset):
    """Unit-length rig: the specimen tube along +x from the origin (tube 0), and with
    ``"clamp_spring"`` a one-segment tube behind it, clamped at its far end and rigidly
    joined to the specimen root (tube 1). ``"shear"`` gives every segment shear strains."""
    unknown = set(features) - {"shear", "clamp_spring"}
    if unknown:
        raise ValueError(f"unknown rig features {sorted(unknown)}")
    shear = 1.0 if "shear" in features else None
    with jax.ensure_compile_time_eval():  # concrete arrays even when first built under jit
        spring = jt.LinearLaw(1.0)
        tube = jt.straight_tube("tube", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), segments, 1.0, 1.0,
                                spring, torsion_law=spring, shear_flexibility=shear)
        if "clamp_spring" not in features:
            return jt.build_structure([tube], [jt.Support("tube:0", "clamped")])
        clamp = jt.straight_tube("clamp", (-CLAMP_FRACTION, 0.0, 0.0), (0.0, 0.0, 0.0), 1,
                                 1.0, 1.0, spring, torsion_law=spring,
                                 shear_flexibility=shear)
        return jt.build_structure([tube, clamp], [jt.Support("clamp:0", "clamped")],
                                  [jt.Connection("clamp:end", "tube:0", "rigid")])


@dataclasses.dataclass(frozen=True)
class CantileverRig:
    """The ``cantilever_tip`` bench as a jaxtube model with ``segments`` rigid segments.

    The structure is built once at unit length, radius and pressure; :meth:`predict` sets
    the specimen numbers per curve as parameters, so one compilation serves every curve.
    """

    segments: int = DEFAULT_SEGMENTS
    solver: jt.NewtonKKT = jt.NewtonKKT()
    features: frozenset = frozenset()

    def template(self):
        """The unit rig (structure, parameters), built once per segment count and features."""
        return _unit_cantilever(self.segments, frozenset(self.features))

    def specimen_parameters(self, model: TubeModel, pressure, radius, length):
        """:class:`jaxtube.StructureParameters` of one specimen with the model's laws and
        effects (traceable in all numbers)."""
        structure, params = self.template()
        tubes = len(structure.tube_names)
        params = eqx.tree_at(
            lambda p: (p.node_position, p.node_radius, p.pressure, p.bending_laws,
                       p.torsion_laws),
            params,
            (params.node_position * length, jnp.full_like(params.node_radius, radius),
             jnp.full_like(params.pressure, pressure), (model.bending_law,) * tubes,
             (model.torsion_law,) * tubes),
        )
        clamp = structure.tube_names.index("clamp") if "clamp" in structure.tube_names else None
        reference = (None, None) if model.reference is None else model.reference
        specimen = RigSpecimen(pressure, radius, length, tube=0, clamp=clamp,
                               clamp_length=CLAMP_FRACTION * length,
                               tip_node=structure.node_id("tube:end"), gravity=params.gravity,
                               reference_pressure=reference[0], reference_radius=reference[1])
        if clamp is not None:  # rigid until an effect says otherwise
            params = set_clamp_compliance(params, specimen, 0.0)
        if "shear" in self.features:
            params = set_shear_flexibility(params, 0.0)
        for effect in model.effects:
            missing = set(effect.features) - set(self.features)
            if missing:
                raise ValueError(f"effect {effect.name!r} needs a rig with features "
                                 f"{sorted(missing)}")
            params = effect.apply(params, specimen)
        return params

    def curve(self, model: TubeModel, pressure, radius, length, deflection) -> RigPrediction:
        """Force along one continuation path of tip deflections ``[P]`` [m]."""
        structure, _ = self.template()
        params = self.specimen_parameters(model, pressure, radius, length)
        tip = structure.node_id("tube:end")
        # Deflections are measured from the unloaded shape: the sag under a weight (one
        # cheap solve) is added to each prescribed deflection. Without an effect that loads
        # the specimen at rest, the unloaded specimen is the straight template (no sag) and
        # the program needs no unloaded solve (a third of its size).
        path, unloaded_converged = jt.DisplacementControl(tip, DOWN, deflection), True
        if any(effect.loads_at_rest for effect in model.effects):
            unloaded = jt.equilibrium(structure, params, solver=self.solver)
            sag = jnp.dot(unloaded.node_position[tip] - params.node_position[tip], DOWN)
            path = jt.DisplacementControl(tip, DOWN, deflection + sag)
            unloaded_converged = unloaded.converged
        sol = jt.solve_path(structure, params, path, self.solver)
        sol = eqx.tree_at(lambda s: s.converged, sol, sol.converged & unloaded_converged)
        # Each spring joint's arc-length position from the unit template (the specimen runs
        # along +x from 0 to 1; the clamp-spring tube lies behind the clamp, at 0).
        _, unit = self.template()
        x = np.clip(np.asarray(unit.node_position)[:, 0], 0.0, 1.0)
        joints = x[np.asarray(structure.spring_joint_topology().node, int)]
        position = jnp.broadcast_to(jnp.asarray(joints, float), sol.joint_regime.shape)
        return RigPrediction(force=sol.control_force, converged=sol.converged,
                             iterations=sol.iterations, joint_regime=sol.joint_regime,
                             joint_position=position)

    def predict(self, model: TubeModel, pressure, radius, length, deflection) -> RigPrediction:
        """All curves in one program: ``pressure, radius, length [C]``, ``deflection [C, P]``.

        On a CPU the curves are solved one after another, elsewhere as one ``vmap``
        (``jaxtube.each_member``). A ``vmap`` does not pay on a CPU (README, "Many solves at
        once"), and its curves wait for each other at every point: one residual-and-Jacobian
        evaluation of a 6 x 14 design took 59-72 ms one after another against 83-94 ms as a
        ``vmap`` (2026-12-05, alternating processes, the same residuals and Jacobian to 12
        digits).
        """
        args = (jnp.asarray(x, float) for x in (pressure, radius, length, deflection))
        return jt.each_member(lambda *curve: self.curve(model, *curve), *args)
