"""``tactorbelt demo`` and ``tactorbelt power``: the paper's study with model participants.

- ``demo`` writes the paper's protocol (as ``study init`` does), runs N model
  participants through the real session runner on the ``sim`` belt and a simulated
  clock, stores everything in DIR/study.sqlite, and writes the analysis report.
- ``power`` estimates, by simulation on the fast path
  (:mod:`tactorbelt.participant.simulate`), how often a study of N model participants
  finds the static-versus-dynamic difference with the analysis' test.

The participants are models (docs/participant-model.md); their results follow from the
model's assumptions and are no evidence about people.

Imports click at import time; NumPy, the runner, the analysis, matplotlib and rich only
when a command runs.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .._errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from ..participant.power import PowerRow, StudyOutcome
    from ..participant.simulate import Protocol, StimulusCues

__all__ = ["demo", "power"]

STORE_NAME = "study.sqlite"
PREVIOUS_STORE_NAME = "study.previous.sqlite"
MODEL_NOTE = ("The participants are simulated observers (the model participant): their "
              "results follow from the model's assumptions and are no evidence about people.")


# -- helpers -----------------------------------------------------------------------------

def _out_dir(path: Path) -> Path:
    """Create the output directory (and parents), or explain why it cannot be."""
    if path.exists() and not path.is_dir():
        raise click.BadParameter(f"{path} exists and is not a directory",
                                 param_hint="'--out'")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise click.BadParameter(f"cannot create directory {path}: {exc.strerror}",
                                 param_hint="'--out'") from None
    return path


def _move_old_store(out: Path) -> Path | None:
    """Move DIR/study.sqlite (and its WAL files) to DIR/study.previous.sqlite.

    Returns the new path of the old store, or None when there was none. An older
    ``study.previous.sqlite`` is replaced: one previous run is kept. Refuses while
    another run holds the store's lock.
    """
    import fcntl

    old = out / STORE_NAME
    lock_path = out / (STORE_NAME + ".lock")
    fd = None
    try:
        if lock_path.exists():
            fd = os.open(lock_path, os.O_RDWR)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise click.UsageError(
                    f"another run is using {old}; wait for it to finish or choose "
                    "another --out") from None
        if not old.exists():
            for suffix in ("-wal", "-shm"):  # leftovers of a run that lost its main file
                (out / (STORE_NAME + suffix)).unlink(missing_ok=True)
            return None
        for suffix in ("", "-wal", "-shm"):
            (out / (PREVIOUS_STORE_NAME + suffix)).unlink(missing_ok=True)
        for suffix in ("", "-wal", "-shm"):
            src = out / (STORE_NAME + suffix)
            if src.exists():
                shutil.move(str(src), str(out / (PREVIOUS_STORE_NAME + suffix)))
    except OSError as exc:
        raise click.UsageError(
            f"cannot move the previous store {old} aside: {exc.strerror}; "
            "remove it or choose another --out"
        ) from None
    finally:
        if fd is not None:
            os.close(fd)
    return out / PREVIOUS_STORE_NAME


def _participant_ids(n: int) -> list[str]:
    width = max(2, len(str(n)))
    return [f"model-{i:0{width}d}" for i in range(1, n + 1)]


def _progress_bar(console: Any) -> Any:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console)


# -- demo ----------------------------------------------------------------------------------

@click.command("demo")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("demo-output"), show_default=True,
              help="Directory for study.toml, study.sqlite, the report and its figures.")
@click.option("--participants", type=click.IntRange(1, 999), default=1, show_default=True,
              help="Number of model participants (ids model-01, model-02, ...).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=1, show_default=True,
              help="Seed of the schedules, the model participants and the analysis.")
def demo(out: Path, participants: int, seed: int) -> None:
    """Run the paper's study with model participants, then analyse it.

    Writes DIR/study.toml (the paper's protocol, as 'tactorbelt study init' writes it),
    runs each model participant through a whole session (training, then 240 test
    trials) on the simulated belt and a simulated clock, stores every trial and cursor
    sample in DIR/study.sqlite, and writes the analysis report: report.html,
    summary.json, per_target.csv and PNG figures. Then prints accuracy and median RT
    per condition and where the report is.

    An existing DIR/study.sqlite is moved to DIR/study.previous.sqlite (replacing an
    older one), so the demo can be run again into the same directory.

    The participants are models: simulated observers whose results follow from the
    model's assumptions (docs/participant-model.md), not evidence about people.
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    import numpy as np
    from rich.console import Console

    from ..analysis.report import analyze as run_analysis
    from ..analysis.report import print_summary_table
    from ..clock import SimClock
    from ..devices import open_belt
    from ..experiment.runner import run_session
    from ..experiment.store import Store
    from ..experiment.study import PAPER_STUDY_TOML, Study
    from ..inputs.model import make_model_cursor
    from ..participant.params import ModelParams, draw_participant

    out = _out_dir(out)
    err = Console(stderr=True)
    study_path = out / "study.toml"
    try:
        study_path.write_text(PAPER_STUDY_TOML, encoding="utf-8")
    except OSError as exc:
        raise click.UsageError(f"cannot write {study_path}: {exc.strerror}") from None
    study = Study.from_toml(PAPER_STUDY_TOML, path=study_path)
    moved = _move_old_store(out)
    if moved is not None:
        err.print(f"note: the previous store was moved to {moved}", highlight=False)
    db = out / STORE_NAME
    base = ModelParams().for_period(study.stimulus.period_s)
    ids = _participant_ids(participants)
    n_trials = study.n_trials()
    people: dict[str, Any] = {}
    with _progress_bar(err) as bar:
        task = bar.add_task("model participants", total=participants * n_trials)
        with Store.open(db) as store:
            for i, pid in enumerate(ids):
                params_seq, cursor_seq = np.random.SeedSequence([seed, i + 1]).spawn(2)
                params = draw_participant(np.random.default_rng(params_seq), base)
                cursor_seed = int(cursor_seq.generate_state(1, np.uint64)[0] >> np.uint64(1))
                people[pid] = {"seed": cursor_seed, "params": params.to_dict()}
                bar.update(task, description=f"{pid} ({i + 1}/{participants})")
                done_before = i * n_trials

                def progress(n_done: int, n_total: int, _base: int = done_before) -> None:
                    bar.update(task, completed=_base + n_done)

                clock = SimClock()
                with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                    cursor = make_model_cursor(belt, clock, seed=cursor_seed, params=params)
                    result = run_session(study, pid, belt, cursor, store, clock, seed=seed,
                                         progress=progress, study_toml=PAPER_STUDY_TOML,
                                         input_name="model")
                if result.status != "complete":
                    raise ConfigError(f"the session of {pid} ended {result.status}; "
                                      f"see {db}")
        (out / "participants.json").write_text(json.dumps(
            {"note": MODEL_NOTE, "study": study.name, "seed": seed, "participants": people},
            indent=2) + "\n", encoding="utf-8")
        atask = bar.add_task("analysis", total=1)

        def aprogress(what: str, done: int, total: int) -> None:
            bar.update(atask, description=f"analysis: {what}", completed=done,
                       total=max(total, 1))

        summary = run_analysis([db], out, seed=seed, progress=aprogress)
        bar.update(atask, completed=bar.tasks[-1].total, description="analysis")
    print_summary_table(summary, Console())
    for note in getattr(summary, "notes", []):
        err.print(f"note: {note}", highlight=False)
    click.echo(f"store:  {db.resolve()}")
    click.echo(f"report: {(out / 'report.html').resolve()}")


# -- power ---------------------------------------------------------------------------------

def parse_sizes(text: str) -> list[int]:
    """Parse ``4,8,12,16`` into study sizes (whole numbers >= 2, no repeats)."""
    sizes: list[int] = []
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        try:
            n = int(part)
        except ValueError:
            n = -1
        if n < 2 or n > 10_000:
            raise click.BadParameter(
                f"must be a comma-separated list of whole numbers of participants from 2 to "
                f"10000, e.g. 4,8,12,16; got {text!r}", param_hint="'--participants'")
        if n not in sizes:
            sizes.append(n)
    if not sizes:
        raise click.BadParameter("give at least one study size, e.g. 4,8,12,16",
                                 param_hint="'--participants'")
    return sorted(sizes)


def analysis_paired_test(static: np.ndarray, dynamic: np.ndarray) -> float:
    """The analysis' static-vs-dynamic test (paired Wilcoxon) p-value; NaN if not computed."""
    import numpy as np

    from ..analysis.stats import wilcoxon_paired

    res = wilcoxon_paired(static, dynamic, np.random.default_rng(0), n_boot=1,
                          key="between_accuracy", what="accuracy")
    if not res.computed or res.p_value is None:
        return float("nan")
    return float(res.p_value)


def _power_chunk(args: tuple[Protocol, StimulusCues, int, list[int], int]
                 ) -> list[StudyOutcome]:
    """Worker: simulate some studies of one size (module level, so processes can run it)."""
    from ..participant.power import simulate_studies

    protocol, cues, n, indices, seed = args
    return simulate_studies(protocol, cues, n, indices, seed, analysis_paired_test)


def run_power(protocol: Protocol, cues: StimulusCues, sizes: Sequence[int], sims: int,
              seed: int, jobs: int, alpha: float,
              advance: Callable[[int], None] | None = None) -> list[PowerRow]:
    """Simulate ``sims`` studies at each size (in ``jobs`` processes) and summarise them."""
    from ..participant.power import power_row

    chunk = max(1, min(25, math.ceil(sims / max(jobs, 1) / 4)))
    work = [(protocol, cues, n, list(range(s, min(s + chunk, sims))), seed)
            for n in sizes for s in range(0, sims, chunk)]
    results: dict[int, list[StudyOutcome]] = {n: [] for n in sizes}
    if jobs <= 1:
        for item in work:
            out = _power_chunk(item)
            results[item[2]].extend(out)
            if advance is not None:
                advance(len(out))
    else:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_power_chunk, item): item for item in work}
            for fut in as_completed(futures):
                out = fut.result()
                results[futures[fut][2]].extend(out)
                if advance is not None:
                    advance(len(out))
    return [power_row(results[n], alpha) for n in sizes]


