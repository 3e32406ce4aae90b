"""Solver behaviour: equilibrium of reactions, displacement control through collapse,
vmap with per-member convergence, non-convergence reported (never NaN), float64 guard."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._mechanics import configuration, reference_geometry, segment_loads

from .helpers import with_tip_force


def test_reactions_balance_applied_loads():
    """An arch clamped at both ends with a strut, self-weight, line and point loads: support
    reactions (multipliers) balance every applied force and moment."""
    arch = jt.arc_tube("arch", (0, 0, 0), 1.0, 0.0, np.pi, 12, 0.05, 2e4, jt.LinearLaw(50.0),
                       torsion_law=jt.LinearLaw(40.0), normal=(0, -1, 0), mass_per_length=0.5)
    strut = jt.straight_tube("strut", (0, 0, 1.0), (0, 0.5, 1.0), 4, 0.03, 2e4,
                             jt.LinearLaw(20.0), torsion_law=jt.LinearLaw(15.0),
                             line_load=(0, 0, -3.0))
    structure, params = jt.build_structure(
        [arch, strut], [jt.Support("arch:0", "clamped"), jt.Support("arch:end", "clamped")],
        [jt.Connection("arch:6", "strut:0")],
        node_force={"arch:3": [1.0, 2.0, -30.0], "strut:end": [0, 0, -5.0]},
    )
    sol = jax.jit(lambda p: jt.equilibrium(structure, p))(params)
    assert bool(sol.converged)
    geometry = reference_geometry(structure, params)
    config = configuration(structure, geometry, sol.state)
    distributed = segment_loads(structure, geometry, params)
    midpoint = 0.5 * (config.segment_start + config.segment_end)
    supports = np.array([n for n, _ in structure.supports])
    applied = params.node_force.sum(0) + distributed.sum(0)
    assert float(jnp.linalg.norm(applied)) > 10.0
    np.testing.assert_allclose(sol.reaction_force.sum(0), -applied, atol=1e-9)
    moment = (jnp.cross(sol.node_position, params.node_force).sum(0)
              + jnp.cross(midpoint, distributed).sum(0)
              + jnp.cross(sol.node_position[supports], sol.reaction_force).sum(0)
              + sol.reaction_moment.sum(0))
    np.testing.assert_allclose(moment, 0.0, atol=1e-8)


@pytest.fixture(scope="module")
def tension_field_cantilever():
    law = jt.TensionFieldLaw(150e3, residual_stiffness_ratio=0.01)
    return jt.cantilever(1.0, 0.075, 2e4, 10, law, jt.LinearLaw(150.0))


def test_displacement_control_traces_collapse_plateau(tension_field_cantilever):
    structure, params = tension_field_cantilever
    tip = structure.node_id("tube:end")
    path = jt.DisplacementControl(tip, [0, 0, -1], jnp.linspace(0.01, 0.4, 40))
    sol = jax.jit(lambda p: jt.solve_path(structure, p, path))(params)
    jt.check_converged(sol)
    force = np.asarray(sol.control_force)
    collapse = np.pi * 2e4 * 0.075**3  # M_c [N m] at the root of a 1 m cantilever
    displacement = np.asarray(path.displacements)
    assert np.all(np.diff(force) > 0)  # residual stiffness keeps it rising
    initial_stiffness = force[0] / displacement[0]
    final_stiffness = (force[-1] - force[-2]) / (displacement[-1] - displacement[-2])
    assert final_stiffness < 0.1 * initial_stiffness  # softened tenfold: the plateau
    assert force[-1] > 0.9 * collapse  # M_c / L, lifted a little by the residual stiffness
    assert int(np.max(sol.joint_regime[-1])) == 2  # the root collapsed
    # the root joint is the first to leave the linear regime
    first = [int(np.argmax(r > 0)) if np.any(r > 0) else 99 for r in np.asarray(
        sol.joint_regime).T]
    assert first[0] == min(first)


def test_vmap_reports_each_member_and_failure_is_not_hidden(tension_field_cantilever):
    """Under vmap each member reports its own convergence. A member given too few Newton
    steps for its (large, collapsing) load in one jump must say so (result code 1), with
    finite numbers, while the others converge."""
    structure, params = tension_field_cantilever
    collapse = np.pi * 2e4 * 0.075**3

    def solve(load):
        return jt.equilibrium(structure, with_tip_force(structure, params, [0, 0, -load]),
                              solver=jt.NewtonKKT(max_steps=6))

    loads = jnp.array([0.05, 0.2, 1.5]) * collapse
    sol = jax.jit(jax.vmap(solve))(loads)
    converged = np.asarray(sol.converged)
    assert converged.tolist() == [True, True, False]
    assert int(sol.result[2]) == 1  # "did not converge within the maximum number of steps"
    assert np.all(np.isfinite(np.asarray(sol.node_position)))
    assert int(sol.iterations[0]) < int(sol.iterations[2])
    with pytest.raises(RuntimeError, match="1 of 3 steps did not converge"):
        jt.check_converged(sol)


def test_float32_is_refused():
    structure, params = jt.cantilever(1.0, 0.075, 2e4, 3, jt.LinearLaw(1.0))
    state = jax.tree.map(lambda x: x.astype(jnp.float32), jt.initial_state(structure, params))
    with pytest.raises(TypeError, match="float64"):
        jt.solve_equilibrium(
            lambda s, a: (jnp.sum(s["joint_rotation"] ** 2), jnp.zeros((0,), jnp.float32)),
            state, None,
        )


def test_pinned_supports_and_tapered_tube():
    """A double-tapered hanging arc pinned at both ends, loaded at its middle: symmetric
    deflection; vertical reactions share the load, horizontal reactions are opposite.
    (A straight inextensible tube between two pins would lock: it cannot sag without
    stretching, and the solver correctly drives it straight with a growing tension.)"""
    taper = [(0.0, 0.05), (0.5, 0.08), (1.0, 0.05)]
    tube = jt.arc_tube("t", (1.0, 0, 0.0), 1.0, np.pi, 2 * np.pi, 12, taper, 2e4,
                       jt.TensionFieldLaw(150e3), torsion_law=jt.LinearLaw(60.0),
                       normal=(0, -1, 0))
    structure, params = jt.build_structure(
        [tube], [jt.Support("t:0", "pinned"), jt.Support("t:end", "pinned")],
        node_force={"t:6": [0, 0, -10.0]},
    )
    np.testing.assert_allclose(params.node_position[6], [1.0, 0.0, -1.0], atol=1e-12)
    sol = jax.jit(lambda p: jt.equilibrium(structure, p))(params)
    assert bool(sol.converged)
    x, z = np.asarray(sol.node_position[:, 0]), np.asarray(sol.node_position[:, 2])
    np.testing.assert_allclose(z, z[::-1], atol=1e-10)
    np.testing.assert_allclose(x, 2.0 - x[::-1], atol=1e-10)
    assert z[6] < -1.0
    np.testing.assert_allclose(sol.reaction_force[:, 2], [5.0, 5.0], atol=1e-8)
    np.testing.assert_allclose(sol.reaction_force[0, 0], -sol.reaction_force[1, 0], atol=1e-8)
    np.testing.assert_allclose(sol.reaction_moment, 0.0, atol=1e-12)  # pins carry no moment


def test_closed_ring_diametral_load():
    """A closed ring (a loop closed by a rigid connection) clamped at its bottom node and
    pushed down at its top: by symmetry the bottom section does not rotate, so this
    is the ring under two opposite diametral loads. Roark (Table 9.2, case 1): the diameter
    shortens by (pi/4 - 2/pi) P R^3 / EI. Linear law, small load. The error is second order
    (4.6 %, 1.15 %, 0.29 % at 24, 48, 96 segments), so 96 segments are within 0.5 %."""
    radius, stiffness, load = 0.5, 10.0, 1e-3
    ring = jt.arc_tube("ring", (0, 0, 0), radius, -np.pi / 2, 1.5 * np.pi, 96, 0.05, 2e4,
                       jt.LinearLaw(stiffness), torsion_law=jt.LinearLaw(8.0), normal=(0, -1, 0))
    structure, params = jt.build_structure(
        [ring], [jt.Support("ring:0", "clamped")], [jt.Connection("ring:0", "ring:end")],
        node_force={"ring:48": [0, 0, -load]},
    )
    assert len(structure.closures) == 1
    np.testing.assert_allclose(params.node_position[structure.node_id("ring:48")],
                               [0, 0, radius], atol=1e-12)
    sol = jax.jit(lambda p: jt.equilibrium(structure, p))(params)
    assert bool(sol.converged)
    top = structure.node_id("ring:48")
    shortening = -float(sol.node_position[top, 2] - params.node_position[top, 2])
    expected = (np.pi / 4 - 2 / np.pi) * load * radius**3 / stiffness
    assert shortening == pytest.approx(expected, rel=5e-3)
    np.testing.assert_allclose(sol.reaction_force.sum(0), [0, 0, load], atol=1e-12)


def _hessian_cases():
    """Structures covering every kind of term: chain with torque, line load, self-weight and
    shear deformation under displacement control; an arch clamped at both ends (derived
    clamp joint) with a strut attached; a closed ring (loop closure); a frame with a pinned
    connection."""
    spline = jt.SplineLaw.from_tension_field(150e3, 2e4, 0.075)
    tube = jt.straight_tube("tube", (0, 0, 0), (1.0, 0.2, 0.1), 6, [(0, 0.08), (1, 0.05)],
                            2e4, spline, torsion_law=jt.LinearLaw(40.0),
                            mass_per_length=0.4, line_load=(0.0, 1.0, -2.0),
                            shear_flexibility=5e-5)
    chain = jt.build_structure([tube], [jt.Support("tube:0", "clamped")],
                               node_force={"tube:end": [0.0, 0.0, -20.0]},
                               node_torque={"tube:end": [0.3, -0.2, 0.5]})
    chain_control = (chain[0].node_id("tube:end"), jnp.array([0.0, 0.0, -1.0]), 0.05)
    arch = jt.arc_tube("arch", (0, 0, 0), 1.0, 0.0, np.pi, 8, 0.05, 2e4, jt.LinearLaw(50.0),
                       torsion_law=jt.LinearLaw(40.0), normal=(0, -1, 0))
    strut = jt.straight_tube("strut", (0, 0, 1.0), (0, 0.5, 1.0), 3, 0.03, 2e4,
                             jt.LinearLaw(20.0), torsion_law=jt.LinearLaw(15.0))
    arch_frame = jt.build_structure(
        [arch, strut], [jt.Support("arch:0", "clamped"), jt.Support("arch:end", "clamped")],
        [jt.Connection("arch:4", "strut:0")], node_force={"strut:end": [0, 0, -5.0]})
    ring = jt.arc_tube("ring", (0, 0, 0), 0.5, 0.0, 2 * np.pi, 10, 0.05, 2e4,
                       jt.LinearLaw(30.0), torsion_law=jt.LinearLaw(20.0), normal=(0, 0, 1))
    ring_structure = jt.build_structure([ring], [jt.Support("ring:0", "clamped")],
                                        [jt.Connection("ring:0", "ring:end")],
                                        node_force={"ring:5": [0.0, 3.0, 0.0]})
    post = jt.straight_tube("post", (0, 0, 0), (0, 0, 1.0), 4, 0.05, 2e4, jt.LinearLaw(30.0),
                            torsion_law=jt.LinearLaw(20.0))
    beam = jt.straight_tube("beam", (0, 0, 1.0), (0.8, 0, 1.0), 4, 0.04, 2e4,
                            jt.LinearLaw(25.0), torsion_law=jt.LinearLaw(20.0))
    pinned = jt.build_structure([post, beam], [jt.Support("post:0", "clamped"),
                                               jt.Support("beam:end", "pinned")],
                                [jt.Connection("post:end", "beam:0", "pinned")])
    return [("chain", chain, chain_control), ("arch+strut", arch_frame, None),
            ("ring", ring_structure, None), ("pinned frame", pinned, None)]


# Two cases cover every Hessian term (the ring's closure and the frame's spring-less pinned
# joint use the same code paths as the arch's second clamp and the chain's supports); each
# case costs a compilation of the dense autodiff Hessian, so the others stay out of CI.
@pytest.mark.parametrize("case", range(2), ids=["chain", "arch+strut"])
def test_assembled_hessian_equals_autodiff_hessian(case):
    """The element-assembled Lagrangian Hessian the solver uses is the exact Hessian: it
    equals jax.hessian of E + lambda . c at random states and multipliers (also at zero
    rotation, where the exponential and logarithm maps switch to their Taylor branches)."""
    _, (structure, params), control = _hessian_cases()[case]
    assert_assembled_hessian_is_exact(structure, params, control, seed=case)


def assert_assembled_hessian_is_exact(structure, params, control, seed):
    """The assembled Lagrangian Hessian equals ``jax.hessian`` of ``E + lambda . c`` at the
    undeformed state and at a random one (random multipliers; ``seed`` for both)."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._mechanics import energy_and_constraints as _objective
    from jaxtube._mechanics import lagrangian_hessian

    geometry = reference_geometry(structure, params)
    state0 = jt.initial_state(structure, params)
    z0, unravel = ravel_pytree(state0)
    m = _objective(structure, geometry, state0, params, control)[1].shape[0]
    rng = np.random.default_rng(seed)

    def lagrangian(zz, lam):
        energy, c = _objective(structure, geometry, unravel(zz), params, control)
        return energy + lam @ c

    autodiff = jax.jit(jax.hessian(lagrangian))
    assemble = jax.jit(lambda zz, lam: lagrangian_hessian(structure, geometry, params, control,
                                                          unravel(zz), lam))
    for scale in (0.0, 0.3):
        z = z0 + scale * jnp.asarray(rng.standard_normal(z0.shape))
        lam = jnp.asarray(rng.standard_normal(m)) * 10.0
        expected = autodiff(z, lam)
        assembled = assemble(z, lam)
        assert np.all(np.isfinite(assembled))
        np.testing.assert_allclose(assembled, expected, rtol=1e-9,
                                   atol=1e-9 * float(jnp.max(jnp.abs(expected))))


