"""Play n-back tones through SDL's ``disk`` audio driver and report what was scheduled.

Run as a script in a fresh process (SDL picks its audio driver once per process):
``python task_audio_probe.py OUT.json`` with ``SDL_AUDIODRIVER=disk`` and
``SDL_DISKAUDIOFILE=...`` set. It opens :class:`tactorbelt.tasks.audio.SdlTaskAudio` on
the wall clock, schedules a marker sound with an onset long past (it lands on the
stream's first frame, which finds the stream in the file: SDL writes silence before the
device is started), then 8 tones at onsets 150 ms + k * 230 ms from now, each announced
100 ms ahead as the runner does, then a 1 s tone that it stops 0.4 s in (a pause),
closes the device and writes the placements, the callback blocks, the onsets asked for,
when each was handed over and the frame count when it stopped to OUT.json.
"""

from __future__ import annotations

import json
import sys
import time

from tactorbelt.clock import WallClock
from tactorbelt.tasks.audio import SdlTaskAudio
from tactorbelt.tasks.sounds import tone

LEAD_NS = 100_000_000


def main(out: str) -> None:
    clock = WallClock()
    audio = SdlTaskAudio(clock)
    try:
        audio.schedule(tone(7, 0.05), 0, "marker")
        t0 = clock.now_ns()
        onsets = [t0 + 150_000_000 + k * 230_000_000 for k in range(8)]
        handed = []  # when each tone was handed over (late where the machine is loaded)
        for k, onset in enumerate(onsets):
            clock.sleep_until_ns(onset - LEAD_NS)
            audio.schedule(tone(k, 0.1), onset, f"tone{k}")
            handed.append(clock.now_ns())
        # a long tone stopped half-way (a pause): silent within a block and the fade
        long_onset = onsets[-1] + 300_000_000
        clock.sleep_until_ns(long_onset - LEAD_NS)
        audio.schedule(tone(4, 1.0), long_onset, "long")
        clock.sleep_until_ns(long_onset + 400_000_000)
        stop_frame = audio.frames
        audio.stop()
        clock.sleep_until_ns(long_onset + 800_000_000)
    finally:
        audio.close()
    time.sleep(0.05)
    with open(out, "w", encoding="utf-8") as f:
        json.dump({"rate": audio.rate, "frames": audio.frames, "driver": audio.driver,
                   "stop_frame": stop_frame,
                   "onsets": onsets, "handed": handed,
                   "played": [[p.label, p.onset_ns, p.frame, p.start_ns, p.late_ns]
                              for p in audio.played],
                   "blocks": list(audio.blocks), "error": repr(audio.error)}, f)


def cycles(n: int = 20) -> None:
    """Open and close the device ``n`` times while this thread keeps Python's GIL busy
    (the callback waits for the GIL then): closing (through ctypes, without the GIL)
    must not deadlock."""
    clock = WallClock()
    for _ in range(n):
        audio = SdlTaskAudio(clock)
        audio.schedule(tone(0, 0.05), clock.now_ns() + 20_000_000)
        end = time.perf_counter() + 0.03
        while time.perf_counter() < end:
            pass
        audio.close()
    print("closed", n)


if __name__ == "__main__":
    if sys.argv[1] == "--cycles":
        cycles()
    else:
        main(sys.argv[1])
