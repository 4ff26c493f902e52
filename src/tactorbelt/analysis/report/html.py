"""The report's HTML: :func:`render_html` fills ``templates/report.html.j2`` (Jinja2,
autoescaped) from a Summary and the figures' PNG bytes.

The template holds the markup; this module hands it plain values (text and numbers, the
numbers formatted by :mod:`.formatting`'s filters). The page is one self-contained
file: inline CSS, figures as base64 ``data:`` URIs, links only to files written next to
it. :func:`provenance_warnings` and :func:`rt_from_words` are shared with the console.

Pure: builds a string; imports Jinja2 when a page is rendered.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING, Any, Final

from ..summary import COUNTING_RULES, Summary
from ..tables.tables import CONDITIONS, KIND_LABELS, KINDS
from . import formatting
from .cells import cells_view
from .formatting import figure_view
from .tasks import load_view, test_text

if TYPE_CHECKING:
    import jinja2
    import pandas as pd

    from ..tables.classical import TestResult

__all__ = ["FIGURE_CAPTIONS", "FIGURE_ORDER", "fixed_effects_view", "model_view",
           "provenance_warnings", "render_html", "rt_from_words", "tests_view"]

FIGURE_CAPTIONS: Final = {
    "fig1b.png": "Fig. 1(B) of the paper, recomputed: amplitude of each tactor against "
                 "direction (top; the study's layout and law), then recognition accuracy and "
                 "median time from stimulus onset to target acquisition per direction, static "
                 "vs dynamic. Grey bands mark on-tactor targets (always rendered static).",
    "polar.png": "Accuracy and mean signed error per direction, as seen from above: front "
                 "(navel) at the top, angles clockwise.",
    "confusion.png": "Confusion matrices per condition: each row is a target, each column the "
                     "selected response; cells are the proportion of that target's counted "
                     "trials. The last column holds timeouts.",
    "trajectories.png": "Cursor trajectories (100 Hz samples) of a few test trials per "
                        "condition, in the normalised response ellipse (front up).",
    "paired.png": "Per-participant between-tactor accuracy and median RT in the two "
                  "conditions; each grey line is one participant.",
}
FIGURE_ORDER: Final = tuple(FIGURE_CAPTIONS)
MAX_TABLE_ROWS: Final = 200
MAX_LISTED: Final = 50

#: stored column names as the report's tables name them
_COLUMN_WORDS = {"session_key": "session", "study_name": "study",
                 "condition_order": "block order", "started_at": "started",
                 "ended_at": "ended", "trial_index": "trial", "target_deg": "target (°)",
                 "response_deg": "response (°)", "rt_s": "response time (s)",
                 "on_tactor": "on-tactor", "n_targets": "targets"}
#: the sessions table's columns, in order
_SESSION_COLUMNS = ("session_key", "participant", "study_name", "condition_order", "seed",
                    "belt", "input", "started_at", "ended_at", "status")
#: the tests of the condition, as the table names them
_TEST_WORDS = {"Wald": "Wald chi-square over every condition term (chi-square reference)",
               "LRT": "likelihood ratio, chi-square reference (anova(m0, m))",
               "parametric bootstrap": "likelihood ratio, parametric-bootstrap reference "
                                       "(pbkrtest's PBmodcomp)"}


@cache
def _environment() -> jinja2.Environment:
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("tactorbelt.analysis.report", "templates"),
        autoescape=True, trim_blocks=True, lstrip_blocks=True,
        undefined=jinja2.StrictUndefined)
    env.filters.update(num=formatting.fixed, pval=formatting.p_value4, pct=formatting.percent,
                       g3=formatting.number, joined=formatting.joined, test_text=test_text)
    return env


def rt_from_words(summary: Summary) -> str:
    """Where the RTs count from, in words (``summary.rt_from``)."""
    return ("the onset at the skin (rt_from: skin)" if summary.rt_from == "skin"
            else "the stored onset, the command (rt_from: command)")


def provenance_warnings(summary: Summary) -> list[tuple[str, str]]:
    """What the reader must know about where the data come from: answers from the model
    participant rather than people, and sessions on the simulated belt (nothing
    vibrated), each said separately. A list of (title, message); empty for people on a
    real belt."""
    out: list[tuple[str, str]] = []
    n = len(summary.sessions)
    model, belt = summary.simulated_sessions, summary.simulated_belt_sessions
    if model:
        if len(model) == n:
            msg = ("Every session was answered by the model participant, not by people. The "
                   "numbers show what the model does; they are not evidence about human "
                   "perception.")
        else:
            msg = (f"{len(model)} of {n} sessions were answered by the model participant, "
                   f"not by people ({', '.join(model[:20])}); they are pooled with the "
                   "others below.")
        out.append(("Model participant.", msg))
    people_on_sim = [k for k in belt if k not in set(model)]
    if people_on_sim:
        msg = (f"{len(people_on_sim)} of {n} sessions answered by a person ran on the simulated "
               f"belt ({', '.join(people_on_sim[:20])}): no motor vibrated, so these answers "
               "are not tactile localisation; use them to check the set-up only.")
        out.append(("Simulated belt.", msg))
    return out


def _listing(df: pd.DataFrame, shown: int = MAX_LISTED) -> dict[str, Any] | None:
    """Rows of a stored table, at most ``shown`` (None when there are none)."""
    if df.empty:
        return None
    return {"n": len(df), "headers": [_COLUMN_WORDS.get(str(c), str(c)) for c in df.columns],
            "rows": [[formatting.cell_text(v) for v in r]
                     for r in df.head(shown).itertuples(index=False)],
            "more": max(len(df) - shown, 0), "shown": shown}


def _condition_rows(summary: Summary) -> list[dict[str, Any]]:
    rows = []
    for cond in CONDITIONS:
        for kind in KINDS:
            r = summary.condition_row(cond, kind)
            n = int(r["n"])
            rows.append({"condition": cond, "kind": KIND_LABELS[kind], "n": n,
                         **{k: int(r[k]) for k in ("n_participants", "n_timeout")},
                         "none": "no trials" if n == 0 else "no answered trial",
                         **{k: r[k] for k in ("accuracy", "median_rt_s", "circ_mean_error_deg",
                                              "circ_sd_error_deg")}})
    return rows


def tests_view(tests: list[TestResult]) -> list[dict[str, Any]]:
    """The rows of the statistical tests' table."""
    fmt = formatting.fixed
    rows = []
    for t in tests:
        row: dict[str, Any] = {"test": t.test, "question": t.question, "computed": t.computed,
                               "n": ", ".join(f"{k} {v}" for k, v in t.n.items()),
                               "reason": t.reason}
        rows.append(row)
        if not t.computed:
            continue
        d = t.details
        effect = f"{t.effect_name} = {fmt(t.effect)}"
        if t.key == "between_accuracy" and "odds_ratio" in d:
            odds = d.get("odds_ratio")
            effect += "; odds ratio = " + (fmt(odds) if odds is not None
                                           else str(d.get("odds_ratio_note", "")))
            if orci := d.get("odds_ratio_ci95"):
                effect += (f" [{fmt(orci[0], missing='0')}, {fmt(orci[1], missing='inf')}] "
                           "(conditional MLE, exact interval)")
        if d.get("hodges_lehmann_ci95") is not None:
            hl = d.get("hodges_lehmann", d.get("hodges_lehmann_s"))
            hci = d["hodges_lehmann_ci95"]
            effect += (f"; Hodges-Lehmann {fmt(hl)} [{fmt(hci[0])}, {fmt(hci[1])}] "
                       f"({d.get('hodges_lehmann_method', '')})")
        if t.key == "mixed_model":
            effect += f"; odds ratio = {fmt(d.get('odds_ratio'))}"
        extra = []
        if d.get("method"):
            extra.append(str(d["method"]))
        if d.get("p_method"):
            extra.append("p: " + str(d["p_method"]))
        if tci := d.get("t_interval_ci95"):
            extra.append(f"t interval of the mean difference: [{fmt(tci[0])}, {fmt(tci[1])}]")
        extra += ["warning: " + str(w) for w in d.get("warnings", [])]
        extra += [str(w) for w in d.get("notes", [])]
        row.update(statistic=f"{t.statistic_name} = {fmt(t.statistic)}", p=t.p_value,
                   effect=effect, extra=extra,
                   effect_note=d.get("effect_note") if t.key == "mixed_model" else None,
                   ci=f"[{fmt(t.ci_low)}, {fmt(t.ci_high)}] ({t.ci_name})")
    return rows


