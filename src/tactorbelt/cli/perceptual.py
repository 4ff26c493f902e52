"""``tactorbelt calibrate perceptual``: measure a wearer's perceptual profile.

Parses the options, calls :func:`tactorbelt.app.wearer.calibrate_wearer`, prints what was
measured. Heavy imports are inside the command.
"""

from __future__ import annotations

from pathlib import Path

import click

from ..inputs.kinds import calibration_inputs
from ._options import belt_option, output_option, seed_option

__all__ = ["perceptual"]


@click.command()
@belt_option("The belt the wearer wears")
@click.option("--participant", "-p", required=True,
              help="Participant id: letters, digits, '-' or '_' (e.g. P01).")
@click.option("--input", "input_kind", type=click.Choice(calibration_inputs()), default="keyboard",
              show_default=True,
              help="Who answers: keyboard (a person, keys in the terminal), mouse (a "
                   "person in a window: mouse or keys), joystick (a person in a window: "
                   "the stick and a button) or model (the model participant).")
@click.option("--db", default=None, metavar="STORE",
              help="Keep the profile with the participant in this store (SQLite path or "
                   "postgresql://...); `run` then renders the study for this wearer.")
@output_option("file", "Also write the profile (TOML) here.")
@seed_option("Seed of the trial order (and of the model participant).", default=0)
def perceptual(belt_url: str, participant: str, input_kind: str, db: str | None,
               out: Path | None, seed: int) -> None:
    """Measure a wearer's profile: equal-feeling tactors, phantom points where meant.

    Part 1: each tactor against tactor 0, "which of the two vibrations was stronger"
    (keys 1 / 2). Part 2: for each adjacent pair, a point between the two tactors,
    "was it nearer tactor a or tactor b than the marked point" (keys a / b). QUEST+
    chooses each next stimulus; at most 228 trials, about 9 minutes with 6 tactors.
    q quits without writing. --input mouse or joystick asks in a window instead (the
    marked point drawn on the belt; Esc Esc quits). See docs/calibration-perceptual.md.
    """
    from ..app.wearer import calibrate_wearer
    from ..calibration.motor import CalibrationQuit
    from ._terminal import Keys

    keys = Keys()
    try:
        result = calibrate_wearer(belt_url, participant, input_kind=input_kind, db=db,
                                  out=None if out is None else str(out), seed=seed,
                                  read_key=keys.read,
                                  say=lambda text: click.echo(text, err=True))
    except CalibrationQuit as exc:
        click.echo(str(exc), err=True)
        raise click.exceptions.Exit(1) from None
    p = result.profile
    click.echo(f"calibrated {p.participant} on {belt_url}: {result.n_trials} trials, "
               f"{result.duration_s / 60:.1f} min of stimuli")
    click.echo("gains: " + ", ".join(f"{g:.2f}" for g in p.gains))
    for k, w in enumerate(p.warps):
        pts = ", ".join(f"{i:g} -> {r:.3f}" for i, r in zip(w.intended, w.rendered, strict=True))
        click.echo(f"pair {k}: {pts}")
    if db is not None:
        click.echo(f"kept with {p.participant} in {db}")
    if out is not None:
        click.echo(f"wrote {out}")
