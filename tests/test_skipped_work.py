"""The Newton iteration does not execute work a pass does not need
(``jaxtube._solver.kkt_step.unless``): every KLU solve the compiled program executes is one
the iteration asked for, a regularised step's or a second-order correction's.

Counted two ways on the small test kite hung on the augmented (KLU) route: the KLU custom
calls the program executes, from a ``jax.profiler`` trace of one warm run, and the solves
asked for, from host callbacks beside each (a callback has a side effect, so XLA never moves
or drops it). Written as a plain while-loop of at most one pass, XLA moved the line search's
correction out of its loop and ran it on every pass of the iteration (two fifths of the V3
hang's time): the first count then exceeds the second.
"""

import collections
import gzip
import json
from pathlib import Path

import jax
import pytest

import jaxtube as jt
from jaxtube._solver import newton_kkt

from .kite_fem_mini import SUSPENSION, write_mini_kite


def _executed_custom_calls(trace_dir: Path) -> collections.Counter:
    """``{HLO instruction name: executions}`` of the ``ffi_call`` thunks in a profiler trace."""
    traces = sorted(trace_dir.rglob("*.trace.json.gz"))
    assert traces, f"no profiler trace written under {trace_dir}"
    events = json.loads(gzip.open(traces[-1]).read())["traceEvents"]
    return collections.Counter(e["name"] for e in events
                               if e.get("ph") == "X" and e["name"].startswith("ffi_call"))


def test_every_klu_solve_executed_is_one_the_iteration_asked_for(tmp_path, monkeypatch):
    path = tmp_path / "mini.npz"
    write_mini_kite(path)
    imported = jt.import_kite_fem(path, suspension=SUSPENSION, centre_node=3,
                                  centre_load_kg=0.2, tip_nodes=(7, 9),
                                  tip_load_kg=0.05)
    asked = collections.Counter()

    def counted(name, function):
        def wrapper(*args, **kwargs):
            result = function(*args, **kwargs)
            jax.debug.callback(lambda _: asked.update([name]), jax.tree.leaves(result)[0])
            return result
        return wrapper

    monkeypatch.setattr(newton_kkt, "regularised_step",
                        counted("step", newton_kkt.regularised_step))
    monkeypatch.setattr(newton_kkt, "second_order_correction",
                        counted("correction", newton_kkt.second_order_correction))
    solver = jt.NewtonKKT(linear_solver="augmented", max_steps=200)
    hang = jax.jit(lambda p: jt.hang_kite(imported.structure, p, steps=2, solver=solver))
    jax.block_until_ready(hang(imported.params))  # compile
    asked.clear()
    trace_dir = tmp_path / "trace"
    with jax.profiler.trace(str(trace_dir)):
        solution = jax.block_until_ready(hang(imported.params))
    assert bool(solution.converged.all())
    executed = _executed_custom_calls(trace_dir)
    if not executed:
        pytest.fail("the profiler trace holds no ffi_call events: the trace format changed")
    steps = int(solution.iterations.sum())
    assert asked["step"] >= steps > 0
    assert sum(executed.values()) == asked["step"] + asked["correction"], (
        f"KLU solves executed {dict(executed)}, asked for {dict(asked)} over {steps} Newton "
        f"steps")
