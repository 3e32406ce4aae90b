"""Built-in effects in the cantilever rig against the independent continuum solver.

Each effect, switched on alone in a rig that provides every degree of freedom (shear
strains, clamp spring), must reproduce the tip force of ``fitting.continuum``'s shooting
solver with the same physics; at their null values the effects must leave the plain
cantilever unchanged.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.interpolate

import jaxtube as jt
from fitting import continuum
from fitting._bench import effects as fx
from fitting._bench.rig import CantileverRig, TubeModel

EI, PRESSURE, RADIUS, LENGTH = 200.0, 2e4, 0.075, 0.8
DEFLECTIONS = np.array([0.002, 0.05, 0.12])
SHEAR_FLEXIBILITY = 1.0 / (2 * np.pi * 0.5 * 5e3)  # k = 0.5, G t = 5 kN/m


def _effects(**on):
    values = {"shear": 0.0, "reinforcement": 0.0, "clamp_compliance": 0.0, "self_weight": 0.0}
    values.update(on)
    return (fx.Shear(values["shear"]), fx.Reinforcement(values["reinforcement"]),
            fx.ClampCompliance(values["clamp_compliance"]),
            fx.SelfWeight(values["self_weight"]))


@pytest.fixture(scope="module")
def featured_curve():
    rig = CantileverRig(segments=20, features=frozenset({"shear", "clamp_spring"}))

    @jax.jit
    def curve(effects):
        model = TubeModel(jt.LinearLaw(EI), jt.LinearLaw(150.0), effects)
        pred = rig.curve(model, PRESSURE, RADIUS, LENGTH, jnp.asarray(DEFLECTIONS))
        return pred.force, pred.converged

    return curve


CASES = {
    "null": ({}, {}),
    "shear": ({"shear": SHEAR_FLEXIBILITY},
              {"shear_stiffness": PRESSURE * np.pi * RADIUS**2 + RADIUS / SHEAR_FLEXIBILITY}),
    "reinforcement": ({"reinforcement": 60.0}, {"reinforcement_stiffness": 60.0}),
    "clamp_compliance": ({"clamp_compliance": 4e-4}, {"clamp_stiffness": 1.0 / 4e-4}),
    "self_weight": ({"self_weight": 2.0}, {"mass_per_length": 2.0}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_effect_matches_continuum_solver(featured_curve, case):
    on, continuum_kwargs = CASES[case]
    force, converged = featured_curve(_effects(**on))
    assert bool(np.all(converged))
    reference = continuum.CantileverModel(LENGTH, continuum.linear_law(EI), **continuum_kwargs)
    expected = np.array([reference.tip_force(u) for u in DEFLECTIONS])
    np.testing.assert_allclose(np.asarray(force), expected, rtol=3e-3)


def test_null_effects_equal_the_plain_rig(featured_curve):
    """The featured rig at null values is the plain cantilever (no extra degrees of freedom)."""
    plain = CantileverRig(segments=20)
    model = TubeModel(jt.LinearLaw(EI), jt.LinearLaw(150.0))
    force = plain.curve(model, PRESSURE, RADIUS, LENGTH, jnp.asarray(DEFLECTIONS)).force
    featured, _ = featured_curve(_effects())
    np.testing.assert_allclose(np.asarray(featured), np.asarray(force), rtol=1e-5)


def test_effect_needing_a_missing_rig_feature_is_refused():
    model = TubeModel(jt.LinearLaw(EI), effects=(fx.Shear(1e-4),))
    with pytest.raises(ValueError, match="needs a rig with features"):
        CantileverRig(segments=4).specimen_parameters(model, PRESSURE, RADIUS, LENGTH)


def _spline_moment_by_hand(curvatures, moments, share, residual_ratio):
    """M(kappa) of a three-pivot SplineLaw at its reference specimen, in numpy and scipy
    (docs/physics.md, section 1.1): Fritsch-Butland knot slopes, the residual slope at the
    last pivot, the first piece ``a k + b max(k - k_0, 0)^3``, cubic Hermite pieces, a
    linear tail."""
    widths = np.diff(np.concatenate([[0.0], curvatures]))
    secants = np.diff(np.concatenate([[0.0], moments])) / widths
    before, after = 2 * widths[1:] + widths[:-1], widths[1:] + 2 * widths[:-1]
    interior = (before + after) / (before / secants[:-1] + after / secants[1:])
    residual = 1.0 / (1.0 / (residual_ratio * secants[0]) + 1.0 / (3.0 * secants[-1]))
    slopes = np.concatenate([interior, [residual]])
    k1, width = curvatures[0], (1.0 - share) * curvatures[0]
    a = (3.0 * moments[0] - slopes[0] * width) / (3.0 * k1 - width)
    b = (moments[0] - a * k1) / width**3
    hermite = scipy.interpolate.CubicHermiteSpline(curvatures, moments, slopes)

    def moment(kappa):
        k = abs(kappa)
        if k <= k1:
            value = a * k + b * max(k - share * k1, 0.0) ** 3
        elif k <= curvatures[-1]:
            value = float(hermite(k))
        else:
            value = moments[-1] + residual * (k - curvatures[-1])
        return math.copysign(value, kappa)

    return moment


def test_unwrinkled_linearity_matches_continuum_solver():
    """The model-structure extension in the rig: its law (the spline with ``linear_share``)
    solved by the continuum shooting solver gives the same tip forces; at its null the rig
    is the plain spline's."""
    law = jt.SplineLaw.from_pivots([0.02, 0.3, 1.5], [12.0, 20.0, 24.0], PRESSURE, RADIUS,
                                   pivots_per_regime=(1, 1, 1))  # paper form, B = 1
    rig = CantileverRig(segments=20)
    deflections = jnp.asarray([0.002, 0.01, 0.03])  # the root passes k_0 and k_1

    @jax.jit
    def forces(effects):
        return rig.curve(TubeModel(law, jt.LinearLaw(150.0), effects), PRESSURE, RADIUS,
                         LENGTH, deflections).force

    share = 0.7
    curvatures, moments = np.array([0.02, 0.3, 1.5]), np.array([12.0, 20.0, 24.0])
    moment = _spline_moment_by_hand(curvatures, moments, share, residual_ratio=0.01)

    reference = continuum.CantileverModel(LENGTH, continuum.law_from_moment(
        moment, curvature_scale=0.02))
    expected = np.array([reference.tip_force(float(u)) for u in deflections])
    np.testing.assert_allclose(np.asarray(forces((fx.UnwrinkledLinearity(share),))),
                               expected, rtol=3e-3)
    plain = np.asarray(forces(()))
    np.testing.assert_allclose(np.asarray(forces((fx.UnwrinkledLinearity(0.0),))), plain,
                               rtol=1e-12)  # the same law, rounded differently
    # Linear over 70 % of the first regime, the tube starts softer than the odd cubic, whose
    # initial slope (3 M_1 / k_1 - d_1) / 2 exceeds the secant M_1 / k_1.
    assert expected[0] < plain[0]


