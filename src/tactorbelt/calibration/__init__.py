"""Calibration: making a belt and a wearer agree with what the software renders.

- :mod:`.motor`: a belt's motors (one-tactor pulses, the walk-through that finds each
  tactor's start level and comfortable ceiling; the file format is
  :mod:`tactorbelt.devices.calibration`);
- :mod:`.wearer`: a wearer's perceptual profile (per-tactor gains, per-pair warps),
  :class:`~.wearer.WearerProfile`;
- :mod:`.perceptual`: the procedure that measures that profile (QUEST+ tracks and their
  fits) and the runner's hook for studies that require one.

Layer: above the devices and the player, below inputs, the window and the experiment.
"""
