"""The use cases: what a command does end to end, wiring the layers below together.

- :mod:`.run`: ``run`` (the session and resume policy, the display check, the clock, the
  summary), :func:`~.run.run_study`;
- :mod:`.wearer`: ``calibrate perceptual`` (who answers, the belt on the right clock, the
  profile kept);
- :mod:`.demo`: ``demo`` (a model study of N participants); ``power`` is
  :mod:`tactorbelt.power`.
"""
