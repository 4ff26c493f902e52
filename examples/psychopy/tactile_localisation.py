"""A PsychoPy experiment with a vibrotactile belt: feel a direction, click towards it.

Each trial shows a fixation cross; the belt plays a direction starting with the frame
that removes the cross (``belt.present`` + ``win.flip``), and the participant clicks in
the direction they felt. The data file is PsychoPy's usual trial-by-trial CSV (one row
per trial, ``participant``, ``session`` and ``date`` columns), with the belt's onset
time next to PsychoPy's own frame times, so it reads like every other PsychoPy data
file (and like ``tactorbelt export --format psychopy``).

Run it (PsychoPy installed, a belt on ``serial:auto``, or ``sim`` to try it without one):

    python examples/psychopy/tactile_localisation.py --belt sim --participant P01

Every time in the data file is on PsychoPy's clock (the one ``win.flip()`` returns): the
belt's onset (``belt.started``) follows the flip that shows the prompt
(``belt.startedRefresh``) by a fraction of a millisecond. The response is the first
press of the left button after the prompt appears (a button held since the fixation
counts once released and pressed again); its time counts from that flip. Press Escape
during a response to stop: the motors go off (``core.quit``), as they do on SIGTERM and
when the window closes. See docs/psychopy.md.
"""

from __future__ import annotations

import argparse
import math
import random
from typing import Any

from tactorbelt.psychopy import TactileBelt

TARGETS = [k * 45.0 for k in range(8)]  # 8 directions, 0 = navel (front), clockwise


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0].replace("\n", " "),
        epilog="The data file goes to data/PARTICIPANT_tactile-localisation_DATE.csv. "
               "Press Escape during a response to stop (motors off). See docs/psychopy.md.")
    ap.add_argument("--belt", default="sim",
                    help="belt URL: sim (no belt), serial:auto, ble:NAME (default: sim)")
    ap.add_argument("--participant", default="P01", help="participant ID (default: P01)")
    ap.add_argument("--session", default="1", help="session (default: 1)")
    ap.add_argument("--repetitions", type=int, default=2,
                    help="repetitions of the 16 conditions (default: 2)")
    ap.add_argument("--trials", type=int, default=None,
                    help="stop after this many trials (to try the set-up)")
    ap.add_argument("--fullscreen", action="store_true", help="a full-screen window")
    ap.add_argument("--prefs-json", metavar="FILE",
                    help="PsychoPy preferences to use (read by PsychoPy)")
    args = ap.parse_args()
    if args.repetitions < 1 or (args.trials is not None and args.trials < 1):
        ap.error("--repetitions and --trials must be at least 1")
    return args


def wait_for_click(mouse: Any, win: Any, prompt: Any) -> None:
    """Return when the left button goes down: a button already down (held since the
    fixation) counts only after it was released, so the press is a response to the
    stimulus (``clickReset`` resets click times, not the button's state)."""
    from psychopy import core, event

    released = False
    while True:
        if event.getKeys(["escape"]):
            core.quit()  # motors off
        down = mouse.getPressed()[0]
        if not down:
            released = True
        elif released:
            return
        prompt.draw()
        win.flip()


def main() -> None:
    args = parse_args()  # before PsychoPy's import, whose own parser reads --help

    import psychopy
    from psychopy import core, data, event, visual

    exp_name = "tactile-localisation"
    exp_info = {"participant": args.participant, "session": args.session,
                "date": data.getDateStr(), "expName": exp_name,
                "psychopyVersion": psychopy.__version__}
    this_exp = data.ExperimentHandler(
        name=exp_name, extraInfo=exp_info,
        dataFileName=f"data/{args.participant}_{exp_name}_{exp_info['date']}")

    win = visual.Window(size=(1024, 768), units="height", color="grey",
                        fullscr=args.fullscreen)
    belt = TactileBelt(win, args.belt, duration_s=2.0)  # opened once for the experiment
    fixation = visual.TextStim(win, text="+", height=0.08)
    prompt = visual.TextStim(win, text="Click in the direction you felt", pos=(0, -0.4),
                             height=0.03)
    mouse = event.Mouse(win=win)

    conditions = [{"target_deg": t, "mode": m} for t in TARGETS for m in ("static", "dynamic")]
    trials = data.TrialHandler(conditions, nReps=args.repetitions, method="random",
                               name="trials")
    this_exp.addLoop(trials)
    rt_clock = core.Clock()
    for n, trial in enumerate(trials):
        if args.trials is not None and n >= args.trials:
            break
        fixation.draw()
        win.flip()
        core.wait(random.uniform(0.8, 1.2))
        belt.present(trial["target_deg"], trial["mode"])  # starts with the next flip
        win.callOnFlip(rt_clock.reset)  # the response time counts from that flip
        prompt.draw()
        win.flip()
        belt.add_data(this_exp)  # belt.started (PsychoPy's clock), belt.startedRefresh, ...
        mouse.clickReset()
        wait_for_click(mouse, win, prompt)
        rt = rt_clock.getTime()
        belt.stop_on_flip()
        win.flip()
        x, y = mouse.getPos()
        response = math.degrees(math.atan2(x, y)) % 360.0  # 0 = up (front), clockwise
        error = (response - trial["target_deg"] + 180.0) % 360.0 - 180.0
        this_exp.addData("belt.stopped", belt.tStop)
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
