"""A campaign's kite: imported per case with the model's values, its tube surfaces and canopy
for the markers, its line sets and measured lengths.

The structure is imported once per case (:func:`jaxtube.import_kite_fem`: the case's
pressure; every case has the same structure and parameter shapes), the case's loads are set
as dead forces on their nodes, and the model's values (:class:`KiteModel`) are put into the
parameters (:func:`with_model_values`): the bending law's factor (``law_form``: the
stiffness, or the whole curve, of Breukels' 2011 law scaled) and its collapse factor (the
wrinkling and collapse moments scaled), per tube class and for torsion, the pressure's
factor and offset, the rest lengths and stiffnesses of each named line set times their
factors, point masses at named points (dead loads) and the suspension points' offsets (the
fixed points' positions). Values are parameters, not structure: one compiled program serves
every value (:mod:`fitting._campaign.solve`). Factors are searched by their logarithm, masses and
offsets as they are (:func:`search_coordinates`).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .._shape.surfaces import TubeSurfaces
from .file import AXES, Campaign, CampaignCase
from .model import KiteModel


def line_set_rows(campaign: Campaign, name: str) -> np.ndarray:
    """Rows of the model's ``spring_matrix`` (= its lines, same order) of line set ``name``
    (every spring joining one of the set's node pairs), ``[k]`` int."""
    springs = np.sort(np.asarray(campaign.kite_fem.spring_nodes, dtype=np.int64), axis=1)
    wanted = {tuple(sorted(pair)) for pair in campaign.line_sets[name]}
    return np.flatnonzero([tuple(pair) in wanted for pair in springs.tolist()])


def tube_class_members(campaign: Campaign, tube_names, tube_class: str) -> np.ndarray:
    """``[T]`` bool: the tubes (named ``beams_<first>_<last>`` by
    :func:`jaxtube.import_kite_fem`) of tube class ``tube_class``: both end nodes on the
    beams of one of the class's ``[tubes]`` groups."""
    members = []
    for name in tube_names:
        ends = {int(n) for n in name.split("_")[1:]}
        members.append(any(ends <= {n for a, b, _ in campaign.tubes[group] for n in (a, b)}
                           for group in campaign.tube_classes[tube_class]))
    return np.asarray(members, bool)


PASCAL_PER_BAR = 1e5


def with_model_values(campaign: Campaign, params: jt.StructureParameters,
                      model: KiteModel, imported: jt.KiteFemImport | None = None
                      ) -> jt.StructureParameters:
    """``params`` with ``model``'s values: the bending, collapse and torsion factors on every
    tube's laws (the bending laws must be :func:`campaign_bending_law`'s, the torsion laws
    scaled laws: :func:`import_campaign_case`), every tube's pressure times the pressure
    factor plus the pressure offset, the rest lengths and stiffnesses of each line set times
    their factors, each named point's mass as a dead load along gravity and the suspension
    points moved by their offsets. ``imported`` (the kite these parameters are of) is needed
    for the values that act on named tubes or nodes: ``bending_class_factors``,
    ``point_masses_kg``, ``suspension_offsets_mm``. Every value enters differentiably
    (traced values welcome)."""
    needs_kite = [kind for kind in ("bending_class_factors", "point_masses_kg",
                                    "suspension_offsets_mm") if getattr(model, kind)]
    if needs_kite and imported is None:
        raise ValueError(f"with_model_values: {', '.join(needs_kite)} need the imported kite")
    count = len(params.bending_laws)
    bending = [model.bending_scale] * count
    for name, factor in model.bending_class_factors.items():
        for t in np.flatnonzero(tube_class_members(campaign, imported.tube_names, name)):
            bending[t] = bending[t] * factor
    laws = tuple(_bending_law_with(law, model.law_form, factor, model.collapse_scale)
                 for law, factor in zip(params.bending_laws, bending))
    torsion = tuple(eqx.tree_at(lambda law: law.factor, law, jnp.asarray(model.torsion_scale))
                    if isinstance(law, jt.ScaledLaw) else law for law in params.torsion_laws)
    params = eqx.tree_at(lambda p: (p.bending_laws, p.torsion_laws), params, (laws, torsion))
    params = eqx.tree_at(lambda p: p.pressure, params, params.pressure * model.pressure_factor
                         + model.pressure_offset_bar * PASCAL_PER_BAR)
    elements = params.elements
    for kind, values in (("line_rest_length", model.rest_length_factors),
                         ("line_stiffness", model.stiffness_factors)):
        array = getattr(elements, kind)
        for name, factor in values.items():
            in_set = np.zeros(array.shape, bool)
            in_set[line_set_rows(campaign, name)] = True
            array = array * jnp.where(in_set, factor, 1.0)  # differentiable in the factor
        elements = eqx.tree_at(lambda e, kind=kind: getattr(e, kind), elements, array)
    params = eqx.tree_at(lambda p: p.elements, params, elements)
    for point, mass in model.point_masses_kg.items():
        node = int(imported.node_index[campaign.points[point]])
        weight = mass * jnp.asarray(campaign.gravity)
        params = jt.with_node_dead_load(imported.structure, params, node,
                                        jt.node_dead_load(imported.structure, params, node)
                                        + weight)
    for member, offset in model.suspension_offsets_mm.items():
        node, _, axis = member.partition(".")
        row = suspension_point_row(imported, int(node))
        moved = params.elements.point_position.at[row, AXES.index(axis)].add(offset / 1000)
        params = eqx.tree_at(lambda p: p.elements.point_position, params, moved)
    return params


def campaign_bending_law() -> jt.ScaledLaw:
    """Breukels' 2011 bending law as every tube of a campaign's kite carries it:
    ``ScaledLaw(CurvatureScaledLaw(law, a), b)``, ``M(kappa) = b M_2011(a kappa)`` (factors
    1 here; :func:`with_model_values` sets them): one structure for both law forms and every
    value, so one compiled program serves them all."""
    return jt.ScaledLaw(jt.CurvatureScaledLaw(jt.EmpiricalBendingLaw2011(), 1.0), 1.0)


def _bending_law_with(law, law_form: str, bending, collapse):
    """``law`` (:func:`campaign_bending_law`) with bending factor ``s`` = ``bending`` and
    collapse factor ``c`` = ``collapse``: the initial stiffness ``s EI0`` in either form, the
    wrinkling and collapse moments ``c M_max`` (curvature form: ``M = c M(s kappa / c)``) or
    ``c s M_max`` (moment form: ``M = c s M(kappa / c)``). Traced factors welcome."""
    if law_form not in ("curvature", "moment"):
        raise ValueError(f"law_form: expected 'curvature' or 'moment', found {law_form!r}")
    outer, inner = ((collapse, bending / collapse) if law_form == "curvature"
                    else (bending * collapse, 1.0 / collapse))
    return eqx.tree_at(lambda law: (law.factor, law.base.factor), law,
                       (jnp.asarray(outer), jnp.asarray(inner)))


def suspension_point_row(imported: jt.KiteFemImport, node: int) -> int:
    """The row of suspension ``node`` (a fixed point of the imported kite) in
    ``params.elements.point_position``; ``ValueError`` if it is a tube node (held by a
    support at the tube's own node: its position is the tube's, not a value)."""
    index = int(imported.node_index[node])
    if index < imported.structure.node_count:
        raise ValueError(f"suspension node {node} lies on a tube: its position is not a model "
                         "value (only a suspension point off the tubes can be moved)")
    return index - imported.structure.node_count


#: The model's values per named member (a line set, tube class, point or suspension axis).
VALUE_KINDS = ("rest_length_factors", "stiffness_factors", "bending_class_factors",
               "point_masses_kg", "suspension_offsets_mm")
#: The model's values that act on the whole kite.
KITE_VALUES = ("bending_scale", "torsion_scale", "collapse_scale", "pressure_factor",
               "pressure_offset_bar")
#: Values that add to the model file's (null 0, searched as they are); the others are
#: factors on it (null 1, searched by their logarithm).
OFFSET_KINDS = ("pressure_offset_bar", "point_masses_kg", "suspension_offsets_mm")


def is_offset(name: str) -> bool:
    """Value ``name`` adds to the model file's (a mass, an offset) rather than scaling it."""
    return name.partition(".")[0] in OFFSET_KINDS


def search_coordinates(names, values) -> np.ndarray:
    """``[k]``: the coordinates fits search ``values`` of ``names`` in: the logarithm of a
    factor, an offset as it is."""
    return np.asarray([float(v) if is_offset(n) else np.log(float(v))
                       for n, v in zip(names, values)])


def values_from_search(names, theta):
    """The values of ``names`` at search coordinates ``theta`` ``[k]`` (NumPy or traced):
    the inverse of :func:`search_coordinates`."""
    xp = jnp if isinstance(theta, jax.Array) else np
    return xp.stack([theta[k] if is_offset(n) else xp.exp(theta[k])
                     for k, n in enumerate(names)])


def model_value(model: KiteModel, name: str) -> float:
    """One of ``model``'s values by name: one of :data:`KITE_VALUES`, or ``KIND.MEMBER`` with
    ``KIND`` one of :data:`VALUE_KINDS`: ``"rest_length_factors.SET"``,
    ``"stiffness_factors.SET"``, ``"bending_class_factors.CLASS"``,
    ``"point_masses_kg.POINT"``, ``"suspension_offsets_mm.NODE.AXIS"`` (a member without a
    value: its null, 1 for a factor and 0 for an offset)."""
    if name in KITE_VALUES:
        return getattr(model, name)
    kind, _, member = name.partition(".")
    if kind not in VALUE_KINDS or not member:
        raise ValueError(f"unknown model value {name!r} (expected one of "
                         f"{', '.join(KITE_VALUES)} or KIND.MEMBER with KIND one of "
                         f"{', '.join(VALUE_KINDS)})")
    return getattr(model, kind).get(member, 0.0 if is_offset(name) else 1.0)


def unknown_value_words(campaign: Campaign, name: str) -> str | None:
    """Why ``name`` is not one of ``campaign``'s model values (``None``: it is)."""
    kind, _, member = name.partition(".")
    members = campaign.members()
    if name in KITE_VALUES or member in members.get(kind, ()):
        return None
    members = "; ".join(f"{k}.{{{', '.join(names) or 'none'}}}"
                        for k, names in members.items())
    return f"unknown value {name!r} (expected {', '.join(KITE_VALUES)} or one of: {members})"


def with_values(model: KiteModel, names, values) -> KiteModel:
    """``model`` with its values ``names`` (:func:`model_value`) set to ``values`` (numbers
    or traced scalars)."""
    changed = {kind: dict(getattr(model, kind)) for kind in VALUE_KINDS}
    for k, name in enumerate(names):
        model_value(model, name)  # validates the name
        if name in KITE_VALUES:
            changed[name] = values[k]
        else:
            kind, _, member = name.partition(".")
            changed[kind][member] = values[k]
    return dataclasses.replace(model, **changed)


def import_campaign_case(campaign: Campaign, case: CampaignCase,
                         model: KiteModel) -> jt.KiteFemImport:
    """The campaign's kite at ``case``'s pressure with its loads and ``model``'s values."""
    law = campaign_bending_law()
    suspension = campaign.suspension
    # The importer's own V3 loads stay off (zero masses; its load nodes are set to a
    # suspension node so that they exist in any model): the case's loads follow.
    imported = jt.import_kite_fem(campaign.kite_fem, pressure_bar=case.pressure_bar,
                                  bending_law=law, suspension=suspension,
                                  gravity=campaign.gravity, centre_node=suspension[0],
                                  tip_nodes=(suspension[0], suspension[0]),
                                  torsion_law=jt.ScaledLaw(jt.EmpiricalTorsionLaw2011(), 1.0))
    params = imported.params
    forces: dict[int, np.ndarray] = {}
    for load in case.loads:
        node = int(imported.node_index[load.node])
        forces[node] = forces.get(node, np.zeros(3)) + load.force_N
    for node, force in forces.items():
        params = jt.with_node_dead_load(imported.structure, params, node, force)
    return dataclasses.replace(imported, params=with_model_values(campaign, params, model,
                                                                  imported))


def campaign_tube_surfaces(campaign: Campaign, positions=None) -> TubeSurfaces:
    """The marker groups' tubes (``[tubes]``: beams with half their diameter as radius) and
    the canopy triangles at kite positions ``[N, 3]`` [m] (default: the model file's)."""
    model = campaign.kite_fem
    rows = [(group, a, b, radius, radius) for group, segments in campaign.tubes.items()
            for a, b, radius in segments]
    if positions is None:
        positions = model.node_position
    return TubeSurfaces.from_segments(positions, rows, canopy_triangles(model))


def canopy_triangles(model: jt.KiteFemModel) -> np.ndarray:
    """``[t, 3]`` canopy triangles: the 3-cliques of canopy springs and beams. A canopy
    spring has both ends on tubes or on triangles of springs (the canopy is a mesh with
    diagonals; bridle lines form trees of lines and pulleys, without triangles)."""
    springs = np.asarray(model.spring_nodes, dtype=np.int64).tolist()
    beams = np.asarray(model.beam_nodes, dtype=np.int64).tolist()

    def neighbours_of(edges):
        neighbours: dict[int, set] = {}
        for a, b in edges:
            neighbours.setdefault(a, set()).add(b)
            neighbours.setdefault(b, set()).add(a)
        return neighbours

    linked = neighbours_of(springs)
    mesh = {n for edge in beams for n in edge}
    mesh |= {n for a, b in springs if linked[a] & linked[b] for n in (a, b)}
    edges = {tuple(sorted(e)) for e in beams}
    edges |= {tuple(sorted(e)) for e in springs if e[0] in mesh and e[1] in mesh}
    neighbours = neighbours_of(edges)
    triangles = {tuple(sorted((a, b, c))) for a, b in edges
                 for c in neighbours[a] & neighbours[b]}
    return np.asarray(sorted(triangles), int).reshape(-1, 3)


def campaign_lengths(campaign: Campaign, positions) -> dict:
    """``{length name: distance [m]}`` of ``[lengths.pairs]`` at kite positions ``[N, 3]``."""
    positions = np.asarray(positions, dtype=float)
    return {name: float(np.linalg.norm(positions[a] - positions[b]))
            for name, (a, b) in campaign.length_pairs.items()}
