"""A campaign's model values (:class:`KiteModel`, the ``[model]`` table or a model.json),
and the errors of campaign and model files (:class:`CampaignError`, every problem with its
file, key and reason)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import jaxtube as jt

LAW_FORMS = ("curvature", "moment")


class CampaignError(ValueError):
    """An invalid campaign (or model) file; ``problems`` lists every :class:`jaxtube.Problem`
    found (``source: key: reason``)."""

    def __init__(self, problems):
        self.problems = tuple(problems)
        count = len(self.problems)
        lines = [f"{count} problem{'s' if count != 1 else ''} in campaign file "
                 f"{self.problems[0].source}:"]
        super().__init__("\n".join(lines + [f"  {p}" for p in self.problems]))


@dataclasses.dataclass(frozen=True)
class KiteModel:
    """The parameter values a campaign's kite is solved with.

    Attributes:
        law_form: how ``bending_scale`` acts on Breukels' 2011 bending law: ``"curvature"``
            (:class:`jaxtube.CurvatureScaledLaw`: stiffness x scale, the wrinkling and
            collapse moments kept) or ``"moment"`` (:class:`jaxtube.ScaledLaw`: the whole
            curve x scale, as the peers scale it).
        bending_scale: the factor (1: the 2011 law as published).
        rest_length_factors: ``{line set: factor}`` on the rest lengths of a named line set.
        stiffness_factors: ``{line set: factor}`` on the stiffness [N/m] of a line set.
        bending_class_factors: ``{tube class: factor}`` on the bending law of the tubes of a
            class (``[tube_classes]``), on top of ``bending_scale``.
        torsion_scale: the factor on every tube's torsion law (Breukels' 2011 torsion law,
            :class:`jaxtube.ScaledLaw`; 1: as published).
        pressure_factor: the factor on every case's tube overpressure (1: the pressure the
            case states; a gauge that reads 10 % low is 1.1).
        pressure_offset_bar: added to every case's tube overpressure [bar] after the factor
            (a gauge's zero error).
        point_masses_kg: ``{point: mass [kg]}`` hung at a named point (``[points]``), a
            dead load along gravity besides the case's loads.
        suspension_offsets_mm: ``{"NODE.AXIS": offset [mm]}``: a suspension point moved from
            the model file's position along ``x``, ``y`` or ``z`` of the model's frame.
        collapse_scale: the factor on every tube's wrinkling and collapse moments (the
            bending law's plateau ``M_max``) on top of the law form's, the initial stiffness
            kept (1: the law form's moments). With ``c`` this factor and ``s`` the bending
            factor, ``M(kappa) = c M_2011(s kappa / c)`` in the curvature form and
            ``c s M_2011(kappa / c)`` in the moment form.
    """

    law_form: str = "curvature"
    bending_scale: float = 1.0
    rest_length_factors: dict = dataclasses.field(default_factory=dict)
    stiffness_factors: dict = dataclasses.field(default_factory=dict)
    torsion_scale: float = 1.0
    pressure_factor: float = 1.0
    bending_class_factors: dict = dataclasses.field(default_factory=dict)
    pressure_offset_bar: float = 0.0
    point_masses_kg: dict = dataclasses.field(default_factory=dict)
    suspension_offsets_mm: dict = dataclasses.field(default_factory=dict)
    collapse_scale: float = 1.0

    def to_json(self) -> dict:
        return {"law_form": self.law_form, "bending_scale": float(self.bending_scale),
                "torsion_scale": float(self.torsion_scale),
                "collapse_scale": float(self.collapse_scale),
                "pressure_factor": float(self.pressure_factor),
                "pressure_offset_bar": float(self.pressure_offset_bar),
                "rest_length_factors": {k: float(v) for k, v in
                                        self.rest_length_factors.items()},
                "stiffness_factors": {k: float(v) for k, v in
                                      self.stiffness_factors.items()},
                **{kind: {k: float(v) for k, v in getattr(self, kind).items()}
                   for kind in ("bending_class_factors", "point_masses_kg",
                                "suspension_offsets_mm")}}


class ProblemCollector:
    """Collects the problems of one file while it is read (``number`` and ``node`` read one
    value with its check; a failed check records the key and the reason and returns
    ``None``)."""

    def __init__(self, source: Path):
        self.report = jt.ProblemReport(str(source))

    def add(self, key, message):
        self.report.add(key, message)

    def number(self, table, key, where, default=None, minimum=None, positive=False):
        value = table.get(key, default)
        if value is None:
            if default is None and key not in table:
                self.add(f"{where}.{key}", "missing (expected a number)")
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or \
                not math.isfinite(value):
            self.add(f"{where}.{key}", f"expected a finite number, found {value!r}")
            return None
        if positive and not value > 0:
            self.add(f"{where}.{key}", f"expected a positive number, found {value!r}")
            return None
        if minimum is not None and value < minimum:
            self.add(f"{where}.{key}", f"expected a number >= {minimum}, found {value!r}")
            return None
        return float(value)

    def node(self, value, where, node_count, movable=None):
        if isinstance(value, bool) or not isinstance(value, int) or \
                not 0 <= value < node_count:
            self.add(where, f"expected a node of the model (an integer 0..{node_count - 1}), "
                            f"found {value!r}")
            return None
        if movable is not None and value not in movable:
            self.add(where, f"node {value} is held or fixed in the model (no element moves "
                            "it, or it is a suspension node): a load there does nothing")
            return None
        return int(value)

    def unknown_keys(self, table, known, where):
        for key in table:
            if key not in known:
                self.add(f"{where}.{key}" if where else key,
                         f"unknown key (expected one of: {', '.join(known)})")


#: The model's values per named member: kind -> (what a member is, the value's check).
MEMBER_VALUES = {"rest_length_factors": ("line set", "positive"),
                 "stiffness_factors": ("line set", "positive"),
                 "bending_class_factors": ("tube class", "positive"),
                 "point_masses_kg": ("point", "not negative"),
                 "suspension_offsets_mm": ("suspension axis (NODE.AXIS)", "finite")}


def read_model_values(table, where, checker, members) -> KiteModel:
    """A :class:`KiteModel` from a ``[model]`` table (or a model.json object);
    ``members``: ``{kind: names}`` the campaign's members of each kind of
    :data:`MEMBER_VALUES` (:meth:`Campaign.members`)."""
    known = ("law_form", "bending_scale", "torsion_scale", "collapse_scale", "pressure_factor",
             "pressure_offset_bar") + tuple(MEMBER_VALUES)
    for key in table:
        if key not in known:
            checker.add(f"{where}.{key}", "unknown effect (the model's values are: "
                                          f"{', '.join(known)})")
    form = table.get("law_form", "curvature")
    if form not in LAW_FORMS:
        checker.add(f"{where}.law_form", f"expected one of {', '.join(LAW_FORMS)}, "
                                         f"found {form!r}")
    scale = checker.number(table, "bending_scale", where, default=1.0, positive=True)
    torsion = checker.number(table, "torsion_scale", where, default=1.0, positive=True)
    collapse = checker.number(table, "collapse_scale", where, default=1.0, positive=True)
    pressure = checker.number(table, "pressure_factor", where, default=1.0, positive=True)
    offset = checker.number(table, "pressure_offset_bar", where, default=0.0)
    values = {}
    for kind, (words, check) in MEMBER_VALUES.items():
        values[kind] = {}
        given = table.get(kind, {})
        if not isinstance(given, dict):
            checker.add(f"{where}.{kind}", f"expected a table {{{words} = value}}")
            continue
        for name in given:
            if name not in members[kind]:
                checker.add(f"{where}.{kind}.{name}",
                            f"unknown {words} (the campaign's: "
                            f"{', '.join(members[kind]) or 'none'})")
                continue
            value = checker.number(given, name, f"{where}.{kind}", positive=check == "positive",
                                   minimum=0.0 if check == "not negative" else None)
            if value is not None:
                values[kind][name] = value
    return KiteModel(form, scale or 1.0, values["rest_length_factors"],
                     values["stiffness_factors"], torsion or 1.0, pressure or 1.0,
                     values["bending_class_factors"], offset or 0.0,
                     values["point_masses_kg"], values["suspension_offsets_mm"],
                     collapse or 1.0)


def parse_document(path: Path, loads, decode_error: type[Exception], kind: str):
    """``loads(path's text)``; a missing file or a ``decode_error`` raises
    :class:`CampaignError` naming the file (``kind``: the format, e.g. ``"TOML"``)."""
    try:
        return loads(path.read_text())
    except FileNotFoundError:
        raise CampaignError([jt.Problem(str(path), "file not found")]) from None
    except decode_error as error:
        raise CampaignError([jt.Problem(str(path), f"not {kind}: {error}")]) from None


def read_model_file(path, campaign) -> KiteModel:
    """A model.json written by ``jaxtube shape`` (or by hand): the ``[model]`` keys as JSON,
    checked against ``campaign``'s line sets."""
    path = Path(path)
    checker = ProblemCollector(path)
    table = parse_document(path, json.loads, json.JSONDecodeError, "JSON")
    if not isinstance(table, dict) or not isinstance(table.get("model"), dict):
        raise CampaignError([jt.Problem(str(path), "expected a JSON object with an object "
                                                   "'model'", "model")])
    model = read_model_values(table["model"], "model", checker, campaign.members())
    if len(checker.report):
        raise CampaignError(checker.report.problems)
    return model
