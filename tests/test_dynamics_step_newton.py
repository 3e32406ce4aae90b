"""Each time step's own Newton-KKT iteration (jaxtube/_dynamics/step_newton.py) on a small
curved problem: a KKT point to the stopping rule's tolerance with the residual it reports,
and a step that runs out of iterations reported as such. (Its implicit derivative is
checked through a whole history in test_dynamics_time.py.)"""

from functools import partial

import jax
import jax.numpy as jnp

from jaxtube._dynamics.step_newton import solve_step
from jaxtube._solver.newton_kkt import NewtonKKT


def _objective(z, weight):
    """Two energy terms [J] on ``z [2]`` and the unit circle as the constraint: a curved
    constraint, so a full Newton step leaves it violated at second order."""
    terms = jnp.stack([(z[0] - 2.0) ** 2, weight * (z[1] - z[0] ** 2) ** 2])
    return terms, jnp.stack([z @ z - 1.0])


def _hessian(z, multipliers, weight):
    return jax.hessian(lambda zz: jnp.sum(_objective(zz, weight)[0])
                       + multipliers @ _objective(zz, weight)[1])(z)


GUESS = jnp.array([0.3, 0.8])


@partial(jax.jit, static_argnums=1)
def _solve(weight, solver=NewtonKKT()):
    return solve_step(_objective, GUESS, weight, solver, jnp.zeros(1), _hessian)


def test_step_newton_converges_honestly_and_reports_a_short_run():
    weight = jnp.asarray(3.0)
    solved = _solve(weight)
    assert bool(solved.converged) and int(solved.result) == 0
    # The reported residual is the stopping rule's, at the returned state (to round-off).
    gradient = jax.grad(lambda z: jnp.sum(_objective(z, weight)[0])
                        + solved.multipliers @ _objective(z, weight)[1])(solved.state)
    assert abs(float(jnp.max(jnp.abs(gradient))) - float(solved.residual)) <= 1e-14
    assert int(solved.iterations) > 1
    assert abs(float(solved.state @ solved.state) - 1.0) <= 1e-11
    # From the same guess one Newton iteration is not enough: reported, not passed over.
    short = _solve(weight, NewtonKKT(max_steps=1))
    assert not bool(short.converged) and int(short.result) == 1
    assert int(short.iterations) == 1
