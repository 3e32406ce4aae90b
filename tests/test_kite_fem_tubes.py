"""kite_fem beams as jaxtube tubes (chains, radii, junctions), the spring groups, and the
scaled law. Pure NumPy and single law evaluations: no structure is compiled here."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._io.kite_fem_tubes import beam_chains, chain_junctions, spring_groups

V3_MODEL = (Path(__file__).parents[1] / "experiments" / "data" / "v3_hanging" / "kite_fem"
            / "initial.npz")


def test_v3_chains():
    model = jt.read_kite_fem(V3_MODEL)
    chains = beam_chains(model.beam_nodes, model.beam_diameter, model.beam_pressure_bar)
    assert len(chains) == 11
    leading_edge = chains[-1]
    assert leading_edge.nodes == tuple(range(1, 58, 2))
    assert [c.nodes[0] for c in chains[:10]] == [1, 7, 13, 19, 25, 33, 39, 45, 51, 57]
    assert all(len(c.nodes) == 7 for c in chains[:10])
    assert sorted(r for c in chains for r in c.beam_rows) == list(range(88))
    # Radii: each end takes its beam's, an inner node the mean of its two beams'.
    d = model.beam_diameter[list(leading_edge.beam_rows)]
    np.testing.assert_allclose(leading_edge.radius[[0, -1]], 0.5 * d[[0, -1]])
    np.testing.assert_allclose(leading_edge.radius[5], 0.25 * (d[4] + d[5]))
    junctions = chain_junctions(chains)
    # Every chordwise chain is attached to the leading edge at its first node.
    assert len(junctions) == 10
    for (first, _), (second, index) in junctions:
        assert second == "beams_1_57" and first.startswith("beams_")
    assert (("beams_1_2", 0), ("beams_1_57", 0)) in junctions
    assert (("beams_7_8", 0), ("beams_1_57", 3)) in junctions


def test_chains_split_where_the_file_breaks_them():
    beams = np.array([[0, 1], [1, 2], [5, 6], [2, 3], [3, 7], [7, 2]])  # [7, 2]: a loop
    chains = beam_chains(beams, np.full(6, 0.1), np.full(6, 0.2))
    assert [c.nodes for c in chains] == [(0, 1, 2), (5, 6), (2, 3, 7), (7, 2)]
    assert chain_junctions(chains) == [(("beams_0_2", 2), ("beams_2_7", 0)),
                                       (("beams_2_7", 2), ("beams_7_2", 0)),
                                       (("beams_0_2", 2), ("beams_7_2", 1))]
    chains = beam_chains(np.array([[0, 1], [1, 2]]), [0.1, 0.2], [0.2, 0.3])
    assert [c.nodes for c in chains] == [(0, 1), (1, 2)]  # one pressure per tube


def test_v3_spring_groups():
    model = jt.read_kite_fem(V3_MODEL)
    groups = np.array(spring_groups(model.spring_nodes, model.beam_nodes))
    # The file lists the 618 canopy springs first, then the 46 bridle lines (README).
    assert np.all(groups[:618] == "canopy") and np.all(groups[618:] == "bridle")


def test_scaled_law():
    base = jt.EmpiricalBendingLaw2011()
    law = jt.ScaledLaw(base, 0.3)
    kappa, p, r = jnp.linspace(0.0, 2.0, 7), 1.5e4, 0.08
    np.testing.assert_allclose(law.moment(kappa, p, r), 0.3 * base.moment(kappa, p, r))
    np.testing.assert_allclose(law.energy_density(kappa**2, p, r),
                               0.3 * base.energy_density(kappa**2, p, r))
    np.testing.assert_allclose(law.initial_stiffness(p, r), 0.3 * base.initial_stiffness(p, r))
    np.testing.assert_array_equal(law.regime(kappa, p, r), base.regime(kappa, p, r))
    # dW/dkappa = M, and the factor is differentiable.
    grad = jax.grad(lambda k: law.energy_density(k**2, p, r))(0.7)
    assert float(grad) == pytest.approx(float(law.moment(0.7, p, r)), rel=1e-10)
    d_factor = jax.grad(lambda s: jt.ScaledLaw(base, s).moment(0.7, p, r))(0.3)
    assert float(d_factor) == pytest.approx(float(base.moment(0.7, p, r)), rel=1e-12)


def test_curvature_scaled_law_keeps_the_moments_and_softens():
    """``CurvatureScaledLaw``: ``M(kappa) = M_base(s kappa)``: stiffness x s at zero, the
    same moments (the collapse plateau) reached at curvatures / s; dW/dkappa = M (also at
    zero curvature, gradient and curvature of the energy finite there)."""
    base, s = jt.EmpiricalBendingLaw2011(), 0.4
    law = jt.CurvatureScaledLaw(base, s)
    kappa, p, r = jnp.linspace(0.0, 3.0, 13), 1.5e4, 0.08
    np.testing.assert_allclose(law.moment(kappa / s, p, r), base.moment(kappa, p, r),
                               rtol=1e-12)
    np.testing.assert_array_equal(law.regime(kappa / s, p, r), base.regime(kappa, p, r))
    assert float(law.initial_stiffness(p, r)) == pytest.approx(
        s * float(base.initial_stiffness(p, r)), rel=1e-12)
    slope = jax.grad(lambda k: law.moment(k, p, r))(0.0)
    assert float(slope) == pytest.approx(float(law.initial_stiffness(p, r)), rel=1e-9)
    for k in (0.0, 0.3, 2.5, 6.0):
        grad = jax.grad(lambda x: law.energy_density(x**2, p, r))(k)
        assert float(grad) == pytest.approx(float(law.moment(k, p, r)), rel=1e-10, abs=1e-12)
    curvature = jax.hessian(lambda x: law.energy_density(x**2, p, r))(0.0)
    assert float(curvature) == pytest.approx(float(law.initial_stiffness(p, r)), rel=1e-9)
    # The largest moment in reach is the base law's, not s times it.
    far = jnp.asarray(40.0)
    assert float(law.moment(far / s, p, r)) == pytest.approx(float(base.moment(far, p, r)),
                                                             rel=1e-12)
