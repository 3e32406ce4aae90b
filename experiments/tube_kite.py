# %% [markdown]
# # The static kite test of Breukels & Ockels (2008)
#
# A surf kite's leading-edge tube (one envelope, double tapered, 0.25 bar) fixed at both
# wing tips with the arc upright, its crown pushed down in displacement control through
# wrinkling. The paper measured about 0-70 N over 0-140 mm on its kite; its geometry is not
# given in the paper, so this kite (span 2.6 m, arc height 1.0 m, radius 85 mm at the
# centre to 45 mm at the tips, tension-field law E t = 150 kN/m, 0.25 kg/m self-weight) is
# a stand-in of the same kind, not a reproduction of the specimen.
#
# Writes into ``experiments/results/tube_kite/`` (``--out``):
#
# - ``curve.csv``: per step the crown displacement [mm], actuator force [N], wrinkled and
#   collapsed joint counts, convergence;
# - ``wrinkling.csv``: per joint its arc-length position [m], radius [m], the first step and
#   crown displacement at which it wrinkled and collapsed;
# - ``deformed_kite.png`` (3-D, joints coloured by regime, supports and actuator drawn) and
#   ``force_deflection.png``.
#
# ``--struts 4`` adds four chordwise struts (0.3 bar) to the leading edge.
#
# Run from the repository root: ``python -m experiments.tube_kite [--struts 4]``.

# %%
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

PRESSURE = 2.5e4  # Pa
WALL_MODULUS = 150e3  # E t [N/m]


def build_kite(segments: int, struts: int, strut_mass_per_length: float = 0.0) -> jt.TubeKite:
    """The stand-in kite: ``segments`` on the leading edge, ``segments // 4`` on each strut
    (weightless unless ``strut_mass_per_length`` [kg/m] is given: the dynamics needs it)."""
    law = jt.TensionFieldLaw(WALL_MODULUS, residual_stiffness_ratio=0.01)
    fractions = (np.arange(struts) + 1.0) / (struts + 1.0)
    return jt.TubeKite(
        segments=segments, radius=jt.double_taper(0.085, 0.045), pressure=PRESSURE,
        bending_law=law, torsion_law=jt.LinearLaw(150.0), span=2.6, arc_height=1.0,
        mass_per_length=0.25,
        struts=tuple(jt.Strut(float(f), 0.7, ((0.0, 0.055), (1.0, 0.028)), segments // 4,
                              pressure=3e4, mass_per_length=strut_mass_per_length)
                     for f in fractions))


def joint_nodes(structure, params) -> np.ndarray:
    """Node of every spring joint, in the order of ``Solution.joint_regime`` (static)."""
    return np.asarray(structure.spring_joint_topology().node)


def first_step(regime: np.ndarray, level: int) -> np.ndarray:
    """Per joint, the first step index at which its regime reaches ``level`` (-1: never)."""
    reached = regime >= level
    return np.where(reached.any(axis=0), reached.argmax(axis=0), -1)


