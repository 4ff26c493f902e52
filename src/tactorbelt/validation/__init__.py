"""Validation of a belt's timing against a sensor, before a study (docs/validation.md).

``tactorbelt validate onsets`` pulses each tactor, senses the vibration with time stamps
on the commands' clock, and reports per tactor the latency (command to 10 % of the steady
vibration), the 10-90 % rise, the 90-10 % fall and the amplitude against level:

- :mod:`.envelope`: the envelope estimator, crossings, per-pulse and per-tactor
  statistics (pure NumPy);
- :mod:`.sensors`: the sensor registry (``model``, ``audio:DEVICE?channel=N``, ``board``)
  and the sensors;
- :mod:`.run`: the procedure (:func:`validate_onsets`) and the command as a function
  (:func:`run_onsets`);
- :mod:`.figure`: the figure.

The measured latencies go into the belt's calibration file
(:meth:`tactorbelt.devices.calibration.Calibration.skin_latency` reads them back).
"""

from __future__ import annotations

from .run import NoPulseError, OnsetSettings, OnsetValidation, run_onsets, validate_onsets
from .sensors import SENSORS, Sensor, open_sensor

__all__ = ["SENSORS", "NoPulseError", "OnsetSettings", "OnsetValidation", "Sensor",
           "open_sensor", "run_onsets", "validate_onsets"]