def test_a_converged_solve_at_the_wrinkling_onset_meets_its_tolerance():
    """Formerly a known defect (strict xfail): a dead tip load of ``M_w / L`` puts the root
    joint of this cantilever exactly on the tension-field law's wrinkling onset after one
    Newton step (with the specimen traced, as in a fit or a sweep). The old stopping rule's
    scale ``max(|grad E|, |J^T lambda|, |H z|)`` exploded there with the law's computed
    second derivative (wrong by up to 5e6 EI within rounding of the onset; fixed in
    ``jaxtube/_laws/tension_field.py``) and reported convergence after one step with the geometric
    nonlinearity lost (7e-5 relative in the root moment). The stopping rule's scale is now
    the largest generalised force of a term (``jaxtube/_solver/newton_kkt.py``)."""
    import equinox as eqx

    from fitting import CantileverRig, TubeModel

    down = np.array([0.0, 0.0, -1.0])

    pressure, radius = 1e4, 0.03
    rig = CantileverRig(segments=12)
    structure, _ = rig.template()
    tip = structure.node_id("tube:end")
    onset_moment = np.pi * pressure * radius**3 / 2  # Comer & Levy M_w [N m]

    @jax.jit
    def solve(pressure, radius):  # traced, as in a fit or a sweep (a knife edge: with the
        # specimen folded in as constants the step lands a rounding error off the onset)
        params = rig.specimen_parameters(TubeModel(jt.TensionFieldLaw(150e3)), pressure,
                                         radius, 1.0)
        moment = jnp.pi * pressure * radius**3 / 2
        force = params.node_force.at[tip].set(jnp.asarray(down) * moment)
        return jt.equilibrium(structure, eqx.tree_at(lambda p: p.node_force, params, force))

    solution = solve(jnp.asarray(pressure), jnp.asarray(radius))
    assert bool(solution.converged)
    # Converged means the KKT residual is at the solver's tolerance (rtol 1e-10 of the
    # moments in play), so the root moment balances F times the deformed lever arm.
    arm = float(solution.node_position[tip][0] - solution.node_position[0][0])
    root_moment = float(jnp.linalg.norm(solution.joint_moment[0, :2]))
    assert abs(root_moment / (onset_moment * arm) - 1) < 1e-8


