"""How close the paper-form law gets to a study design's noise floor: from the physics
guess (as the diagnosis' baseline starts), from the best of several starts, and with the
design's hidden effects fixed at their true sizes (docs/diagnosis-study.md, "Why the final
model missed the noise floor").

The last fit is the ceiling of the diagnosis on that design: the model with the hidden
physics in it, exactly sized. Where it stays above 1.3x the floor, the law's form (three
pivots, ``A (p r^3)^B``) cannot follow the tension-field truth at that design's specimens,
and no decision rule can name the hidden effect by the fit it brings. Each fit frees
every law coordinate (pivots (1,1,1)), the candidates held at their null unless hidden;
coordinates that end on their box bounds (:data:`fitting._calibrate.problem.EXPONENT_BOUNDS`,
a factor ``SCALE_RANGE`` about the guess for the scales) are listed.

    python -m experiments.law_ceiling                 # design 13 of seed 0
    python -m experiments.law_ceiling --index 41 --starts 4
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from experiments._study_design import add_design_arguments, design_setup
from fitting._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from fitting._bench.scaling import PivotScaling
from fitting._calibrate.fit import fit_problem
from fitting._calibrate.problem import make_problem
from fitting._diagnose.restart import on_box_bounds
from fitting._diagnose.score import chi2, parameter_names


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_design_arguments(parser, 13)
    parser.add_argument("--starts", type=int, default=6,
                        help="starts of the multistart fit (default 6)")
    args = parser.parse_args(argv)
    setup = design_setup(args.index, args.seed, args.iterations)
    design, floor, fit_options = setup.design, setup.noise_floor_N, setup.fit_options
    problem = make_problem(setup.data, PivotScaling(), CantileverRig(segments=DEFAULT_SEGMENTS),
                           fit_options, effects=setup.candidates)
    law = list(problem.free_names)
    print(f"{'fit':<48}{'RMSE/floor':>11}{'chi2':>9}{'s':>6}  on a bound")

    def run(label, vector, options):
        started = time.perf_counter()
        result = fit_problem(problem.with_free(law, vector), options)
        print(f"{label:<48}{result.rmse / floor:>11.2f}{chi2(result):>9.1f}"
              f"{time.perf_counter() - started:>6.0f}  {', '.join(on_box_bounds(result)) or '-'}")
        return result

    run("from the physics guess (the baseline's start)", problem.base, fit_options)
    best = run(f"best of {args.starts} starts", problem.base,
               dataclasses.replace(fit_options, multistart=args.starts))
    if design.hidden:
        truth = np.array(best.vector, float)
        # Each physical effect has one parameter, in the units its size is drawn in.
        parameter = {c.name: parameter_names(c)[0] for c in setup.candidates}
        for effect, size in design.hidden:
            truth[problem.names.index(parameter[effect])] = size
        run("hidden effects at their true size, law refit", truth, fit_options)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