def test_effects_that_do_not_load_at_rest_leave_the_unloaded_specimen_straight():
    """The rig skips the unloaded solve unless an effect ``loads_at_rest``: every built-in
    that says it does not (each at a typical, non-null size) leaves the specimen's loads
    and rest geometry those of the plain specimen (its laws are odd, so the straight
    template is then the unloaded equilibrium), where self-weight (which does) adds a weight."""
    rig = CantileverRig(segments=4, features=frozenset({"shear", "clamp_spring"}))
    law = jt.SplineLaw.from_tension_field(150e3, PRESSURE, RADIUS, form="paper")
    stiffness_only = tuple(cls(*[p.typical for p in cls.parameters])
                           for cls in (*fx.MODEL_EXTENSIONS.values(), *fx.BUILT_IN_EFFECTS.values())
                           if not cls.loads_at_rest)
    assert {e.name for e in stiffness_only} == {"reinforcement", "clamp_compliance", "shear",
                                                "radius_scaling", "unwrinkled_linearity"}

    def at_rest(effects):
        model = TubeModel(law, jt.LinearLaw(150.0), effects, reference=(PRESSURE, RADIUS))
        params = rig.specimen_parameters(model, PRESSURE, RADIUS, LENGTH)
        return [np.asarray(x) for x in (params.node_position, params.mass_per_length,
                                         params.line_load, params.node_force,
                                         params.node_torque, *jax.tree.leaves(params.elements))]

    plain = at_rest(())
    for changed, unchanged in zip(at_rest(stiffness_only), plain, strict=True):
        np.testing.assert_array_equal(changed, unchanged)
    assert not all(np.array_equal(a, b) for a, b in zip(at_rest((fx.SelfWeight(0.3),)), plain))