def test_tension_field_hessian_is_exact_at_the_wrinkling_onset():
    """Within rounding above the onset ``kappa_w`` the law's second derivative is ``EI`` (the
    law is C1 there). Differentiating the energy through the taut half-angle gave
    -5.4e6 EI at ``kappa_w (1 + 4e-16)``; the envelope-theorem derivative gives EI."""
    law = jt.TensionFieldLaw(150e3)
    pressure, radius = 1e4, 0.03
    onset = pressure / (2 * 150e3)
    stiffness = np.pi * 150e3 * radius**3

    def hessian(curvature):
        return jax.hessian(lambda k: law.energy_density(k[0] ** 2 + k[1] ** 2, pressure,
                                                        radius))(jnp.array([curvature, 0.0]))

    for relative in (0.0, 4e-16, 1e-14, 1e-12, 1e-10):
        curvature = onset * (1 + relative)
        slope = float(jax.grad(lambda k: law.moment(k, pressure, radius))(curvature))
        # Near the onset the half-angle a(kappa) is ill-conditioned (pi - a ~ sqrt(2 (kappa /
        # kappa_w - 1)) ~ 3e-8 at 4e-16): both routes carry ~eps / (pi - a) ~ 4e-9
        # relative rounding, hence 1e-8 (measured: 1.7e-9 and 1.3e-9 at 4e-16 and 1e-14).
        np.testing.assert_allclose(float(hessian(curvature)[0, 0]), slope,
                                   rtol=1e-8)
        assert abs(slope / stiffness - 1) < 1e-4


