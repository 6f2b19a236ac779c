"""pocketray's experiments: one module per experiment, run by ``python -m bench.experiments``.

Every module has ``NAME``, ``TITLE`` and three steps:

- ``measure(ctx) -> dict``: measures (``ctx`` is a :class:`~.context.Context`) and returns
  the raw data, JSON-able; the runner saves it as ``figures/NAME.json`` with the run's
  :class:`~.context.RunInfo` under ``"run"``;
- ``plot(data, figures, quick) -> {chart: alt text}`` (when it has charts): draws them from
  the saved data;
- ``report(data, run, charts) -> str``: the Markdown section, from the saved data only.

So ``--replot`` writes the same sections and charts from ``figures/*.json`` without
measuring. Shared pieces, one job each: ``context`` (the run), ``timing``, ``machine``,
``scenes`` (settings and scene helpers), ``images``, ``cache``, ``data`` (the JSON files),
``markdown``, ``style`` (charts), ``results`` (RESULTS.md).
"""

from .llvm import use_llvm19

use_llvm19()  # before anything imports mitsuba (bench/experiments/llvm.py says why)

# In the order they appear in RESULTS.md.
EXPERIMENTS = (
    "table_4_2",
    "fig_4_4",
    "fig_4_5",
    "scaling",
    "crossover",
    "peers",
    "peers_path",
    "first_hits",
    "pareto",
    "path",
    "specialize",
    "ray_engines",
    "dynamic",
    "cost",
    "scheduling",
    "shader",
    "hardening",
    "hardening2",
    "meshes",
    "shapes",
    "denoise",
    "client",
    "refine",
    "phone",
    "materials",
)
