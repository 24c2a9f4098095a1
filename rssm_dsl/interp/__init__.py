"""The HPN interpreter behind `rssmc simulate` (docs/simulate.md).

    comp = compile_file(path)
    rt = build_runtime(comp, RunConfig(base_dir=path.parent))     # bindings, devices
    result = Simulator(rt, SimOptions(seed=1, max_steps=10_000)).run()

Modules: values (representation of values), compile_expr (expressions to closures),
program (binding the flat net to operations and conditions), engine (token game), codegen
(firing rules and macro steps compiled to Python), clock, channels, state, scheduler
(deterministic and concurrent runs), trace, summary, device (the device interface), replay
(verifier counterexamples and traces).
"""

from rssm_dsl.interp.program import RunConfig, Runtime, build_runtime
from rssm_dsl.interp.scheduler import RunResult, SimOptions, Simulator

__all__ = ["RunConfig", "RunResult", "Runtime", "SimOptions", "Simulator", "build_runtime"]
