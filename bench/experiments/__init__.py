"""pocketray's experiments: one module per experiment, run by ``bench/experiments.py``.

Every module has ``NAME``, ``TITLE`` and ``run(ctx) -> str``: it measures, saves its
charts through ``ctx.savefig`` and its raw data through ``ctx.save_data``, and returns
the Markdown fragment that ``bench/experiments.py`` puts into ``RESULTS.md``.
"""

# In the order they appear in RESULTS.md.
EXPERIMENTS = ("table_4_2", "fig_4_4", "fig_4_5", "scaling", "crossover", "peers", "pareto", "specialize",
               "ray_engines", "dynamic", "cost", "scheduling", "shader", "hardening", "meshes")
