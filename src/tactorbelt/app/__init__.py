"""The use cases: what a command does end to end, wiring the layers below together.

- :mod:`.run`: ``run`` (the session's seam assembled, the display check, the summary),
  :func:`~.run.run_study`; :mod:`.request`: its options and their rules (session,
  resume, clock);
- :mod:`.wearer`: ``calibrate perceptual`` (who answers, the belt on the right clock, the
  profile kept);
- :mod:`.demo`: ``demo`` (a model study of N participants); ``power`` is
  :mod:`tactorbelt.power`.
"""
