"""The semantics core of RSSM, shared by every backend.

One definition of each run-time concept: the value domain and its arithmetic
(:mod:`rssm_core.values`), the four producer/consumer communication modes
(:mod:`rssm_core.modes`), the firing rule of the flat net (:mod:`rssm_core.firing`) and the
trace format (:mod:`rssm_core.trace`). The interpreter (``rssmc simulate``), the verifier and
the renderer import these modules; ``rssmc ros2`` ships the very same files in the generated
workspace (package ``<system>_runtime`` installs ``rssm_core`` beside it), so a generated node
computes what the interpreter computes.

The package depends on the Python standard library and numpy only, and its modules import
each other relatively, so that it can be copied as it is.
"""
