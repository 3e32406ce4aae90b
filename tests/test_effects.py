"""Built-in effects in the cantilever rig against the independent continuum solver.

Each effect, switched on alone in a rig that provides every degree of freedom (shear
strains, clamp spring), must reproduce the tip force of ``fitting.continuum``'s shooting
solver with the same physics; at their null values the effects must leave the plain
cantilever unchanged.
"""


import jax
import jax.numpy as jnp
import numpy as np
import pytest

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
