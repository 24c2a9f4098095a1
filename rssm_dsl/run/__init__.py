"""`rssmc run`: the paper's section V experiment on the simulated LWR4+ (docs/run.md).

    comp = compile_file(path)
    experiment = run_experiment(comp, RunOptions(until=30.0))
    files = output_files(experiment)                  # trajectory.csv, fig19.png, summary.json

Modules: rig (the LWR4+ device, its virtual effector and the set points it tracks, found in
the compiled system), recorder (samples every device step), experiment (builds and runs the
interpreter on simulated time), metrics (tracking error, circle fit), report (CSV, JSON and
text summary), plot (the paper's Fig. 19), video (offscreen rendering), viewer (MuJoCo's
passive viewer).
"""

from rssm_dsl.run.experiment import Experiment, RunError, RunOptions, run_experiment
from rssm_dsl.run.report import output_files, summary_text

__all__ = ["Experiment", "RunError", "RunOptions", "output_files", "run_experiment",
           "summary_text"]
