"""Validation of a belt's timing against a sensor, before a study (docs/validation.md).

``tactorbelt validate onsets`` pulses each tactor, senses the vibration with time stamps
on the commands' clock, and reports per tactor the latency (command to 10 % of the steady
vibration), the 10-90 % rise, the 90-10 % fall and the amplitude against level:

- :mod:`.envelope`: the envelope estimator, crossings, per-pulse and per-tactor
  statistics (pure NumPy);
- :mod:`.registry`: the sensor registry (``model``, ``audio:DEVICE?channel=N``,
  ``board``), without NumPy; :mod:`.sensors`: the sensors;
- :mod:`.run`: the procedure (:func:`validate_onsets`) and the command as a function
  (:func:`run_onsets`);
- the figures: :func:`.run.onset_figure`, :func:`.stimulus.stimulus_figure`.

The measured latencies go into the belt's calibration file
(:meth:`tactorbelt.devices.calibration.Calibration.skin_latency` reads them back).

The names below load their module when first used, so that the registry (and the
command's ``--help``) does not import NumPy.
"""

from __future__ import annotations

from .._registry import lazy_attributes

__all__ = ["SENSORS", "NoPulseError", "OnsetSettings", "OnsetValidation", "Sensor",
           "open_sensor", "run_onsets", "validate_onsets"]

__getattr__ = lazy_attributes(__name__, {
    "SENSORS": ".registry", "NoPulseError": ".run", "OnsetSettings": ".run",
    "OnsetValidation": ".run", "Sensor": ".sensors", "open_sensor": ".sensors",
    "run_onsets": ".run", "validate_onsets": ".run"})