def test_secant_predictor_same_path_fewer_newton_steps():
    """``solve_path``'s secant predictor (the last two solutions extrapolated to the next
    step) against the plain warm start from the last solution, on a displacement-controlled
    tension-field cantilever through wrinkling and collapse: every step converges with both,
    the curves are the same equilibria (to the solver's tolerance), and the secant start saves
    Newton steps (it starts at a distance of second order in the step, not first)."""
    law = jt.TensionFieldLaw(150e3, residual_stiffness_ratio=0.01)
    structure, params = jt.cantilever(1.0, 0.075, 2e4, 10, law, jt.LinearLaw(150.0))
    tip = structure.node_id("tube:end")
    path = jt.DisplacementControl(tip, [0, 0, -1], jnp.linspace(0.02, 0.4, 20))
    runs = {name: jax.jit(lambda p, name=name: jt.solve_path(structure, p, path,
                                                            predictor=name))(params)
            for name in ("secant", "previous")}
    for name, sol in runs.items():
        assert bool(np.all(sol.converged)), name
    np.testing.assert_allclose(runs["secant"].control_force, runs["previous"].control_force,
                               rtol=1e-8)
    np.testing.assert_allclose(runs["secant"].node_position, runs["previous"].node_position,
                               atol=1e-9)
    regimes = np.asarray(runs["secant"].joint_regime)
    assert regimes.max() == 2  # the path goes through collapse
    steps = {name: int(np.sum(sol.iterations)) for name, sol in runs.items()}
    assert steps["secant"] < 0.85 * steps["previous"], steps
    with pytest.raises(ValueError, match="predictor"):
        jt.solve_path(structure, params, path, predictor="tangent")
