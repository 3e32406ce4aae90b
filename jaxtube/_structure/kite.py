"""Parametric tube kites: a leading-edge arc with optional chordwise struts.

A :class:`TubeKite` describes the inflatable frame of a surf kite (Breukels & Ockels 2008):

- **the leading-edge tube** ``"le"``: a circular arc through both wing tips and the crown
  (from the span and the arc height), or a sampled centreline; radius largest at the centre
  and falling towards the tips (:func:`double_taper`), one envelope at one pressure;
- **struts** ``"strut_1"``, ``"strut_2"``, ...: straight tapered tubes attached rigidly to a
  leading-edge node and running chordwise, each at its own pressure or the leading edge's;
- **supports** at both wing tips, clamped or pinned.

Frame: ``y`` along the span (left tip at ``y = -span / 2``), ``z`` up (the arc stands
upright, tips at ``z = 0``, crown at ``z = arc_height``), ``x`` chordwise (struts run
towards ``+x`` by default). :meth:`TubeKite.build` returns ``(structure, params)`` of
:func:`~jaxtube.build_structure`; :meth:`TubeKite.node` turns the kite's node names
(``le:centre``, ``le:left_tip``, ``le:right_tip``, ``strut_2:root``, ``strut_2:end``, or any
plain ``tube:index``) into the ``tube:index`` form that ``Structure.node_id`` reads.

Loads come through :meth:`TubeKite.build` (point forces at named nodes) and the tubes'
``line_load`` and ``mass_per_length``; the paper's kite test loads the crown ``le:centre``.
"""

from __future__ import annotations

import math

import equinox as eqx
import numpy as np

from .._laws import AbstractMomentLaw
from .build import build_structure
from .structure import (
    STANDARD_GRAVITY,
    SUPPORT_KINDS,
    Connection,
    Structure,
    StructureParameters,
    Support,
)
from .tube import Tube, arc_tube, polyline_tube, straight_tube

LEADING_EDGE = "le"
# Named nodes besides "tube:index": le:centre, le:left_tip, le:right_tip, strut_k:root.
KITE_NODE_NAMES = ("centre", "left_tip", "right_tip", "root")


def double_taper(centre_radius: float, tip_radius: float) -> tuple[tuple[float, float], ...]:
    """Radius table ``[(fraction, radius [m]), ...]`` falling linearly from the centre
    (fraction 0.5) to both tips, for :class:`TubeKite` ``radius``."""
    return ((0.0, float(tip_radius)), (0.5, float(centre_radius)), (1.0, float(tip_radius)))


def arc_through_tips(span: float, arc_height: float) -> tuple[float, float]:
    """Circle through the tips ``(y, z) = (+-span / 2, 0)`` and the crown ``(0, arc_height)``:
    returns ``(arc_radius [m], half_angle [rad])``, from ``R = (span^2 / 4 + h^2) / (2 h)``
    and ``sin(half_angle) = span / (2 R)`` (half the angle the arc subtends; above
    ``pi / 2`` when the arc is more than a half circle)."""
    half = 0.5 * span
    radius = (half**2 + arc_height**2) / (2.0 * arc_height)
    return radius, math.atan2(half, radius - arc_height)


