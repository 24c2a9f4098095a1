"""The HPN interpreter behind `rssmc simulate` (docs/simulate.md).

    comp = compile_file(path)
    rt = build_runtime(comp, RunConfig(base_dir=path.parent))     # bindings, devices
    result = Simulator(rt, SimOptions(seed=1, max_steps=10_000)).run()

Modules: values (representation of values), compile_expr (expressions to closures),
program (binding the flat net to operations and conditions), engine (token game), codegen
(firing rules and macro steps compiled to Python), clock, channels, state, scheduler
(deterministic and concurrent runs), trace, summary, device (the device interface), replay
(verifier counterexamples and traces).

The names below are imported when first used, so that a device module importing
``rssm_dsl.interp.device`` (the device interface) does not load the compiler with them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rssm_dsl.lazy import lazy_names

if TYPE_CHECKING:
    from rssm_dsl.interp.program import RunConfig, Runtime, build_runtime
    from rssm_dsl.interp.scheduler import RunResult, SimOptions, Simulator

__all__ = ["RunConfig", "RunResult", "Runtime", "SimOptions", "Simulator", "build_runtime"]
_MODULE = {"RunConfig": "program", "Runtime": "program", "build_runtime": "program",
           "RunResult": "scheduler", "SimOptions": "scheduler", "Simulator": "scheduler"}

__getattr__ = lazy_names(__name__, _MODULE)
