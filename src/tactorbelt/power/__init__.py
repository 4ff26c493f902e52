"""Power analysis: how many participants a study needs to find its effect.

``tactorbelt power`` runs :func:`.study.run_power_study`. The study is read once, into
one design object that every analysis takes:

- :mod:`.design`: :class:`~.design.PowerDesign` (``PowerDesign.from_study(study)``: the
  layout, the acquisition radius, the stimulus, and each test block's condition, target
  count, repetitions, load and stimulus) and the views the analyses simulate: the fast
  path's protocols (one target count, or one per count with the loads) and
  :class:`~.design.TrialDesign` (one participant's counted test trials);
- :mod:`.effects`: the effect to look for (``--effect``: dynamic vs static, at N targets,
  the interaction, a load);
- :mod:`.simulation`: power with model participants (docs/participant-model.md) for the
  paper's test and any design and effect (:func:`~.simulation.run_power`), the paired
  Wilcoxon and Friedman tests;
- :mod:`.glmm`: power of the report's accuracy GLMM for effect sizes the user names
  (``--odds-ratio``; :func:`~.glmm.named_power`);
- :mod:`.outcomes`: a simulated study's outcome, the power at one size and its
  Clopper-Pearson interval; :mod:`.pool`: simulated studies in chunks, in processes;
- :mod:`.study`: the orchestration and the files (power.csv, power.json, power.png).

Every simulated study is seeded by ``(seed, N, index)``: results do not depend on
``--jobs``. The package imports nothing until a module is used.
"""
