"""The analysis report: ``analyze()`` writes report.html, summary.json, per_target.csv, PNGs.

:func:`analyze` loads the stores, calls :func:`~tactorbelt.analysis.summary.summarize`,
fetches the cursor samples of a few trials for the trajectory figure (by SQL), draws
the figures and writes the files; the HTML comes from :func:`.html.render_html` (the
template ``templates/report.html.j2``). :func:`print_summary_table` prints the headline
numbers with rich (the demo reuses it).

I/O edge of the analysis (writes files); never imports devices, inputs or the window.
"""

from __future__ import annotations

import datetime as _dt
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Final

import numpy as np
import pandas as pd

from ... import __version__
from ..._errors import ConfigError
from ..models.glmm import FixefPrior
from ..models.lme4 import Lme4Unavailable
from ..summary import Summary, summarize
from ..tables.classical import DEFAULT_N_BOOT
from ..tables.load import StoreData, analysis_seed, load_samples, load_stores
from ..tables.tables import CONDITIONS, KIND_LABELS, KINDS, per_site
from .figures import make_figures
from .formatting import fixed as _fmt
from .formatting import p_value4 as _p
from .formatting import percent as _pct
from .html import FIGURE_ORDER, provenance_warnings, render_html, rt_from_words
from .tasks_figures import TASK_FIGURE_ORDER

if TYPE_CHECKING:
    from rich.console import Console

__all__ = ["KNOWN_OUTPUTS", "ProgressFn", "analyze", "choose_sample_trials",
           "print_summary_table"]

#: ``progress(description, done, total)``: called as the work advances.
ProgressFn = Callable[[str, int, int], None]

KNOWN_OUTPUTS: Final = ("report.html", "summary.json", "per_target.csv", "profile_effect.csv",
                        *FIGURE_ORDER)


# -- content ---------------------------------------------------------------------------

def choose_sample_trials(summary: Summary, per_condition: int = 5, seed: int = 0) -> pd.DataFrame:
    """A few answered test trials per condition for the trajectory figure.

    Takes the first participant (sorted) with answered test trials in both conditions
    (else the first with any), prefers between-tactor targets, distinct targets,
    chosen with a seeded generator.
    """
    tr = summary.trials
    ok = tr.loc[tr["counted"] & tr["responded"]]
    if ok.empty:
        return ok.iloc[0:0]
    both = ok.groupby("participant")["condition"].nunique()
    cands = sorted(both.index[both == both.max()].astype(str).tolist())
    who = ok.loc[ok["participant"].astype(str) == cands[0]]
    rng = np.random.default_rng(seed)
    picks = []
    for cond in CONDITIONS:
        sub = who.loc[who["condition"] == cond]
        if sub.empty:
            continue
        sub = sub.sample(frac=1.0, random_state=rng)
        sub = sub.sort_values("on_tactor", kind="stable").drop_duplicates("target_deg")
        picks.append(sub.head(per_condition))
    return pd.concat(picks) if picks else ok.iloc[0:0]


# -- console ---------------------------------------------------------------------------

def print_summary_table(summary: Summary, console: Console | None = None) -> None:
    """Print accuracy and median RT per condition, on- and between-tactor (rich)."""
    from rich.console import Console
    from rich.table import Table

    con = console or Console()
    table = Table(title="Accuracy and median response time (test block)")
    for i, column in enumerate(("condition", "targets", "n", "accuracy", "median RT (s)")):
        table.add_column(column, justify="left" if i < 2 else "right")
    style = {"static": "bold blue", "dynamic": "bold dark_orange3"}
    for cond in CONDITIONS:
        for kind in KINDS:
            n = summary.condition_value(cond, kind, "n") or 0
            acc = summary.condition_value(cond, kind, "accuracy")
            rt = summary.condition_value(cond, kind, "median_rt_s")
            table.add_row(f"[{style[cond]}]{cond}[/]", KIND_LABELS[kind], str(int(n)),
                          _pct(acc, missing="no trials"),
                          _fmt(rt, missing="no trials" if not n else "none answered"))
    con.print(table)
    con.print(f"Response times from {rt_from_words(summary)}: {summary.rt_from_reason}",
              highlight=False, markup=False)
    t = summary.between_accuracy_test
    if t.computed:
        p = _p(t.p_value)
        con.print(f"{t.test}, {t.question}: p {p if p.startswith('<') else '= ' + p}, "
                  f"{t.effect_name} = {_fmt(t.effect)}; 95 % CI of the {t.ci_name}: "
                  f"[{_fmt(t.ci_low)}, {_fmt(t.ci_high)}]", highlight=False)
    else:
        con.print(f"{t.test}, {t.question}: not computed ({t.reason})")
    for title, msg in provenance_warnings(summary):
        con.print(f"[bold]{title}[/] {msg}", highlight=False)


# -- files -----------------------------------------------------------------------------