class Strut(eqx.Module):
    """A straight tapered strut attached rigidly to the leading edge, running chordwise.

    Attributes:
        span_fraction: where it sits along the leading edge, as a fraction of its arc length
            from the left tip, in ``(0, 1)``; it attaches at the nearest leading-edge node
            (ties go away from the centre, so mirrored fractions give mirrored nodes).
        chord: strut length [m].
        radius: a number [m] or a taper ``[(fraction of the strut from its root, radius), ...]``.
        segments: number of rigid segments.
        pressure: envelope overpressure [Pa]; ``None`` shares the leading edge's.
        bending_law: ``None`` uses the leading edge's law object (evaluated at the strut's
            own pressure and radius).
        torsion_law: ``None`` uses the leading edge's torsion law when the strut has no
            bending law of its own, else the strut's bending law (as for ``Tube``).
        mass_per_length [kg/m], line_load ``[3]`` [N/m]: as for :class:`~jaxtube.Tube`.
        direction: unit chordwise direction ``[3]`` (default ``+x``).
    """

    span_fraction: float
    chord: float
    radius: float | tuple
    segments: int = eqx.field(static=True)
    pressure: float | None = None
    bending_law: AbstractMomentLaw | None = None
    torsion_law: AbstractMomentLaw | None = None
    mass_per_length: float = 0.0
    line_load: tuple = (0.0, 0.0, 0.0)
    direction: tuple = (1.0, 0.0, 0.0)

    def __check_init__(self):
        if not 0.0 < float(self.span_fraction) < 1.0:
            raise ValueError(f"strut span_fraction must lie in (0, 1), got {self.span_fraction}")
        if not (float(self.chord) > 0 and int(self.segments) > 0):
            raise ValueError("strut chord and segments must be positive")
        if not np.any(np.asarray(self.direction, float)):
            raise ValueError("strut direction must be a non-zero vector")


