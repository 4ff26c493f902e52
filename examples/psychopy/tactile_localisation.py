"""A PsychoPy experiment with a vibrotactile belt: feel a direction, click towards it.

Each trial shows a fixation cross; the belt plays a direction starting with the frame
that removes the cross (``belt.present`` + ``win.flip``), and the participant clicks in
the direction they felt. The data file is PsychoPy's usual trial-by-trial CSV (one row
per trial, ``participant``, ``session`` and ``date`` columns), with the belt's onset
time next to PsychoPy's own frame times, so it reads like every other PsychoPy data
file (and like ``tactorbelt export --format psychopy``).

Run it (PsychoPy installed, a belt on ``serial:auto``, or ``sim`` to try it without one):

    python examples/psychopy/tactile_localisation.py --belt sim --participant P01

Press Escape to stop: the motors go off (``core.quit``), and the window's ``close``
turns them off too. See docs/psychopy.md.
"""

from __future__ import annotations

import argparse
import math
import random

import psychopy
from psychopy import core, data, event, visual

from tactorbelt.psychopy import TactileBelt

TARGETS = [k * 45.0 for k in range(8)]  # 8 directions, 0 = navel (front), clockwise


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--belt", default="sim", help="belt URL (sim, serial:auto, ble:NAME)")
    ap.add_argument("--participant", default="P01")
    ap.add_argument("--session", default="1")
    ap.add_argument("--repetitions", type=int, default=2)
    args = ap.parse_args()

    exp_name = "tactile-localisation"
    exp_info = {"participant": args.participant, "session": args.session,
                "date": data.getDateStr(), "expName": exp_name,
                "psychopyVersion": psychopy.__version__}
    this_exp = data.ExperimentHandler(
        name=exp_name, extraInfo=exp_info,
        dataFileName=f"data/{args.participant}_{exp_name}_{exp_info['date']}")

    win = visual.Window(size=(1024, 768), units="height", color="grey", fullscr=False)
    belt = TactileBelt(win, args.belt, duration_s=2.0)  # opened once for the experiment
    fixation = visual.TextStim(win, text="+", height=0.08)
    prompt = visual.TextStim(win, text="Click in the direction you felt", pos=(0, -0.4),
                             height=0.03)
    mouse = event.Mouse(win=win)

    conditions = [{"target_deg": t, "mode": m} for t in TARGETS for m in ("static", "dynamic")]
    trials = data.TrialHandler(conditions, nReps=args.repetitions, method="random",
                               name="trials")
    this_exp.addLoop(trials)
    clock = core.Clock()
    for trial in trials:
        fixation.draw()
        win.flip()
        core.wait(random.uniform(0.8, 1.2))
        belt.present(trial["target_deg"], trial["mode"])  # starts with the next flip
        prompt.draw()
        flip_time = win.flip()
        clock.reset()
        this_exp.addData("belt.started", belt.onset_s)
        this_exp.addData("frame.flipped", flip_time)
        mouse.clickReset()
        while not mouse.getPressed()[0]:
            if event.getKeys(["escape"]):
                core.quit()  # motors off
            prompt.draw()
            win.flip()
        rt = clock.getTime()
        belt.stop_on_flip()
        win.flip()
        x, y = mouse.getPos()
        response = math.degrees(math.atan2(x, y)) % 360.0  # 0 = up (front), clockwise
        error = (response - trial["target_deg"] + 180.0) % 360.0 - 180.0
        this_exp.addData("response.deg", response)
        this_exp.addData("response.rt", rt)
        this_exp.addData("response.error_deg", error)
        this_exp.nextEntry()

    this_exp.saveAsWideText(this_exp.dataFileName + ".csv", delim="auto")
    this_exp.abort()  # saved above: no second copy at exit (as Builder scripts do)
    belt.close()
    win.close()
    core.quit()


if __name__ == "__main__":
    main()