def _plot_power(rows: Sequence[PowerRow], path: Path, title: str, alpha: float) -> None:
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r.n_participants for r in rows]
    pw = [r.power for r in rows]
    lo = [r.power - r.ci_low for r in rows]
    hi = [r.ci_high - r.power for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    ax.axhline(0.8, color="0.6", lw=1, ls="--", label="power 0.8")
    ax.errorbar(n, pw, yerr=[lo, hi], fmt="o-", color="tab:orange", capsize=4,
                label="simulated power (95 % Clopper-Pearson CI)")
    ax.set_xlabel("participants")
    ax.set_ylabel("power")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xticks(n)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.text(0.01, 0.01, f"Model participants (simulated); alpha = {alpha:g}, "
             f"{rows[0].sims} simulated studies per size. Follows from the model's "
             "assumptions.", fontsize=6.5, color="0.35")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path)
    plt.close(fig)


@click.command("power")
@click.option("--participants", "sizes_text", default="4,8,12,16", show_default=True,
              help="Study sizes to simulate, comma-separated.")
@click.option("--sims", type=click.IntRange(1, 1_000_000), default=500, show_default=True,
              help="Simulated studies per size.")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("power-output"), show_default=True,
              help="Directory for power.csv, power.json and power.png.")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=1, show_default=True,
              help="Seed of the simulation (results do not depend on --jobs).")
