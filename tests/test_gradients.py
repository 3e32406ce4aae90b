"""Implicit-function-theorem gradients against central finite differences (float64).

Quantities: the tip deflection under a dead tip load (force control) and the reaction force
under displacement control, in the wrinkled regime of the paper's spline law, w.r.t. a
pivot's scaling factor A and exponent B, the pressure p and the radius r.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt

PRESSURE, RADIUS, WALL_MODULUS = 2e4, 0.075, 150e3
SEGMENTS = 8


@pytest.fixture(scope="module")
def problem():
    law = jt.SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS, form="paper")
    structure, params = jt.cantilever(1.0, RADIUS, PRESSURE, SEGMENTS, law, jt.LinearLaw(150.0))
    return structure, params


# Each parameter: (name, getter, setter) on the parameter PyTree.
PARAMETERS = {
    "A (moment pivot 5)": lambda p: p.bending_laws[0].moment_scale[4],
    "B (moment pivot 5)": lambda p: p.bending_laws[0].moment_exponent[4],
    "A (curvature pivot 4)": lambda p: p.bending_laws[0].curvature_scale[3],
    "B (curvature pivot 4)": lambda p: p.bending_laws[0].curvature_exponent[3],
    "p": lambda p: p.pressure[0],
}


def _set(params, name, value):
    law = params.bending_laws[0]
    if name == "p":
        return eqx.tree_at(lambda p: p.pressure, params, params.pressure.at[0].set(value))
    if name == "r":
        return eqx.tree_at(lambda p: p.node_radius, params, jnp.full_like(params.node_radius,
                                                                          value))
    field = {"A (moment": "moment_scale", "B (moment": "moment_exponent",
             "A (curvat": "curvature_scale", "B (curvat": "curvature_exponent"}[name[:9]]
    index = int(name.split()[-1].rstrip(")")) - 1
    array = getattr(law, field).at[index].set(value)
    return eqx.tree_at(lambda p: getattr(p.bending_laws[0], field), params, array)


def _check(quantity, params, solve):
    """Compare the gradient of ``quantity(p, solve(p))`` with its central differences. One
    compiled program (value, gradient and the path's solution, to check that every step
    converged in the wrinkled regime) serves the gradient and every difference."""
    def value_and_solution(p):
        sol = solve(p)
        return quantity(p, sol), sol

    compiled = jax.jit(jax.value_and_grad(value_and_solution, has_aux=True))
    (value0, sol), grad = compiled(params)
    assert bool(np.all(sol.converged))
    assert int(np.max(sol.joint_regime[-1])) >= 1, "the test must reach the wrinkled regime"

    def value(p):
        return float(compiled(p)[0][0])

    names = list(PARAMETERS) + ["r"]
    getters = dict(PARAMETERS, r=lambda p: p.node_radius[0])
    for name in names:
        x0 = float(getters[name](params))
        h = 1e-4 * abs(x0)
        fd = (value(_set(params, name, x0 + h)) - value(_set(params, name, x0 - h))) / (2 * h)
        if name == "r":
            analytic = float(jnp.sum(grad.node_radius))
        else:
            analytic = float(getters[name](grad))
        scale = max(abs(fd), 1e-6 * abs(float(value0)) / abs(x0))
        assert abs(analytic - fd) <= 1e-5 * scale, (name, analytic, fd)


def test_tip_deflection_gradient_force_control(problem):
    structure, params = problem
    tip = structure.node_id("tube:end")
    wrinkling = float(params.bending_laws[0].pivots(PRESSURE, RADIUS)[1][2])  # M_w [N m]
    force = params.node_force.at[tip].set(jnp.array([0.0, 0.0, -1.6 * wrinkling]))
    loaded = eqx.tree_at(lambda p: p.node_force, params, force)
    path = jt.ForceControl(jnp.linspace(0.25, 1.0, 4))

    def tip_deflection(p, sol):
        return -(sol.node_position[-1, tip, 2] - p.node_position[tip, 2])

    _check(tip_deflection, loaded, lambda p: jt.solve_path(structure, p, path))


def test_reaction_force_gradient_displacement_control(problem):
    structure, params = problem
    tip = structure.node_id("tube:end")
    path = jt.DisplacementControl(tip, [0.0, 0.0, -1.0], jnp.linspace(0.02, 0.08, 4))

    def tip_force(p, sol):
        return sol.control_force[-1]

    _check(tip_force, params, lambda p: jt.solve_path(structure, p, path))
