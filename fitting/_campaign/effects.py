"""Candidate effects for a kite's shape: named groups of model values, each value with the
range it plausibly takes.

An effect (:class:`ShapeEffect`) names the model values (:func:`fitting.model_value`) it
frees and, for each, its plausible range: a factor on the model file's value, or for a
mass or an offset (:func:`fitting.is_offset`) the added amount in the value's unit. The diagnosis
(:mod:`fitting._campaign.diagnose`) fits an effect's values within that range; an effect
whose fit ends on an edge of its range is not named (the data want it beyond what is
physical: something else is missing), as the curve diagnosis does not name an effect whose
fitted size falls outside its plausible range.

Built-in effects (:func:`shape_effects`; ``SET``: each of the campaign's ``[line_sets]``):

- ``bending``: the bending law's factor (``bending_scale``; in the law form of the model:
  whole curve, or stiffness with the wrinkling and collapse moments kept), 0.05-5: tube
  stiffness measured on leading edges and struts spans about a factor of ten either side of
  Breukels' 2011 fit (Breukels 2011, ch. 3; the V3 calibration finds 0.27);
- ``torsion``: the torsion law's factor (``torsion_scale``), 0.1-10;
- ``collapse``: the bending law's wrinkling and collapse moments scaled, its stiffness kept
  (``collapse_scale``), 0.2-5: Comer & Levy's membrane collapse moment ``pi p r^3`` is
  0.2-0.75 of Breukels' 2011 plateau for the V3 tubes at 0.15 bar (r 0.04-0.10 m) and
  0.3-1.0 at 0.25 bar; seams and Dacron reinforcement raise it;
- ``pressure``: an offset on every case's stated overpressure (``pressure_offset_bar``),
  -0.03 to +0.03 bar: a hand gauge's zero error and the tube's pressure change when hung,
  at 0.1-0.3 bar;
- ``point_mass.POINT``: a mass hung at a named point (``[points]``;
  ``point_masses_kg.POINT``), 0-2 kg: shackles, a marker board, a wet patch of canopy,
  rigging left on the kite;
- ``suspension``: every suspension point but the first moved along x, y and z
  (``suspension_offsets_mm.NODE.AXIS``), -100 to +100 mm: where a hanging rig holds the
  bridle points is known to a few centimetres; the first stays, since moving every point
  together is a rigid motion the markers' registration absorbs;
- ``rest_length.SET``: the rest lengths of a line set (``rest_length_factors.SET``), 0.9-1.1:
  Dyneema bridles shrink and creep by a few per cent; sewing tolerances of a canopy edge;
- ``stiffness.SET``: the axial stiffness of a line set (``stiffness_factors.SET``), 0.1-10;
- ``bending.CLASS``: the bending law of one tube class (``[tube_classes]``, e.g. the
  leading edge or the struts; ``bending_class_factors.CLASS``) on top of the whole kite's,
  0.2-5: leading edges and struts differ in diameter, seams and reinforcement.

A user's effect is a :class:`ShapeEffect` (or a function of the campaign returning one) in a
Python file, named ``path/to/file.py:NAME`` in the campaign's ``[diagnose] candidates`` or
``jaxtube shape diagnose --effect``; for example, the bridle and the trailing edge
shortened together::

    from fitting import ShapeEffect

    def shrunk_lines(campaign):
        sets = ("bridle", "trailing_edge")
        return ShapeEffect("shrunk_lines", tuple(f"rest_length_factors.{s}" for s in sets),
                           ((0.9, 1.1),) * len(sets), "every line set shorter")
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .._user_files import import_user_file
from .file import AXES, Campaign
from .kite import is_offset, unknown_value_words


@dataclasses.dataclass(frozen=True)
class ShapeEffect:
    """A candidate effect: the model values it frees and their plausible ranges.

    Attributes:
        name: how the diagnosis names it.
        values: model value names (:func:`fitting.model_value`), e.g.
            ``("rest_length_factors.bridle",)``.
        plausible: ``((low, high), ...)`` per value: the factors (or, for a mass or an
            offset, the amounts) it can physically take (fits are bounded to this range).
        description: what it is, in words.
    """

    name: str
    values: tuple
    plausible: tuple
    description: str = ""

    def __post_init__(self):
        if not self.values or len(self.values) != len(self.plausible):
            raise ValueError(f"effect {self.name!r}: expected one plausible range (low, high) "
                             f"per value, found {len(self.plausible)} for {len(self.values)}")
        for value, (low, high) in zip(self.values, self.plausible):
            if value.startswith("point_masses_kg."):
                valid, words = 0 <= low < high, "0 <= low < high (a mass)"
            elif is_offset(value):
                valid, words = low < high, "low < high"
            else:
                valid, words = 0 < low < high, "0 < low < high (a factor)"
            if not valid:
                raise ValueError(f"effect {self.name!r}: {value}: expected {words}, "
                                 f"found ({low}, {high})")

    @property
    def bounds(self) -> dict:
        """``{value: (low, high)}``."""
        return dict(zip(self.values, self.plausible))


#: The built-in effects acting on the whole kite: name -> (value, plausible, description).
KITE_EFFECTS = {
    "bending": ("bending_scale", (0.05, 5.0), "the tubes' bending law scaled"),
    "torsion": ("torsion_scale", (0.1, 10.0), "the tubes' torsion law scaled"),
    "collapse": ("collapse_scale", (0.2, 5.0), "the tubes' wrinkling and collapse moments "
                                              "scaled, their stiffness kept"),
    "pressure": ("pressure_offset_bar", (-0.03, 0.03), "every case's overpressure offset"),
}
#: A point mass's plausible range [kg] (module docstring).
POINT_MASS_KG = (0.0, 2.0)
#: A suspension point's plausible offset along each axis [mm] (module docstring).
SUSPENSION_OFFSET_MM = (-100.0, 100.0)
#: The built-in effects of each line set: prefix -> (value kind, plausible, description).
LINE_SET_EFFECTS = {
    "rest_length": ("rest_length_factors", (0.9, 1.1), "the rest lengths of line set"),
    "stiffness": ("stiffness_factors", (0.1, 10.0), "the axial stiffness of line set"),
}


def shape_effects(campaign: Campaign) -> dict:
    """``{name: ShapeEffect}``: the built-in effects for ``campaign`` (module docstring)."""
    effects = {name: ShapeEffect(name, (value,), (plausible,), words)
               for name, (value, plausible, words) in KITE_EFFECTS.items()}
    for prefix, (kind, plausible, words) in LINE_SET_EFFECTS.items():
        for line_set in campaign.line_sets:
            name = f"{prefix}.{line_set}"
            effects[name] = ShapeEffect(name, (f"{kind}.{line_set}",), (plausible,),
                                        f"{words} {line_set!r} scaled")
    for tube_class in campaign.tube_classes:
        name = f"bending.{tube_class}"
        effects[name] = ShapeEffect(name, (f"bending_class_factors.{tube_class}",),
                                    ((0.2, 5.0),), f"the bending law of the {tube_class!r} "
                                                   "tubes scaled")
    for point in campaign.points:
        effects[f"point_mass.{point}"] = ShapeEffect(
            f"point_mass.{point}", (f"point_masses_kg.{point}",), (POINT_MASS_KG,),
            f"a mass hung at point {point!r} (node {campaign.points[point]})")
    if len(campaign.suspension) > 1:
        moved = [f"suspension_offsets_mm.{node}.{axis}" for node in campaign.suspension[1:]
                 for axis in AXES]
        effects["suspension"] = ShapeEffect(
            "suspension", tuple(moved), (SUSPENSION_OFFSET_MM,) * len(moved),
            f"suspension points {', '.join(map(str, campaign.suspension[1:]))} moved "
            f"relative to {campaign.suspension[0]}")
    return effects


def resolve_shape_effect(text: str, campaign: Campaign) -> ShapeEffect:
    """A built-in effect by name (:func:`shape_effects`) or a user's
    ``path/to/file.py:NAME`` (a :class:`ShapeEffect`, or a function of the campaign returning
    one); relative paths are taken from the campaign file's folder. Raises ``ValueError``
    saying why not."""
    built_in = shape_effects(campaign)
    if text in built_in:
        return built_in[text]
    path, sep, name = text.rpartition(":")
    if not sep or not path.endswith(".py"):
        raise ValueError(f"unknown effect {text!r} (expected one of {', '.join(built_in)} "
                         "or path/to/file.py:NAME)")
    file = Path(path) if Path(path).is_absolute() else campaign.path.parent / path
    if not file.is_file():
        raise ValueError(f"effect {text!r}: file not found: {file}")
    found = getattr(import_user_file(file, text), name, None)
    effect = found(campaign) if callable(found) and not isinstance(found, ShapeEffect) \
        else found
    if not isinstance(effect, ShapeEffect):
        raise ValueError(f"effect {text!r}: {file} has no ShapeEffect (or function of the "
                         f"campaign returning one) named {name!r}")
    for value in effect.values:
        words = unknown_value_words(campaign, value)
        if words is not None:
            raise ValueError(f"effect {text!r}: {words}")
    return effect
