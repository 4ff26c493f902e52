"""``tactorbelt power``: a study's power at each size, written to power.csv, power.json and
power.png (:func:`run_power_study`).

The study is read once (:meth:`~tactorbelt.power.design.PowerDesign.from_study`); the
effect is read against the design (:func:`~tactorbelt.power.effects.parse_effect`); then
one of three analyses runs on the design:

- no ``--effect``, one target count, no load (the paper's protocol): model participants,
  dynamic vs static over every test block, rendered with the study's ``[stimulus]``
  (:func:`~tactorbelt.power.simulation.run_power` of the design's one protocol);
- otherwise: model participants and the named effect
  (:func:`~tactorbelt.power.simulation.run_power` of the design's factorial protocol);
- ``--odds-ratio``: trials drawn from the report's accuracy GLMM with the named effect
  sizes, each study analysed with the report's headline test
  (:func:`~tactorbelt.power.glmm.named_power`).

I/O: writes files; imports NumPy, the simulation, the analysis and matplotlib only inside
the functions.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError

if TYPE_CHECKING:
    from ..experiment.study import Study
    from .design import PowerDesign
    from .effects import Effect
    from .glmm import NamedEffect
    from .outcomes import PowerRow

__all__ = [
    "MODEL_NOTE",
    "NAMED_NOTE",
    "NAMED_TEST",
    "PowerStudyResult",
    "prepare_out",
    "run_power_study",
]

MODEL_NOTE = ("The participants are simulated observers (the model participant): their "
              "results follow from the model's assumptions and are no evidence about people.")
SMALL_STUDY_NOTE = ("with 5 or fewer participants the exact two-sided Wilcoxon test cannot "
                    "reach p < 0.05 (its smallest p is 2/2^n), whatever the effect.")
NAMED_NOTE = ("The trials are simulated from the report's accuracy model with the effect "
              "sizes you named, and each simulated study is analysed with that model: the "
              "power holds if people's accuracies follow that model with those sizes.")
#: what a model-based power analysis tests, in words (power.json, the CLI and the plot).
NAMED_TEST = ("the report's headline test: the binomial GLMM of accuracy (correct ~ "
              "condition * on_tactor + (1 + condition | participant) + (1 | target), "
              "simplified while singular by the report's rule; Laplace maximum likelihood) "
              "against the same model without the condition terms: the likelihood ratio "
              "referred to F(k, participants - 1); found = p < alpha with the named sign")


def prepare_out(path: Path) -> Path:
    """Create the output directory (and parents), or explain why it cannot be."""
    if path.exists() and not path.is_dir():
        raise ConfigError(f"--out {path} exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create directory {path}: {exc.strerror}") from None
    return path


@dataclass(frozen=True)
class PowerStudyResult:
    """What :func:`run_power_study` computed and wrote."""

    rows: list[PowerRow]
    study_name: str
    plot: Path
    notes: list[str]
    #: the effect looked for, in words
    effect: str = "dynamic vs static between-tactor accuracy"
    #: what the rows' ``static_acc`` and ``dynamic_acc`` are: ``static``, ``dynamic``,
    #: or for a load effect ``loaded`` (under load) and ``no_load``
    pair: tuple[str, str] = ("static", "dynamic")
    #: the test each simulated study ran, in words
    test: str = ("paired Wilcoxon signed-rank on per-participant between-tactor accuracy "
                 "(the model-participant simulation's test, not the report's GLMM)")


def run_power_study(study: Study, sizes: Sequence[int], sims: int, seed: int, out: Path,
                    *, jobs: int | None = None, alpha: float = 0.05,
                    advance: Callable[[int], None] | None = None,
                    study_label: str | None = None,
                    effect: str | None = None,
                    named: NamedEffect | None = None) -> PowerStudyResult:
    """Simulate ``sims`` studies per size, write power.csv, power.json and power.png.

    Args:
        jobs: worker processes (default: the number of CPUs, at most 8).
        advance: called with the number of simulated studies just finished.
        study_label: how to name the study in errors (its file).
        effect: the effect to detect in a factorial study (``dynamic vs static``,
            ``dynamic vs static at N``, ``interaction``, ``load``, ``load NAME``; see
            :func:`tactorbelt.power.effects.parse_effect`). None: dynamic vs static
            between-tactor accuracy over every test block (the paper's test).
        named: effect sizes for the report's accuracy GLMM (``--odds-ratio``) instead of
            model participants.

    Raises:
        ConfigError: the study lacks a static or a dynamic test block (a load effect:
            blocks with and without a load); an unknown effect; ``out`` unusable.
    """
    from ..participant.factorial import FactorialProtocol
    from .design import PowerDesign
    from .effects import parse_effect
    from .simulation import observer, run_power

    design = PowerDesign.from_study(study)
    counts = design.counts
    conds = design.conditions
    eff = parse_effect(effect, counts, design.loads)
    if eff.kind != "load" and ("static" not in conds or "dynamic" not in conds):
        raise ConfigError(f"{study_label or 'the study'} needs a static and a dynamic test "
                          f"block for the static-vs-dynamic test; it has {', '.join(conds)}")
    # the two accuracies of each row: static/dynamic, or under load/without (load effect)
    pair = ("loaded", "no_load") if eff.kind == "load" else ("static", "dynamic")
    n_jobs = jobs if jobs is not None else max(1, min(8, os.cpu_count() or 1))
    out = prepare_out(out)
    if named is not None:
        return _named_power(design, eff, named, sizes, sims, seed, out, n_jobs, alpha,
                            advance)
    loaded = design.loaded
    plain = effect is None and len(counts) == 1 and not loaded  # the paper's protocol
    protocol = FactorialProtocol((design.protocol(),)) if plain else design.factorial()
    base = observer(protocol)
    rows = run_power(protocol, eff, sizes, sims, seed, n_jobs, alpha, advance=advance)

    doc: dict[str, Any] = {
        "note": MODEL_NOTE,
        "study": design.name,
        "test": "Wilcoxon signed-rank (two-sided) on per-participant between-tactor "
                "accuracy, dynamic vs static "
                "(tactorbelt.analysis.tables.classical.wilcoxon_paired); "
                "found = p < alpha and mean dynamic > mean static",
        **({} if plain else
           {"effect": eff.text, "test": eff.describe(), "target_counts": list(counts),
            **({"loads": "blocks under a load are simulated with the model localising "
                         "under that load (tactorbelt.participant.load; assumptions)"}
               if loaded else {})}),
        "alpha": alpha, "sims": sims, "seed": seed,
        "model": base.to_dict(),
    }
    _write_power(rows, out, doc, pair)
    plot = out / "power.png"
    what = ("static vs dynamic between-tactor accuracy" if effect is None
            else f"effect: {eff.text}")
    _plot_power(rows, plot, f"{design.name}: {what}", alpha)
    notes = [MODEL_NOTE, "each simulated study ran the paired Wilcoxon test; the report's "
                         "headline test is the accuracy GLMM: plan for it with --odds-ratio"]
    if any(r.n_participants <= 5 for r in rows):
        notes.append(SMALL_STUDY_NOTE)
    if loaded:
        notes.append("blocks under a load are simulated with the model localising worse "
                     "under that load (a documented assumption, docs/participant-model.md)")
    return PowerStudyResult(rows, design.name, plot, notes,
                            what if effect is not None else eff.describe(), pair)


def _named_power(design: PowerDesign, eff: Effect, named: NamedEffect, sizes: Sequence[int],
                 sims: int, seed: int, out: Path, jobs: int, alpha: float,
                 advance: Callable[[int], None] | None) -> PowerStudyResult:
    """Model-based power: trials drawn from the report's GLMM with the named effect sizes."""
    if eff.kind != "condition":
        raise ConfigError("--odds-ratio plans for the condition effect (dynamic vs static); "
                          f"'{eff.text}' cannot be named by that odds ratio (use --effect "
                          "'dynamic vs static at N', or leave out --odds-ratio to simulate "
                          "model participants)")
    if min(sizes) < 3:
        raise ConfigError("the report's mixed model needs at least 3 participants: use "
                          "study sizes of 3 or more with --odds-ratio")
    from .glmm import maximal_formula, named_power

    trials = design.trials(eff.n_targets)
    rows = named_power(trials, named, sizes, sims, seed, jobs, alpha, advance)
    formula = maximal_formula(trials, named)
    what = (f"odds ratio {named.odds_ratio:g} (dynamic over static, {trials.n_targets} "
            "targets)")
    _write_power(rows, out, {
        "note": NAMED_NOTE, "study": design.name, "test": NAMED_TEST, "formula": formula,
        "simulated_from": "the same GLMM, with the named effect sizes "
                          "(tactorbelt.power.glmm)",
        "effect": what, "effect_sizes": named.to_dict(), "n_targets": trials.n_targets,
        "trials_per_participant": trials.n, "alpha": alpha, "sims": sims, "seed": seed,
    })
    plot = out / "power.png"
    _plot_power(rows, plot, f"{design.name}: {what}", alpha)
    return PowerStudyResult(rows, design.name, plot, [NAMED_NOTE], what, test=NAMED_TEST)


# -- the files -----------------------------------------------------------------------------

def _write_power(rows: Sequence[PowerRow], out: Path, doc: dict[str, Any],
                 pair: tuple[str, str] = ("static", "dynamic")) -> None:
    """power.csv and power.json (``pair``: what the rows' two accuracies are)."""
    header = ["participants", "sims", "found", "power", "ci_low", "ci_high",
              f"mean_{pair[0]}_between_acc", f"mean_{pair[1]}_between_acc", "median_p"]
    lines = [",".join(header)]
    for r in rows:
        lines.append(",".join([str(r.n_participants), str(r.sims), str(r.found),
                               f"{r.power:.4f}", f"{r.ci_low:.4f}", f"{r.ci_high:.4f}",
                               f"{r.static_acc:.4f}", f"{r.dynamic_acc:.4f}",
                               "" if not math.isfinite(r.median_p) else f"{r.median_p:.6g}"]))
    (out / "power.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    # power.json's names of the two accuracies (``static_acc`` is ``loaded_acc`` for a load)
    keys = {"static_acc": f"{pair[0]}_acc", "dynamic_acc": f"{pair[1]}_acc"}
    doc = {**doc, "rows": [{keys.get(k, k): (None if isinstance(v, float)
                                             and not math.isfinite(v) else v)
                            for k, v in r.__dict__.items()} for r in rows]}
    (out / "power.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


def _plot_power(rows: Sequence[PowerRow], path: Path, title: str, alpha: float) -> None:
    from ..figures import _pyplot

    plt = _pyplot()
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
