"""Analysis of session stores: tables, statistics, figures and the HTML report.

Rooms (import-linter layers, docs/architecture.md; each imports only the rooms below it):

- ``report/``: :func:`report.analyze.analyze` (stores in; report.html, summary.json,
  per_target.csv and PNGs out), the HTML rendered from ``report/templates/``, the
  figures, the console table.
- ``summary``: :func:`summary.summarize`, the pure computation behind the report, and
  its :class:`summary.Summary`.
- ``models/``: the mixed models: :func:`models.fit.fit_model` (the one public fit), the
  GLMM and LMM (``glmm``), likelihood-ratio and bootstrap tests (``lrt``),
  Satterthwaite df, contrasts, separation, R's lme4 (``lme4``).
- ``tables/``: loading stores (``load``, ``dataset``), the study design, the descriptive
  tables, cells and information transfer, the classical tests, secondary tasks.

Nothing is re-exported here: import a name from the module that owns it. Never imports
devices, inputs or the window.
"""