def fixed_effects_view(m: dict[str, Any]) -> dict[str, Any]:
    """A model's fixed effects as the coefficient table shows them: Satterthwaite df and
    t when the model has them, else Wald z; a not-estimable term shows its note."""
    satt = any("df" in v for v in m["fixed_effects"].values())
    headers = (["term", "estimate", "SE", "df (Satterthwaite)", "t", "p (t on that df)",
                "95 % t interval"] if satt else
               ["term", "estimate", "SE", "z", "p (Wald z)", "95 % Wald interval"])
    rows = [{**v, "term": k,
             "note": v.get("note", "not estimable") if v.get("estimable") is False else None}
            for k, v in m["fixed_effects"].items()]
    # a not-estimable row: its term, blank cells, and its note in the last column
    return {"satterthwaite": satt, "fixed_headers": headers, "fixed": rows,
            "fixed_blank": len(headers) - 2}


def _condition_tests_view(m: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for t in m.get("tests") or []:
        method = str(t.get("method"))
        fref = t.get("f_reference")
        row: dict[str, Any] = {
            "name": _TEST_WORDS.get(method, method), "statistic": t.get("statistic"),
            "f": ({"statistic": fref.get("statistic"), "df1": fref.get("df1"),
                   "df2": fref.get("df2"), "p": fref.get("p")}
                  if method == "LRT" and fref else None),
            "reason": str(t.get("reason", "")) if t.get("computed") is False else None,
            "df": t.get("df", ""), "p": t.get("p"), "invalid": t.get("valid") is False}
        extra = ""
        if method == "parametric bootstrap":
            extra = (f"{t.get('n_sim')} simulations ({t.get('n_positive', t.get('n_sim'))} "
                     "with LRT* > 0)")
            if ci := t.get("p_mc_ci95"):
                extra += (f"; Monte Carlo 95 % interval of p [{formatting.fixed(ci[0])}, "
                          f"{formatting.fixed(ci[1])}]")
        if row["invalid"]:
            extra = (extra + "; " if extra else "") + str(t.get("why", "not valid"))
        row["extra"] = extra
        rows.append(row)
    return rows


def _separation_view(m: dict[str, Any]) -> dict[str, Any] | None:
    """Cells at 0 or 100 %, the fixed effects they make infinite, and the penalised fit
    beside the maximum-likelihood one (docs/analysis.md, 'Separation')."""
    sep = m.get("separation") or {}
    if not sep.get("cells"):
        return None
    sens = m.get("sensitivity")
    return {
        "cells": [c["label"] for c in sep["cells"]], "terms": sep.get("terms") or [],
        "prior_call": m["fixef_prior"]["call"] if m.get("fixef_prior") else None,
        "sensitivity": None if not sens else {
            "computed": sens.get("computed"), "call": sens["fixef_prior"]["call"],
            "effect": sens.get("condition_effect") or {},
            "fixed": list((sens.get("fixed_effects") or {}).items()),
            "reason": sens.get("reason", "")},
    }


def model_view(m: dict[str, Any]) -> dict[str, Any]:
    """One mixed model: its paragraph, tests of the condition, coefficients, separation
    and random effects."""
    steps = m.get("simplification", [])
    tests = m.get("tests") or []
    return {
        **{k: m[k] for k in ("formula", "family", "criterion", "engine", "scale", "coding",
                             "vcov_method", "p_method", "ci_method")},
        "simplified": steps[:-1] if len(steps) > 1 else [],
        "singular": bool(m.get("singular")),
        "convergence": "; ".join(m.get("convergence", [])),
        "tests": _condition_tests_view(m),
        "wald_terms": next((t.get("terms", []) for t in tests if t.get("method") == "Wald"), []),
        "headline_why": (m.get("headline_test") or {}).get("why", ""),
        **fixed_effects_view(m),
        "separation": _separation_view(m),
        "random": [{"group": g, "sd": list(e.get("sd", {}).items()),
                    "corr": list((e.get("corr") or {}).items())}
                   for g, e in m.get("random_effects", {}).items()],
    }


def _rt_timeouts(rt: dict[str, Any]) -> str:
    cells = rt.get("timeouts_by_cell", [])

    def cell_name(c: dict[str, Any]) -> str:
        name = f"{c['condition']} {'on' if c['on_tactor'] else 'between'}-tactor"
        if c.get("n_targets") is not None and formatting.finite(c.get("n_targets")):
            name += f" {int(c['n_targets'])} targets"
        if c.get("load") not in (None, "none"):
            name += f" under {c['load']}"
        return name

    text = (f"Timeouts have no response time and are left out of this model: "
            f"{sum(c['timeouts'] for c in cells)} of {sum(c['n'] for c in cells)} counted "
            "trials (" + ", ".join(f"{cell_name(c)} {c['timeouts']}/{c['n']}" for c in cells)
            + ").")
    if rt.get("timeout_note"):
        text += " Note: " + rt["timeout_note"] + "."
    return text


def _models_view(summary: Summary) -> dict[str, Any] | None:
    acc, rt = summary.mixed_model, summary.rt_model
    rt_shown = bool(rt and rt.get("computed"))
    if acc is None and not rt_shown:
        return None
    return {"accuracy": None if acc is None else model_view(acc),
            "rt": ({**model_view(rt), "timeouts": _rt_timeouts(rt)}
                   if rt is not None and rt_shown else None)}


def _contrasts_view(summary: Summary) -> dict[str, Any] | None:
    """Dynamic against static at each target count (between-tactor targets), on the
    log-odds and the probability scale, Holm-adjusted across the counts."""
    cs = summary.contrasts
    if not cs:
        return None
    rows = []
    for c in cs:
        pr, n = c["probability"], c["by"].get("n_targets")
        row = {"n": n if n is not None else "all", "estimable": c.get("estimable") is not False}
        if row["estimable"]:
            row.update(estimate=c["estimate"], se=c["se"], z=c["z"], p=c["p"],
                       p_adjusted=c["p_adjusted"], dynamic=pr["dynamic"], static=pr["static"],
                       pp=100 * pr["estimate"] if formatting.finite(pr["estimate"]) else None,
                       pp_se=100 * pr["se"] if formatting.finite(pr["se"]) else None,
                       pp_p_adjusted=pr["p_adjusted"])
        rows.append(row)
    formula = summary.mixed_model and summary.mixed_model.get("formula")
    return {"k": len(cs), "rows": rows, "loads_averaged": "load" in str(formula)}


def _directions(summary: Summary) -> list[Any]:
    d = summary.directions
    if not len(d):
        return []
    order = {k: i for i, k in enumerate(CONDITIONS)}
    d = d.sort_values(["condition", "target_deg"],
                      key=lambda col: col.map(order) if col.name == "condition" else col)
    tuples: Any = d.itertuples(index=False)
    return [{**r._asdict(), "target": f"{r.target_deg:g}", "n": int(r.n)} for r in tuples]


def _participants(summary: Summary) -> dict[str, Any] | None:
    pp = summary.per_participant
    if not (len(pp) and summary.counts["participants_with_test_trials"] > 1):
        return None
    tuples: Any = pp.head(MAX_TABLE_ROWS).itertuples(index=False)
    rows = [{"participant": r.participant, "condition": r.condition,
             "kind": KIND_LABELS[str(r.kind)], "n": int(r.n), "accuracy": r.accuracy,
             "median_rt_s": r.median_rt_s,
             "none": "no trials" if r.n == 0 else "no answered trial"}
            for r in tuples]
    return {"rows": rows, "shown": MAX_TABLE_ROWS, "total": len(pp)}


def render_html(summary: Summary, figures: dict[str, bytes], *,
                generated_at: str | None = None, package_version: str | None = None,
                sites: pd.DataFrame | None = None) -> str:
    """The whole report as one HTML string (figures embedded as data: URIs)."""
    prov = summary.provenance()
    design = summary.design
    s = summary.sessions
    angles = design.targets.angles_deg
    training: Any = summary.training.itertuples(index=False)
    context = {
        "s": summary, "c": summary.counts, "prov": prov,
        "study_names": [st["study_name"] for st in prov["studies"][:3]],
        "package_version": package_version or "", "generated_at": generated_at,
        "warnings": provenance_warnings(summary), "counting_rules": COUNTING_RULES,
        "rt_from_words": rt_from_words(summary),
        "incomplete": _listing(summary.incomplete_sessions),
        "timeouts": _listing(summary.timeouts), "aborted": _listing(summary.aborted),
        "conditions": _condition_rows(summary),
        "training": [[r.condition, str(int(r.n)), formatting.percent(r.accuracy)]
                     for r in training],
        "contrasts": _contrasts_view(summary),
        "cells": cells_view(summary, figures), "load": load_view(summary, figures),
        "tests": tests_view(summary.tests), "models": _models_view(summary),
        "figures": [figure_view(n, figures[n], FIGURE_CAPTIONS[n])
                    for n in FIGURE_ORDER if n in figures],
        "directions": _directions(summary), "participants": _participants(summary),
        "sites": [] if sites is None else list(sites.itertuples(index=False)),
        "design": {
            "layout": ", ".join(f"{a:g}" for a in design.layout.angles_deg),
            "m": design.targets.m,
            "targets": ", ".join(f"{a:g}" for a in angles[:8])
                       + (" ..." if design.targets.m > 8 else ""),
            "law": f"{design.law}, falloff {design.falloff_deg:g}°",
            "fallbacks": "; ".join(design.fallbacks)},
        "sessions": _listing(s[[col for col in _SESSION_COLUMNS if col in s]], MAX_TABLE_ROWS),
    }
    return _environment().get_template("report.html.j2").render(context)