class TubeKite(eqx.Module):
    """The inflatable frame of a tube kite (see the module docstring for the frame).

    Attributes:
        segments: leading-edge segments (even, so that ``le:centre`` is a node).
        radius: leading-edge radius, a number [m] or a taper ``[(fraction, radius), ...]``
            along its arc length (:func:`double_taper` for the usual double taper).
        pressure: leading-edge overpressure [Pa].
        bending_law, torsion_law: leading-edge laws (torsion defaults to the bending law).
        span, arc_height: tip-to-tip distance and crown height [m] of a circular arc;
            or ``centreline``: sampled points ``[n, 3]`` [m] from the left tip to the right
            tip (then ``span`` and ``arc_height`` must be ``None``).
        struts: tuple of :class:`Strut`, named ``strut_1``, ``strut_2``, ... in this order.
        tip_support: ``"clamped"`` or ``"pinned"``, at both wing tips.
        mass_per_length [kg/m], line_load ``[3]`` [N/m]: of the leading edge.
    """

    segments: int = eqx.field(static=True)
    radius: float | tuple
    pressure: float
    bending_law: AbstractMomentLaw
    torsion_law: AbstractMomentLaw | None = None
    span: float | None = None
    arc_height: float | None = None
    centreline: tuple | None = None
    struts: tuple = ()
    tip_support: str = eqx.field(static=True, default="clamped")
    mass_per_length: float = 0.0
    line_load: tuple = (0.0, 0.0, 0.0)

    def __check_init__(self):
        if int(self.segments) < 2 or int(self.segments) % 2:
            raise ValueError(f"the leading edge needs an even number of segments (so that "
                             f"le:centre is a node), got {self.segments}")
        if self.tip_support not in SUPPORT_KINDS:
            raise ValueError(f"tip_support {self.tip_support!r}: expected one of "
                             f"{SUPPORT_KINDS}")
        arc = self.span is not None or self.arc_height is not None
        if arc == (self.centreline is not None):
            raise ValueError("give the leading edge either span and arc_height (a circular "
                             "arc) or centreline (sampled points), not both or neither")
        if arc and not (self.span is not None and self.arc_height is not None
                        and self.span > 0 and self.arc_height > 0):
            raise ValueError(f"span and arc_height must both be positive, got {self.span} "
                             f"and {self.arc_height}")
        attached = [self.strut_attachment(k) for k in range(len(self.struts))]
        if len(set(attached)) != len(attached):
            raise ValueError(f"two struts attach at the same leading-edge node "
                             f"(nodes {attached} for {self.segments} segments)")

    def strut_attachment(self, k: int) -> int:
        """Leading-edge node index where strut ``k`` (0-based) attaches."""
        offset = (float(self.struts[k].span_fraction) - 0.5) * self.segments
        index = self.segments // 2 + int(math.copysign(math.floor(abs(offset) + 0.5), offset))
        if not 0 < index < self.segments:
            raise ValueError(f"strut_{k + 1} at span_fraction {self.struts[k].span_fraction} "
                             f"falls on a wing tip at {self.segments} segments")
        return index

    def leading_edge(self) -> Tube:
        """The leading-edge :class:`~jaxtube.Tube`, node 0 at the left tip."""
        kwargs = dict(torsion_law=self.torsion_law, mass_per_length=self.mass_per_length,
                      line_load=self.line_load)
        if self.centreline is not None:
            return polyline_tube(LEADING_EDGE, self.centreline, self.segments, self.radius,
                                 self.pressure, self.bending_law, **kwargs)
        arc_radius, half_angle = arc_through_tips(self.span, self.arc_height)
        # centre + R (cos phi y + sin phi z), phi from the left tip over the crown (pi / 2).
        return arc_tube(LEADING_EDGE, (0.0, 0.0, self.arc_height - arc_radius), arc_radius,
                        0.5 * math.pi + half_angle, 0.5 * math.pi - half_angle, self.segments,
                        self.radius, self.pressure, self.bending_law, normal=(1.0, 0.0, 0.0),
                        reference=(0.0, 1.0, 0.0), **kwargs)

    def tubes(self) -> list[Tube]:
        """The leading edge, then every strut, as :class:`~jaxtube.Tube` objects."""
        le = self.leading_edge()
        tubes = [le]
        for k, strut in enumerate(self.struts):
            root = np.asarray(le.nodes[self.strut_attachment(k)])
            direction = np.asarray(strut.direction, float)
            tip = root + float(strut.chord) * direction / np.linalg.norm(direction)
            tubes.append(straight_tube(
                f"strut_{k + 1}", root, tip, strut.segments, strut.radius,
                self.pressure if strut.pressure is None else strut.pressure,
                self.bending_law if strut.bending_law is None else strut.bending_law,
                torsion_law=(strut.torsion_law if strut.bending_law is not None
                             or strut.torsion_law is not None else self.torsion_law),
                mass_per_length=strut.mass_per_length, line_load=strut.line_load))
        return tubes

    def supports(self) -> list[Support]:
        return [Support(f"{LEADING_EDGE}:0", self.tip_support),
                Support(f"{LEADING_EDGE}:{self.segments}", self.tip_support)]

    def connections(self) -> list[Connection]:
        return [Connection(f"{LEADING_EDGE}:{self.strut_attachment(k)}", f"strut_{k + 1}:0",
                           "rigid") for k in range(len(self.struts))]

    def node_aliases(self) -> dict[str, str]:
        """The kite's node names and the ``tube:index`` they stand for."""
        aliases = {f"{LEADING_EDGE}:centre": f"{LEADING_EDGE}:{self.segments // 2}",
                   f"{LEADING_EDGE}:left_tip": f"{LEADING_EDGE}:0",
                   f"{LEADING_EDGE}:right_tip": f"{LEADING_EDGE}:{self.segments}"}
        for k, strut in enumerate(self.struts):
            aliases[f"strut_{k + 1}:root"] = f"strut_{k + 1}:0"
            aliases[f"strut_{k + 1}:end"] = f"strut_{k + 1}:{strut.segments}"
        return aliases

    def node(self, name: str) -> str:
        """``"tube:index"`` of a kite node name (plain ``tube:index`` names pass through)."""
        return self.node_aliases().get(name, name)

    def build(self, node_force: dict | None = None,
              gravity=(0.0, 0.0, -STANDARD_GRAVITY)) -> tuple[Structure, StructureParameters]:
        """``(structure, params)``; ``node_force`` maps node names (kite names allowed) to
        dead forces ``[3]`` [N]; ``gravity`` [m/s^2] acts on the tubes' masses."""
        forces = {self.node(name): value for name, value in (node_force or {}).items()}
        return build_structure(self.tubes(), self.supports(), self.connections(),
                               node_force=forces or None, gravity=gravity)