# %%
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="The static kite test (Breukels & Ockels "
                                                 "2008): force against crown deflection.")
    parser.add_argument("--segments", type=int, default=24, help="leading-edge segments")
    parser.add_argument("--struts", type=int, default=0, help="number of struts")
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--max-deflection-mm", type=float, default=140.0)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent
                        / "results" / "tube_kite")
    args = parser.parse_args(argv)

    kite = build_kite(args.segments, args.struts)
    structure, params = kite.build()
    crown = structure.node_id(kite.node("le:centre"))
    displacements = np.linspace(0.0, args.max_deflection_mm * 1e-3, args.steps + 1)[1:]
    path = jt.DisplacementControl(crown, [0.0, 0.0, -1.0], jnp.asarray(displacements))
    solution = jax.jit(lambda p: jt.solve_path(structure, p, path))(params)
    converged = np.asarray(solution.converged)
    force = np.asarray(solution.control_force)
    regime = np.asarray(solution.joint_regime)  # [K, J]
    moment = np.linalg.norm(np.asarray(solution.joint_moment)[..., :2], axis=-1)  # [K, J]
    nodes = joint_nodes(structure, params)

    # Where wrinkling starts: the first wrinkled joint against the joint of largest moment.
    radius = np.asarray(params.node_radius)[nodes]
    onset_moment = np.pi * PRESSURE * radius**3 / 2.0  # Comer & Levy M_w at each joint
    le_ids = list(structure.tube_node_ids[0])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(
        np.asarray(params.node_position)[le_ids], axis=0), axis=1))])
    position = {n: arc[k] for k, n in enumerate(le_ids)}
    wrinkled_at, collapsed_at = first_step(regime, 1), first_step(regime, 2)
    lines = [f"tube kite: {structure.segment_count} segments, {args.struts} struts, "
             f"{int(converged.sum())}/{converged.size} steps converged; peak force "
             f"{force[converged].max():.1f} N"]
    if np.any(wrinkled_at >= 0):
        k0 = int(wrinkled_at[wrinkled_at >= 0].min())
        first = np.flatnonzero(wrinkled_at == k0)
        largest = int(np.argmax(moment[k0 - 1] if k0 else moment[k0]))
        ratio = int(np.argmax((moment[k0 - 1] if k0 else moment[k0]) / onset_moment))
        lines.append(f"wrinkling starts at step {k0 + 1} ({displacements[k0] * 1e3:.1f} mm, "
                     f"{force[k0]:.1f} N) at joint(s) on node(s) {nodes[first].tolist()}")
        lines.append(f"  the step before, the largest |M| was at node {nodes[largest]} "
                     f"(r = {radius[largest] * 1e3:.0f} mm) and the largest M / M_w at node "
                     f"{nodes[ratio]} (r = {radius[ratio] * 1e3:.0f} mm)")
        for k in np.unique(wrinkled_at[wrinkled_at >= 0]):
            spread = nodes[wrinkled_at == k].tolist()
            lines.append(f"  step {k + 1:3d} ({displacements[k] * 1e3:6.1f} mm): wrinkling "
                         f"reaches nodes {spread}")
    for line in lines:
        print(line)

    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "curve.csv", "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["step", "crown_displacement_mm", "force_N", "joints_wrinkled",
                         "joints_collapsed", "converged"])
        for k in range(converged.size):
            writer.writerow([k + 1, f"{displacements[k] * 1e3:.6g}", f"{force[k]:.6g}",
                             int((regime[k] == 1).sum()), int((regime[k] == 2).sum()),
                             int(converged[k])])
    with open(args.out / "wrinkling.csv", "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["joint", "node", "tube", "le_arc_position_m", "radius_m",
                         "first_wrinkled_step", "wrinkled_at_mm", "first_collapsed_step"])
        for j, node in enumerate(nodes):
            tube = next(structure.tube_names[t] for t, ids in enumerate(structure.tube_node_ids)
                        if node in ids)
            k1, k2 = int(wrinkled_at[j]), int(collapsed_at[j])
            writer.writerow([j, int(node), tube, f"{position.get(int(node), np.nan):.6g}",
                             f"{radius[j]:.6g}", k1 + 1 if k1 >= 0 else "",
                             f"{displacements[k1] * 1e3:.6g}" if k1 >= 0 else "",
                             k2 + 1 if k2 >= 0 else ""])
    (args.out / "summary.txt").write_text("\n".join(lines) + "\n")
    jt.force_deflection_figure(displacements * 1e3, force, regime.max(axis=1), converged,
                            title="tube kite: crown pushed down, tips clamped",
                            xlabel="crown deflection [mm]").savefig(
        args.out / "force_deflection.png", dpi=120)
    jt.deformed_shape_figure(
        structure, np.asarray(params.node_position), np.asarray(solution.node_position),
        converged, joint_node=nodes, joint_regime=regime,
        control=(crown, np.array([0.0, 0.0, -1.0]), force),
        distributed=np.broadcast_to(np.asarray(params.mass_per_length)[:, None]
                                    * np.asarray(params.gravity), (converged.size,
                                                                   len(structure.tube_names), 3)),
        title="tube kite at the last step").savefig(args.out / "deformed_kite.png", dpi=120)
    print(f"wrote curve.csv, wrinkling.csv, summary.txt and figures to {args.out}")
    return 0 if converged.all() else 1


if __name__ == "__main__":
    sys.exit(main())
