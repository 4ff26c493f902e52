"""JACK plumbing for the onset-validation tests: a known filter between an audio belt's
outputs and an audio sensor's input, and the wiring of this process's PortAudio ports.

:class:`EnvelopeFilter` is a JACK client with one input and one output port computing a
classic diode envelope detector, exactly: a full-wave rectifier followed by a
first-order RC low-pass of time constant ``tau_s``, discretised exactly for a signal
held over each sample (``y[n] = y[n-1] + a (|x[n]| - y[n-1])``, ``a = 1 - exp(-1 / (tau
rate))``). Its step response is ``1 - exp(-t / tau)``: a 10-90 % rise (and 90-10 % fall)
of ``tau ln 9``, and a 10 % point ``tau ln(10/9)`` after a step.

:class:`Wiring` finds the JACK ports PortAudio opened for this process (the ports that
appeared since it was made: PortAudio names its client ``PortAudio``, another process's
may be ``PortAudio-01``) and connects them: PortAudio connects every stream to the
system's ports when it starts; the tests cut those and connect the belt's outputs to the
sensor's input, directly or through the filter.
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["EnvelopeFilter", "Wire", "Wiring", "chain_crossings"]


class EnvelopeFilter:
    """A JACK client: full-wave rectifier + first-order RC low-pass (see the module)."""

    def __init__(self, tau_s: float, name: str = "tactorbelt-envelope-filter") -> None:
        import jack
        from scipy.signal import lfilter

        self.tau_s = float(tau_s)
        self.client = jack.Client(name)
        self.rate = float(self.client.samplerate)
        self.a = 1.0 - math.exp(-1.0 / (self.tau_s * self.rate))
        self._b = np.array([self.a])
        self._den = np.array([1.0, -(1.0 - self.a)])
        self._zi = np.zeros(1)
        self._lfilter = lfilter
        self.inport = self.client.inports.register("in")
        self.outport = self.client.outports.register("out")
        self.client.set_process_callback(self._process)
        self.client.activate()

    def _process(self, frames: int) -> None:
        x = np.abs(self.inport.get_array().astype(float))
        y, self._zi = self._lfilter(self._b, self._den, x, zi=self._zi)
        self.outport.get_array()[:] = y

    def close(self) -> None:
        self.client.deactivate()
        self.client.close()


class Wire:
    """A JACK client whose ``n`` outputs copy its ``n`` inputs in the same cycle: a wire
    as a sound device. Its ports declare no latency (as a plain JACK client's do), which
    PortAudio 19.6 reports, for a stream opened on it (device ``name``, listed once
    :func:`support.audio.rescan` ran), as 2^32 frames: 89,478 s (docs/audio.md)."""

    def __init__(self, n: int = 2, name: str = "tactorbelt-wire") -> None:
        import jack

        self.name = name
        self.client = jack.Client(name)
        self.inports = [self.client.inports.register(f"in_{k}") for k in range(n)]
        self.outports = [self.client.outports.register(f"out_{k}") for k in range(n)]
        self.client.set_process_callback(self._process)
        self.client.activate()

    def _process(self, frames: int) -> None:
        for src, dst in zip(self.inports, self.outports, strict=True):
            dst.get_array()[:] = src.get_array()

    def close(self) -> None:
        self.client.deactivate()
        self.client.close()


class Wiring:
    """Connect this process's PortAudio ports (see the module docstring). Make it before
    the belt and the sensor open; :meth:`find` after."""

    def __init__(self) -> None:
        import jack

        self.client = jack.Client("tactorbelt-validation-wiring")
        self.before = {p.name for p in self.client.get_ports(is_audio=True)}
        self.outputs: list[str] = []
        self.inputs: list[str] = []

    def find(self, timeout_s: float = 10.0) -> None:
        """The belt's output ports and the sensor's input ports, in channel order."""
        end = time.monotonic() + timeout_s
        while True:
            new = [p for p in self.client.get_ports(is_audio=True)
                   if p.name not in self.before and p.name.split(":")[0].startswith("PortAudio")]
            self.outputs = sorted((p.name for p in new if p.is_output), key=_channel)
            self.inputs = sorted((p.name for p in new if p.is_input), key=_channel)
            if (self.outputs and self.inputs) or time.monotonic() > end:
                break
            time.sleep(0.05)
        assert self.outputs and self.inputs, "PortAudio's ports did not appear in JACK"

    def cut(self, port: str) -> None:
        """Disconnect everything from ``port``."""
        for other in self.client.get_all_connections(port):
            if self.client.get_port_by_name(port).is_input:
                self.client.disconnect(other.name, port)
            else:
                self.client.disconnect(port, other.name)

    def loop(self, through: EnvelopeFilter | None = None, sensor_channel: int = 0) -> None:
        """Every belt output into the sensor's input ``sensor_channel`` (JACK sums them;
        one tactor is on at a time), directly or through ``through``."""
        target = self.inputs[sensor_channel]
        self.cut(target)
        for out in self.outputs:
            self.cut(out)
        if through is None:
            for out in self.outputs:
                self.client.connect(out, target)
        else:
            for out in self.outputs:
                self.client.connect(out, through.inport)
            self.client.connect(through.outport, target)

    def close(self) -> None:
        self.client.close()


def _channel(name: str) -> int:
    return int(name.rsplit("_", 1)[-1])


def chain_crossings(tau_s: float | None, ramp_ms: float, window_ms: float,
                    carrier_hz: float, rate: float, on_s: float = 0.4) -> tuple[float, float]:
    """The 10 % point and the 10-90 % rise (ms) of the ideal chain: the audio belt's
    linear ramp over ``ramp_ms`` from its first output sample, on the carrier, through
    the filter (``tau_s``; None: a direct connection), then the audio sensor's estimator
    (rectified, moving mean over ``window_ms``), the steady level as the sensor takes it
    (the median over the last fifth of ``on_s``). What a measurement with no delay at all
    would give."""
    from scipy.signal import lfilter

    from tactorbelt.validation.envelope import measure_pulse, rectified_envelope

    pre = int(0.05 * rate)
    n = pre + int(on_s * rate) + int(0.05 * rate)
    k = np.arange(n) - pre
    env = np.clip((k + 1) / (ramp_ms * rate / 1000.0), 0.0, 1.0)
    env[k < 0] = 0.0
    x = env * np.sin(2 * np.pi * carrier_hz * np.arange(n) / rate)
    if tau_s is not None:
        a = 1.0 - math.exp(-1.0 / (tau_s * rate))
        x = lfilter([a], [1.0, -(1.0 - a)], np.abs(x))
    y = rectified_envelope(x, rate, window_ms / 1000.0)
    t_ns = np.round(k / rate * 1e9).astype(np.int64)
    m = measure_pulse(t_ns, y, 0, round(on_s * 1e9), tactor=0, level=1.0)
    return m.latency_ms, m.rise_ms