@click.option("--jobs", type=click.IntRange(1, 256), default=None,
              help="Worker processes [default: the number of CPUs, at most 8].")
@click.option("--study", "study_file", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Study file to plan [default: the paper's protocol].")
@click.option("--alpha", type=click.FloatRange(0, 1, min_open=True, max_open=True),
              default=0.05, show_default=True, help="Significance level of the test.")
def power(sizes_text: str, sims: int, out: Path, seed: int, jobs: int | None,
          study_file: Path | None, alpha: float) -> None:
    """Plan a study's size by simulation with model participants.

    For each study size, simulates --sims studies of that many model participants
    (each an individual observer drawn around the typical one), runs the analysis'
    static-vs-dynamic test (paired Wilcoxon signed-rank on per-participant
    between-tactor accuracy), and counts the studies in which it finds the difference
    (p < alpha, dynamic higher). Writes power.csv, power.json and power.png (power vs
    participants with 95 % binomial intervals) to DIR and prints the table.

    Trials are simulated directly from the model's perception (no runner, no store;
    the fast path gives the same accuracy as the full runner). The power is that of a
    study *if people behaved like the model* (docs/participant-model.md).
    """
    import numpy as np
    from rich.console import Console
    from rich.table import Table

    from ..experiment.study import load_study, paper_study
    from ..inputs.model import sim_vibrator
    from ..participant.params import ModelParams
    from ..participant.simulate import Protocol, stimulus_cues

    sizes = parse_sizes(sizes_text)
    study = load_study(study_file) if study_file is not None else paper_study()
    protocol = Protocol.from_study(study)
    conds = protocol.conditions
    if "static" not in conds or "dynamic" not in conds:
        raise ConfigError(f"{study_file or 'the study'} needs a static and a dynamic test block "
                          f"for the static-vs-dynamic test; it has {', '.join(conds)}")
    n_jobs = jobs if jobs is not None else max(1, min(8, os.cpu_count() or 1))
    out = _out_dir(out)
    err = Console(stderr=True)
    base = ModelParams().for_period(protocol.period_s)
    cues = stimulus_cues(protocol, sim_vibrator(protocol.layout), base)
    with _progress_bar(err) as bar:
        task = bar.add_task("simulated studies", total=sims * len(sizes))
        rows = run_power(protocol, cues, sizes, sims, seed, n_jobs, alpha,
                         advance=lambda k: bar.advance(task, k))

    header = ["participants", "sims", "found", "power", "ci_low", "ci_high",
              "mean_static_between_acc", "mean_dynamic_between_acc", "median_p"]
    lines = [",".join(header)]
    for r in rows:
        lines.append(",".join([str(r.n_participants), str(r.sims), str(r.found),
                               f"{r.power:.4f}", f"{r.ci_low:.4f}", f"{r.ci_high:.4f}",
                               f"{r.static_acc:.4f}", f"{r.dynamic_acc:.4f}",
                               "" if not np.isfinite(r.median_p) else f"{r.median_p:.6g}"]))
    (out / "power.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    doc = {
        "note": MODEL_NOTE,
        "study": study.name,
        "test": "Wilcoxon signed-rank (two-sided) on per-participant between-tactor "
                "accuracy, dynamic vs static (tactorbelt.analysis.stats.wilcoxon_paired); "
                "found = p < alpha and mean dynamic > mean static",
        "alpha": alpha, "sims": sims, "seed": seed,
        "model": base.to_dict(),
        "rows": [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                  for k, v in r.__dict__.items()} for r in rows],
    }
    (out / "power.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    _plot_power(rows, out / "power.png",
                f"{study.name}: static vs dynamic between-tactor accuracy", alpha)

    table = Table(title=f"Power of the static-vs-dynamic test (alpha {alpha:g}, "
                        f"{sims} simulated studies per size)")
    for col in ("participants", "power", "95 % CI", "static acc.", "dynamic acc.",
                "median p"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(str(r.n_participants), f"{r.power:.2f}",
                      f"[{r.ci_low:.2f}, {r.ci_high:.2f}]", f"{r.static_acc:.1%}",
                      f"{r.dynamic_acc:.1%}",
                      "n/a" if not np.isfinite(r.median_p) else f"{r.median_p:.3g}")
    Console().print(table)
    err.print(f"note: {MODEL_NOTE}", highlight=False)
    if any(r.n_participants <= 5 for r in rows):
        err.print("note: with 5 or fewer participants the exact two-sided Wilcoxon test "
                  "cannot reach p < 0.05 (its smallest p is 2/2^n), whatever the effect.",
                  highlight=False)
    click.echo(f"power: {(out / 'power.png').resolve()}")