def _sites(data: StoreData, summary: Summary) -> pd.DataFrame | None:
    """The per-site table when the sessions come from two sites or more."""
    s = data.sessions.dropna(subset=["site"])
    if s["site"].nunique() < 2:
        return None
    return per_site(summary.trials, dict(zip(s["participant"], s["site"], strict=True)))


def analyze(paths: Sequence[str | Path], out: str | Path, *, seed: int | None = None,
            progress: ProgressFn | None = None, n_boot: int = DEFAULT_N_BOOT,
            engine: str = "tactorbelt", sites: Sequence[str] | None = None,
            include_running: bool = False, pb_sims: int | None = None,
            rt_from: str | None = None, fixef_prior: str | None = None) -> Summary:
    """Analyse stores and write report.html, summary.json, per_target.csv and PNGs to ``out``.

    Args:
        paths: one or more store files.
        out: the output directory (created if needed).
        seed: seeds the bootstrap and the choice of sample trajectories; None (the
            default) derives it from the stores (:func:`load.analysis_seed`), so the
            same stores always give the same report.
        progress: called as ``progress(description, done, total)``.
        n_boot: bootstrap resamples per interval.
        engine: who fits the mixed models, ``tactorbelt`` or ``lme4`` (R via Rscript).
        sites: only these sites' sessions; include_running: a shared store's sessions
            that are not complete too (see :func:`load.load_stores`).
        pb_sims: simulations of the accuracy model's parametric bootstrap (None: the
            default, :data:`~tactorbelt.analysis.models.lrt.DEFAULT_PB_SIMS`; 0: not computed);
            computed only for studies of up to
            :data:`~tactorbelt.analysis.models.fit.PB_MAX_PARTICIPANTS` participants.
        rt_from: where the RTs count from, ``skin`` or ``command`` (None: ``skin`` when
            every analysed trial has a skin onset, else ``command``;
            :func:`~tactorbelt.analysis.summary.rt_from_choice`).

    Raises:
        StoreError: a store that cannot be read (see :func:`load.load_stores`).
        ConfigError: ``out`` exists and is not a directory, or cannot be written;
            ``engine="lme4"`` without R and lme4 (the message says how to install them);
            ``rt_from="skin"`` with trials that have no skin onset.
    """
    total = 6
    step = 0

    def tick(what: str) -> None:
        nonlocal step
        if progress is not None:
            progress(what, step, total)
        step += 1

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} is a file; give a directory for the report")
    prior = None
    if fixef_prior is not None:
        try:
            prior = FixefPrior.parse(fixef_prior)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    tick("loading stores")
    data = load_stores(list(paths), sites=sites, include_running=include_running)
    if seed is None:
        seed = analysis_seed(data)
    tick("computing tables and tests")

    def boot(done: int, n_sim: int) -> None:
        if progress is not None:
            progress(f"computing tables and tests (bootstrap {done}/{n_sim})", step - 1, total)

    try:
        summary = summarize(data, seed=seed, n_boot=n_boot, engine=engine, pb_sims=pb_sims,
                            progress=boot, rt_from=rt_from, fixef_prior=prior)
    except Lme4Unavailable as exc:
        raise ConfigError(str(exc)) from None
    tick("reading sample trajectories")
    chosen = choose_sample_trials(summary, seed=seed)
    samples = load_samples(data, chosen) if len(chosen) else None
    if samples is not None and samples.empty:
        summary.notes.append("no cursor samples are stored for the sample trials; the "
                             "trajectory figure is left out")
        samples = None
    tick("drawing figures")
    figures = make_figures(summary, samples, chosen if samples is not None else None)
    tick("writing the report")
    try:
        out.mkdir(parents=True, exist_ok=True)
        # stale figures of an earlier run would mislead (factorial and load ones too)
        for old in [*(out / n for n in (*FIGURE_ORDER, "resolution.png", *TASK_FIGURE_ORDER)),
                    *out.glob("fig1b-*.png")]:
            if old.name not in figures and old.is_file():
                old.unlink()
        for name, png in figures.items():
            (out / name).write_bytes(png)
        pt = summary.per_target.copy()
        pt["on_tactor"] = pt["on_tactor"].astype(int)
        pt.to_csv(out / "per_target.csv", index=False)
        from ..tables.profiles import profile_table  # sessions with and without a wearer profile

        if (prof := profile_table(list(paths))) is not None:
            prof.to_csv(out / "profile_effect.csv", index=False)
            summary.notes.append("profile_effect.csv: between-tactor results with and "
                                 "without the wearers' perceptual profiles")
        elif (out / "profile_effect.csv").is_file():  # a stale one would mislead
            (out / "profile_effect.csv").unlink()
        (out / "summary.json").write_text(
            json.dumps(summary.to_json(), indent=2, allow_nan=False) + "\n", encoding="utf-8")
        now = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        (out / "report.html").write_text(
            render_html(summary, figures, generated_at=now,
                        package_version=__version__, sites=_sites(data, summary)),
            encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write the report to {out}: {exc.strerror}") from None
    tick("done")
    return summary
