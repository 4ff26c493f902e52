"""The use cases: what a command does end to end, wiring the layers below together.

- :mod:`.wearer`: ``calibrate perceptual`` (who answers, the belt on the right clock, the
  profile kept);
- :mod:`.calibration_effect`: the model participant's errors with and without its wearer
  profile (docs/calibration-perceptual.md).

(``tactorbelt.launch``, the ``run`` use case, and ``tactorbelt.demo`` still stand beside
this package.)
"""
