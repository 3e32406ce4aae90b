"""How finely the spline law must be pivoted to follow the tension-field tube of the
diagnosis study (docs/diagnosis-study.md, "Why the final model missed the noise floor").

One study design (default ``design_0_0084``: three specimens at 0.35 bar, r 100 mm, L 1 m,
10 points each, force noise 0.08 N, nothing hidden) is fitted with the paper-form law at
pivots (1,1,1), (2,2,1) and (3,3,1) per regime, each layout started from the last one's
optimum (:func:`fitting._diagnose.refinement.refined_start`), every pivot coordinate the
data determine free, the candidates held at their null; the RMSE is printed against the
design's noise floor.

    python -m experiments.pivot_resolution            # design 84 of seed 0
    python -m experiments.pivot_resolution --index 53
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from experiments._study_design import add_design_arguments, design_setup
from fitting._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from fitting._bench.scaling import PivotScaling
from fitting._calibrate.fit import fit_problem
from fitting._calibrate.problem import make_problem
from fitting._diagnose.refinement import refined_scaling, refined_start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_design_arguments(parser, 84)
    args = parser.parse_args(argv)
    setup = design_setup(args.index, args.seed, args.iterations)
    data, candidates, fit_options = setup.data, setup.candidates, setup.fit_options
    rig = CantileverRig(segments=DEFAULT_SEGMENTS)
    single = len({curve.pressure * curve.radius**3 for curve in data}) == 1
    scaling, previous = PivotScaling(), None
    print(f"{'pivots':<10}{'RMSE [N]':>10}{'/ floor':>9}{'iterations':>12}{'s':>6}")
    for _ in range(3):
        problem = make_problem(data, scaling, rig, fit_options, effects=candidates)
        # At a single p r^3 the exponents change nothing: only the increments are fitted.
        names = [n for n in scaling.names() if n.endswith(".A") or not single]
        start = (np.array(problem.base, float) if previous is None
                 else refined_start(previous, problem))
        started = time.perf_counter()
        result = fit_problem(problem.with_free(names, start), fit_options)
        layout = ",".join(str(n) for n in scaling.pivots_per_regime)
        print(f"({layout}){'':<3}{result.rmse:>10.4g}{result.rmse / setup.noise_floor_N:>9.2f}"
              f"{result.convergence.iterations:>12}{time.perf_counter() - started:>6.0f}")
        previous, scaling = result, refined_scaling(scaling)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
