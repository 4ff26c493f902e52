"""The analysis report: ``analyze()`` writes report.html, summary.json, per_target.csv, PNGs.

:func:`analyze` loads the stores, calls :func:`~tactorbelt.analysis.summary.summarize`,
fetches the cursor samples of a few trials for the trajectory figure (by SQL), draws
the figures and writes the files. :func:`render_html` is pure (a string from a
Summary and the PNG bytes); the HTML is one self-contained file (inline CSS, figures
as base64 ``data:`` URIs) that links only to files written next to it.
:func:`print_summary_table` prints the headline numbers with rich (the demo reuses it).

I/O edge of the analysis (writes files); never imports devices, inputs or the window.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from ..._errors import ConfigError
from ..summary import COUNTING_RULES, Summary
from ..tables.classical import DEFAULT_N_BOOT, TestResult
from ..tables.tables import CONDITIONS, KIND_LABELS, KINDS
from .cells import cells_section
from .tasks import load_section

if TYPE_CHECKING:
    import pandas as pd
    from rich.console import Console

    from ..tables.dataset import StoreData

__all__ = [
    "FIGURE_CAPTIONS",
    "ProgressFn",
    "analyze",
    "choose_sample_trials",
    "print_summary_table",
    "provenance_warnings",
    "render_html",
]

#: ``progress(description, done, total)``: called as the work advances.
ProgressFn = Callable[[str, int, int], None]

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
FIGURE_ORDER: Final = ("fig1b.png", "polar.png", "confusion.png", "trajectories.png",
                       "paired.png")
KNOWN_OUTPUTS: Final = ("report.html", "summary.json", "per_target.csv", "profile_effect.csv",
                        *FIGURE_ORDER)
MAX_TABLE_ROWS: Final = 200
MAX_LISTED: Final = 50


# -- formatting ------------------------------------------------------------------------

def _finite(v: Any) -> bool:
    try:
        return v is not None and math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


def _fmt(v: Any, digits: int = 3, *, missing: str = "n/a") -> str:
    """A number for a table; ``missing`` (a word, never NaN) when there is none."""
    if not _finite(v):
        return missing
    f = float(v) + 0.0  # no "-0.000"
    if round(f, digits) == 0:
        f = 0.0
    if f != 0 and (abs(f) < 10 ** -(digits) or abs(f) >= 1e6):
        return f"{f:.{digits}g}"
    return f"{f:.{digits}f}"


def _p(v: Any) -> str:
    if not _finite(v):
        return "n/a"
    f = float(v)
    return "< 0.0001" if f < 1e-4 else f"{f:.4f}"


def _pct(v: Any, *, missing: str = "n/a") -> str:
    return f"{100 * float(v):.1f} %" if _finite(v) else missing


def _int(v: Any) -> str:
    return str(int(v))


def _e(text: Any) -> str:
    return html.escape(str(text))


def _joined(values: Sequence[Any], limit: int = 30) -> str:
    if not values:
        return "not recorded"
    text = ", ".join(str(v) for v in values[:limit])
    return _e(text + (" ..." if len(values) > limit else ""))


def _table(headers: Sequence[str] | None, rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    """An HTML table; ``headers=None`` for a table of label/value rows (no header row)."""
    head = ("" if headers is None else
            "<thead><tr>" + "".join(f"<th>{_e(h)}</th>" for h in headers) + "</tr></thead>")
    body = "\n".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}">{head}<tbody>\n{body}\n</tbody></table>'


#: stored column names as the report's tables name them
_COLUMN_WORDS = {"session_key": "session", "study_name": "study",
                 "condition_order": "block order", "started_at": "started",
                 "ended_at": "ended", "trial_index": "trial", "target_deg": "target (°)",
                 "response_deg": "response (°)", "rt_s": "response time (s)",
                 "on_tactor": "on-tactor", "n_targets": "targets"}
#: the sessions table's columns, in order
_SESSION_COLUMNS = ("session_key", "participant", "study_name", "condition_order", "seed",
                    "belt", "input", "started_at", "ended_at", "status")


def _cell_text(v: Any) -> str:
    """A stored value as a reader writes it: no NaN, and a JSON list as 'a, b'."""
    if v is None or (isinstance(v, float) and math.isnan(v)) or str(v) == "<NA>":
        return ""
    text = str(v)
    if text.startswith("["):
        try:
            items = json.loads(text)
        except ValueError:
            return text
        if isinstance(items, list):
            return ", ".join(str(i) for i in items)
    return text


# -- content ---------------------------------------------------------------------------

def choose_sample_trials(summary: Summary, per_condition: int = 5, seed: int = 0) -> pd.DataFrame:
    """A few answered test trials per condition for the trajectory figure.

    Takes the first participant (sorted) with answered test trials in both conditions
    (else the first with any), prefers between-tactor targets, distinct targets,
    chosen with a seeded generator.
    """
    import numpy as np

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
    import pandas as pd

    return pd.concat(picks) if picks else ok.iloc[0:0]


def _summary_rows(summary: Summary) -> list[list[str]]:
    rows = []
    for cond in CONDITIONS:
        for kind in KINDS:
            r = summary.conditions.loc[(summary.conditions["condition"] == cond)
                                       & (summary.conditions["kind"] == kind)].iloc[0]
            n = int(r["n"])
            none = "no trials" if n == 0 else "no answered trial"
            rows.append([
                f'<span class="{cond}">{cond}</span>', KIND_LABELS[kind], str(n),
                str(int(r["n_participants"])),
                _pct(r["accuracy"], missing="no trials"),
                _fmt(r["median_rt_s"], missing=none),
                str(int(r["n_timeout"])),
                _fmt(r["circ_mean_error_deg"], 2, missing=none),
                _fmt(r["circ_sd_error_deg"], 2, missing=none),
            ])
    return rows


def _test_rows(tests: Sequence[TestResult]) -> list[list[str]]:
    rows = []
    for t in tests:
        n = ", ".join(f"{k} {v}" for k, v in t.n.items())
        if not t.computed:
            rows.append([_e(t.test), _e(t.question), _e(n),
                         f'<span class="nc">not computed: {_e(t.reason)}</span>', "", "", ""])
            continue
        effect = f"{_e(t.effect_name)} = {_fmt(t.effect)}"
        odds = t.details.get("odds_ratio")
        if t.key == "between_accuracy" and "odds_ratio" in t.details:
            effect += "; odds ratio = " + (
                _fmt(odds) if odds is not None else _e(t.details.get("odds_ratio_note", "")))
            orci = t.details.get("odds_ratio_ci95")
            if orci:
                effect += (f" [{_fmt(orci[0], missing='0')}, {_fmt(orci[1], missing='inf')}] "
                           "(conditional MLE, exact interval)")
        if t.details.get("hodges_lehmann_ci95") is not None:
            hl = t.details.get("hodges_lehmann", t.details.get("hodges_lehmann_s"))
            hci = t.details["hodges_lehmann_ci95"]
            effect += (f"; Hodges-Lehmann {_fmt(hl)} [{_fmt(hci[0])}, {_fmt(hci[1])}] "
                       f"({_e(t.details.get('hodges_lehmann_method', ''))})")
        if t.key == "mixed_model":
            effect += f"; odds ratio = {_fmt(t.details.get('odds_ratio'))}"
            if t.details.get("effect_note"):
                effect = f'<span class="nc">{_e(t.details["effect_note"])}</span>'
        stat = f"{_e(t.statistic_name)} = {_fmt(t.statistic)}"
        ci = f"[{_fmt(t.ci_low)}, {_fmt(t.ci_high)}] ({_e(t.ci_name)})"
        extra = []
        if t.details.get("method"):
            extra.append(_e(t.details["method"]))
        if t.details.get("p_method"):
            extra.append("p: " + _e(t.details["p_method"]))
        if t.details.get("t_interval_ci95"):
            tci = t.details["t_interval_ci95"]
            extra.append(f"t interval of the mean difference: [{_fmt(tci[0])}, {_fmt(tci[1])}]")
        for w in t.details.get("warnings", []):
            extra.append("warning: " + _e(w))
        for w in t.details.get("notes", []):
            extra.append(_e(w))
        rows.append([_e(t.test), _e(t.question), _e(n), stat, _p(t.p_value), effect,
                     ci + ("<br><small>" + "<br>".join(extra) + "</small>" if extra else "")])
    return rows


def _model_paragraph(m: dict[str, Any], what: str, timeouts: str) -> str:
    steps = m.get("simplification", [])
    if len(steps) > 1:
        simp = ("The maximal model was simplified while its fit was singular (a variance "
                "at 0 or a correlation of +-1): " + "; ".join(
                    f"<code>{_e(s['formula'])}</code>: {_e(s['action'])}" for s in steps[:-1])
                + ".")
    else:
        simp = "The maximal model's fit was not singular; nothing was simplified."
    if m.get("singular"):
        simp += " The reported fit is still singular (a participant SD at 0)."
    conv = "; ".join(m.get("convergence", []))
    return (f"<p><strong>{_e(what)}.</strong> <code>{_e(m['formula'])}</code>, "
            f"{_e(m['family'])}, {_e(m['criterion'])}; engine <code>{_e(m['engine'])}</code>. "
            f"{simp} {timeouts} Coefficients are on the {_e(m['scale'])} scale with "
            f"{_e(m['coding'])}; SEs: {_e(m['vcov_method'])}; {_e(m['p_method'])} and "
            f"{_e(m['ci_method'])} 95 % intervals. Convergence: {_e(conv)}.</p>")


def _fixed_rows(m: dict[str, Any]) -> list[list[str]]:
    satt = any("df" in v for v in m["fixed_effects"].values())
    rows = []
    width = 6 if satt else 5
    for k, v in m["fixed_effects"].items():
        if v.get("estimable") is False:  # separation: the numbers mean nothing
            rows.append([f"<code>{_e(k)}</code>"] + [""] * (width - 2)
                        + [f'<span class="nc">{_e(v.get("note", "not estimable"))}</span>'])
            continue
        row = [f"<code>{_e(k)}</code>", _fmt(v["estimate"]), _fmt(v["se"])]
        row += ([_fmt(v.get("df"), 1), _fmt(v.get("t"), 2)] if satt else [_fmt(v["z"], 2)])
        row += [_p(v["p"]), f"[{_fmt(v['ci_low'])}, {_fmt(v['ci_high'])}]"]
        rows.append(row)
    return rows


def _fixed_headers(m: dict[str, Any]) -> list[str]:
    if any("df" in v for v in m["fixed_effects"].values()):
        return ["term", "estimate", "SE", "df (Satterthwaite)", "t", "p (t on that df)",
                "95 % t interval"]
    return ["term", "estimate", "SE", "z", "p (Wald z)", "95 % Wald interval"]


def _tests_table(m: dict[str, Any]) -> str:
    """The tests of the condition (Wald, LRT, parametric bootstrap) and why the headline
    is the one it is."""
    tests = m.get("tests") or []
    if not tests:
        return ""
    head = m.get("headline_test", {})
    words = {"Wald": "Wald chi-square over every condition term (chi-square reference)",
             "LRT": "likelihood ratio, chi-square reference (anova(m0, m))",
             "parametric bootstrap": "likelihood ratio, parametric-bootstrap reference "
                                     "(pbkrtest's PBmodcomp)"}
    rows = []
    for t in tests:
        method = str(t.get("method"))
        name = _e(words.get(method, method))
        fref = t.get("f_reference")
        if method == "LRT" and fref:
            rows.append(["<strong>likelihood ratio, F reference (headline)</strong>",
                         _fmt(t.get("statistic"), 2) + f" (F = {_fmt(fref.get('statistic'), 2)})",
                         _e(f"{fref.get('df1')}, {fref.get('df2')}"), _p(fref.get("p")),
                         _e(f"F({fref.get('df1')}, {fref.get('df2')}): participants - 1 "
                            "denominator df")])
        if t.get("computed") is False:
            rows.append([name, "", "", f'<span class="nc">{_e(t.get("reason", ""))}</span>', ""])
            continue
        extra = ""
        if method == "parametric bootstrap":
            extra = (f"{t.get('n_sim')} simulations ({t.get('n_positive', t.get('n_sim'))} "
                     "with LRT* > 0)")
            ci = t.get("p_mc_ci95")
            if ci:
                extra += f"; Monte Carlo 95 % interval of p [{_fmt(ci[0])}, {_fmt(ci[1])}]"
        p_cell = _p(t.get("p"))
        if t.get("valid") is False:
            extra = (extra + "; " if extra else "") + str(t.get("why", "not valid"))
            p_cell = f'<span class="nc">not valid ({p_cell})</span>'
        rows.append([name, _fmt(t.get("statistic"), 2), _e(t.get("df", "")), p_cell,
                     _e(extra)])
    text = ("<p><strong>Tests of the condition.</strong> Each tests whether the condition "
            "has any effect in the accuracy model: every fixed-effect term containing "
            "<code>condition</code> (" + _e(", ".join(
                next((t.get("terms", []) for t in tests if t.get("method") == "Wald"), [])))
            + ") against 0; the likelihood ratio compares the model with the same model "
            "without those terms (same random effects, both by maximum likelihood). "
            + _e(head.get("why", "")) + "</p>")
    return text + _table(["test", "statistic", "df", "p", "reference distribution"], rows,
                         "num")


def contrasts_section(summary: Summary) -> str:
    """Dynamic against static at each target count (between-tactor targets), on the
    log-odds and the probability scale, Holm-adjusted across the counts."""
    cs = summary.contrasts
    if not cs:
        return ""
    k = len(cs)
    rows = []
    for c in cs:
        pr = c["probability"]
        n = c["by"].get("n_targets")
        if c.get("estimable") is False:
            rows.append([_e(n if n is not None else "all"),
                         '<span class="nc">not estimable (separation: see the accuracy '
                         'model)</span>'] + [""] * 6)
            continue
        rows.append([_e(n if n is not None else "all"),
                     f"{_fmt(c['estimate'])} ({_fmt(c['se'])})", _fmt(c["z"], 2), _p(c["p"]),
                     _p(c["p_adjusted"]),
                     f"{_pct(pr['dynamic'])} vs {_pct(pr['static'])}",
                     f"{_fmt(100 * pr['estimate'] if _finite(pr['estimate']) else None, 1)} "
                     f"({_fmt(100 * pr['se'] if _finite(pr['se']) else None, 1)})",
                     _p(pr["p_adjusted"])])
    title = ("Dynamic against static at each target count" if k > 1 else
             "Dynamic against static")
    head = ["targets", "log-odds difference (SE)", "z", "p", f"p, Holm ({k})",
            "model accuracy, dynamic vs static", "difference, percentage points (SE)",
            f"p, Holm ({k})"]
    text = ("<p>From the accuracy model (below): dynamic minus static at between-tactor "
            "targets (on_tactor = 0)"
            + (", loads averaged with equal weights" if "load" in str(
                summary.mixed_model and summary.mixed_model.get("formula")) else "")
            + ". Left: the log-odds difference, its SE from the model's covariance matrix, "
            "Wald z and two-sided p, as R's <code>emmeans(m, ~ condition | n_targets, at = "
            "list(on_tactor = 0))</code> and <code>pairs()</code>. Right: the same on the "
            "probability scale (emmeans' <code>regrid</code>: the model's accuracy of a "
            "typical participant and target, delta-method SE). "
            + (f"Holm-adjusted p control the family-wise error over the {k} target counts "
               "(<code>adjust = \"holm\"</code> across every count); the unadjusted p are "
               "beside them." if k > 1 else "One target count: nothing to adjust.")
            + "</p>")
    return f"<h2>{_e(title)}</h2>" + text + _table(head, rows, "num")


def _random_text(m: dict[str, Any]) -> str:
    bits = []
    for grp, e in m.get("random_effects", {}).items():
        sds = ", ".join(f"{_e(k)} {_fmt(v)}" for k, v in e.get("sd", {}).items())
        cor = ", ".join(f"{_e(k)} {_fmt(v, 2)}" for k, v in (e.get("corr") or {}).items())
        bits.append(f"{_e(grp)}: SD {sds}" + (f", correlation {cor}" if cor else ""))
    return "<p>Random effects: " + "; ".join(bits) + ".</p>" if bits else ""


def _separation_text(m: dict[str, Any]) -> str:
    """Cells at 0 or 100 %, the fixed effects they make infinite, and the penalised fit
    beside the maximum-likelihood one (docs/analysis.md, 'Separation')."""
    sep = m.get("separation") or {}
    cells = sep.get("cells") or []
    if not cells:
        return ""
    terms = sep.get("terms") or []
    text = (f"<p><strong>Separation.</strong> {len(cells)} design cell(s) at 0 or 100 %: "
            + _e("; ".join(c["label"] for c in cells)) + ". ")
    if m.get("fixef_prior"):
        text += ("The prior on the fixed effects keeps every estimate of this fit finite "
                 "(<code>" + _e(m["fixef_prior"]["call"]) + "</code>).")
    elif terms:
        text += ("Maximum likelihood has no finite estimate of " + ", ".join(
            f"<code>{_e(t)}</code>" for t in terms) + ": the likelihood keeps rising as they "
            "go to infinity, so the numbers any optimiser stops at, their SEs and Wald tests "
            "mean nothing; they are shown as not estimable. The likelihood-ratio tests stay "
            "valid.")
    else:
        text += "No fixed effect is infinite because of them."
    text += "</p>"
    sens = m.get("sensitivity")
    if sens:
        prior = sens["fixef_prior"]
        if sens.get("computed"):
            ce = sens.get("condition_effect") or {}
            text += ("<p><strong>Sensitivity: the penalised fit.</strong> <code>"
                     + _e(prior["call"]) + "</code> (weakly informative normal priors on the "
                     "fixed effects, bglmer's default): static - dynamic at between-tactor "
                     f"targets {_fmt(ce.get('estimate'))} log-odds (SE {_fmt(ce.get('se'))}, "
                     f"95 % Wald [{_fmt(ce.get('ci_low'))}, {_fmt(ce.get('ci_high'))}]). "
                     "Its fixed effects:</p>")
            rows = [[f"<code>{_e(k)}</code>", _fmt(v.get("estimate")), _fmt(v.get("se"))]
                    for k, v in (sens.get("fixed_effects") or {}).items()]
            text += _table(["term", "estimate (penalised)", "SE"], rows, "num")
        else:
            text += ("<p>Sensitivity: the penalised fit (<code>" + _e(prior["call"])
                     + "</code>) failed: " + _e(sens.get("reason", "")) + "</p>")
    return text


def _model_sections(summary: Summary) -> list[str]:
    """One paragraph and one coefficient table per mixed model."""
    out: list[str] = []
    acc = summary.mixed_model
    rt = summary.rt_model
    if acc is None and not (rt and rt.get("computed")):
        return out
    out.append("<h2>Mixed models</h2>")
    if acc is not None:
        out.append(_model_paragraph(
            acc, "Accuracy", "Timeouts count as incorrect answers (the counting rules)."))
        out.append(_tests_table(acc))
        out.append(_table(_fixed_headers(acc), _fixed_rows(acc), "num"))
        out.append(_separation_text(acc))
        out.append(_random_text(acc))
    if rt and rt.get("computed"):
        cells = rt.get("timeouts_by_cell", [])
        k = sum(c["timeouts"] for c in cells)
        n = sum(c["n"] for c in cells)
        def cell_name(c: dict[str, Any]) -> str:
            name = f"{c['condition']} {'on' if c['on_tactor'] else 'between'}-tactor"
            if c.get("n_targets") is not None and _finite(c.get("n_targets")):
                name += f" {int(c['n_targets'])} targets"
            if c.get("load") not in (None, "none"):
                name += f" under {c['load']}"
            return name

        tt = (f"Timeouts have no response time and are left out of this model: {k} of {n} "
              "counted trials (" + ", ".join(
                  f"{cell_name(c)} {c['timeouts']}/{c['n']}" for c in cells) + ").")
        if rt.get("timeout_note"):
            tt += " Note: " + rt["timeout_note"] + "."
        out.append(_model_paragraph(rt, "Response time", _e(tt)))
        out.append(_table(_fixed_headers(rt), _fixed_rows(rt), "num"))
        out.append(_random_text(rt))
    return out


def _listing(df: pd.DataFrame, what: str) -> str:
    if df.empty:
        return f"<p>No {what}.</p>"
    rows = []
    for r in df.head(MAX_LISTED).itertuples(index=False):
        rows.append([_e(_cell_text(v)) for v in r])
    more = (f"<p>... and {len(df) - MAX_LISTED} more (all in the store).</p>"
            if len(df) > MAX_LISTED else "")
    return _table([_COLUMN_WORDS.get(str(c), str(c)) for c in df.columns], rows) + more


def render_html(summary: Summary, figures: dict[str, bytes], *,
                generated_at: str | None = None, package_version: str | None = None,
                sites: pd.DataFrame | None = None) -> str:
    """The whole report as one HTML string (figures embedded as data: URIs)."""
    c = summary.counts
    prov = summary.provenance()
    studies = prov["studies"]
    title = "tactorbelt analysis: " + ", ".join(_e(s["study_name"]) for s in studies[:3])
    parts: list[str] = [
        "<!doctype html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{title}</title>", f"<style>{_CSS}</style></head><body>",
        "<h1>Between-tactor display: analysis report</h1>",
        f'<p class="meta">tactorbelt {_e(package_version or "")} analysis'
        + (f", generated {_e(generated_at)}" if generated_at else "")
        + f"; stores: {_e(', '.join(summary.paths))}</p>",
    ]
    for title, msg in provenance_warnings(summary):
        parts.append(f'<div class="warn"><strong>{_e(title)}</strong> {_e(msg)}</div>')

    # coverage
    parts.append("<h2>What this report covers</h2>")
    parts.append(
        f"<p>{c['participants']} participant(s), {c['sessions']} session(s) in "
        f"{c['stores']} store(s), {c['trials']} trial(s): {c['test_trials']} test-block "
        f"trial(s), of which {c['done']} done, {c['timeout']} timed out and {c['aborted']} "
        f"aborted; {c['training_trials']} training trial(s).</p>")
    parts.append(f"<p><strong>How trials are counted.</strong> {_e(COUNTING_RULES)} "
                 f"So the accuracies below are over {c['counted_trials']} test trial(s) "
                 f"(done + timed out); response times and errors only over answered ones. "
                 "The signed error of a response is the selected target minus the shown "
                 "target, wrapped to (-180°, 180°], clockwise positive.</p>")
    parts.append(f"<p><strong>Response times count from {_rt_from_words(summary)}.</strong>"
                 f" {_e(summary.rt_from_reason)}.</p>")
    inc = summary.incomplete_sessions
    if len(inc):
        parts.append(f"<h3>Incomplete sessions ({len(inc)})</h3><p>Sessions whose status is not "
                     "complete or that have no end time. Their finished trials are counted "
                     "like the others.</p>" + _listing(inc, "incomplete sessions"))
    else:
        parts.append("<p>Every session is complete.</p>")
    parts.append(f"<h3>Timed-out trials ({len(summary.timeouts)})</h3>"
                 "<p>Counted as incorrect (test block), with no response time.</p>"
                 + _listing(summary.timeouts, "timed-out trials"))
    parts.append(f"<h3>Aborted trials ({len(summary.aborted)})</h3>"
                 "<p>Left out of every table and test.</p>"
                 + _listing(summary.aborted, "aborted trials"))

    # results
    parts.append("<h2>Results by condition</h2>")
    parts.append(_table(["condition", "targets", "n trials", "participants", "accuracy",
                         "median RT (s)", "timeouts", "circular mean error (°)",
                         "circular SD of error (°)"], _summary_rows(summary), "num"))
    parts.append("<p><small>Pooled over participants. 'no trials': the data hold no counted "
                 "trial of that kind; 'no answered trial': every one timed out.</small></p>")
    if len(summary.training):
        rows = [[_e(r.condition), _int(r.n), _pct(r.accuracy)]
                for r in summary.training.itertuples(index=False)]
        parts.append("<h3>Training block (not part of any statistic)</h3>"
                     + _table(["condition", "n trials", "accuracy"], rows, "num"))

    parts.append(contrasts_section(summary))
    parts.append(cells_section(summary, figures))
    parts.append(load_section(summary, figures))

    parts.append("<h2>Statistical tests</h2>")
    parts.append("<p>Two-sided tests. Intervals are 95 % bias-corrected and accelerated "
                 f"(BCa) bootstrap intervals ({summary.n_boot} resamples, seed {summary.seed}; "
                 "trials resampled within a condition with one participant, participants "
                 "resampled with several) unless the row says otherwise. Each row names how "
                 "its p was computed (exact or approximate).</p>")
    parts.append(_table(["test", "question", "n", "statistic", "p", "effect size",
                         "95 % interval"], _test_rows(summary.tests), "tests"))
    parts.extend(_model_sections(summary))

    # figures
    parts.append("<h2>Figures</h2>")
    for name in FIGURE_ORDER:
        if name not in figures:
            continue
        data = base64.b64encode(figures[name]).decode("ascii")
        parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{_e(name)}">'
                     f"<figcaption>{_e(FIGURE_CAPTIONS[name])} ({_e(name)})</figcaption></figure>")

    # per direction
    d = summary.directions
    if len(d):
        rows = []
        order = {k: i for i, k in enumerate(CONDITIONS)}
        d = d.sort_values(["condition", "target_deg"],
                          key=lambda col: col.map(order) if col.name == "condition" else col)
        for r in d.itertuples(index=False):
            rows.append([f'<span class="{r.condition}">{_e(r.condition)}</span>',
                         f"{r.target_deg:g}", "yes" if r.on_tactor else "no", _int(r.n),
                         _pct(r.accuracy), _fmt(r.median_rt_s, missing="all timed out"),
                         _fmt(r.mean_signed_error_deg, 2, missing="all timed out"),
                         _fmt(r.circ_sd_error_deg, 2, missing="all timed out")])
        parts.append("<h2>Per direction (pooled over participants)</h2><details><summary>"
                     f"{len(d)} rows</summary>"
                     + _table(["condition", "target (°)", "on-tactor", "n", "accuracy",
                               "median RT (s)", "mean signed error (°)", "circular SD (°)"],
                              rows, "num") + "</details>")

    # per participant
    pp = summary.per_participant
    if len(pp) and c["participants_with_test_trials"] > 1:
        rows = []
        for r in pp.head(MAX_TABLE_ROWS).itertuples(index=False):
            none = "no trials" if r.n == 0 else "no answered trial"
            rows.append([_e(r.participant), f'<span class="{r.condition}">{r.condition}</span>',
                         KIND_LABELS[str(r.kind)], _int(r.n),
                         _pct(r.accuracy, missing="no trials"),
                         _fmt(r.median_rt_s, missing=none)])
        more = (f"<p>First {MAX_TABLE_ROWS} of {len(pp)} rows; per_target.csv has all "
                "participants.</p>" if len(pp) > MAX_TABLE_ROWS else "")
        parts.append("<h2>Per participant</h2><details><summary>"
                     f"{c['participants_with_test_trials']} participants</summary>"
                     + _table(["participant", "condition", "targets", "n", "accuracy",
                               "median RT (s)"], rows, "num") + more + "</details>")

    if sites is not None and len(sites):  # multi-site studies (tables.per_site)
        parts.append("<h2>Per site</h2>" + _table(
            ["site", "condition", "participants", "n", "accuracy", "median RT (s)"],
            [[_e(r.site), _e(r.condition), _int(r.participants), _int(r.n), _pct(r.accuracy),
              _fmt(r.median_rt_s, missing="all timed out")]
             for r in sites.itertuples(index=False)], "num"))

    if summary.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{_e(n)}</li>" for n in summary.notes)
                     + "</ul>")

    # provenance
    parts.append("<h2>Provenance</h2>")
    design = summary.design
    prov_rows = [
        ["study", "<br>".join(f"{_e(s['study_name'])} (SHA-256 <code>{_e(s['study_sha256'])}"
                              "</code>)" for s in studies)],
        ["layout (tactor angles, °)", _e(", ".join(f"{a:g}" for a in design.layout.angles_deg))],
        ["targets", f"{design.targets.m} ("
         + _e(", ".join(f"{a:g}" for a in design.targets.angles_deg[:8]))
         + (" ..." if design.targets.m > 8 else "") + ")"],
        ["amplitude law", _e(f"{design.law}, falloff {design.falloff_deg:g}°")
         + (" <em>(paper defaults: " + _e("; ".join(design.fallbacks)) + ")</em>"
            if design.fallbacks else "")],
        ["package version(s) that ran the sessions", _joined(prov["package_versions"])],
        ["belt(s)", _joined(prov["belts"])],
        ["firmware version(s)", _joined(prov["firmware_versions"])],
        ["input(s)", _joined(prov["inputs"])],
        ["session seeds", _joined(prov["session_seeds"])],
        ["analysis seed (bootstrap)", f"{summary.seed} ({summary.n_boot} resamples)"],
    ]
    parts.append(_table(None, prov_rows, "prov"))
    s = summary.sessions
    cols = [col for col in _SESSION_COLUMNS if col in s]
    srows = [[_e(_cell_text(v)) for v in r]
             for r in s[cols].head(MAX_TABLE_ROWS).itertuples(index=False)]
    more = (f"<p>First {MAX_TABLE_ROWS} of {len(s)} sessions.</p>"
            if len(s) > MAX_TABLE_ROWS else "")
    table = _table([_COLUMN_WORDS.get(c, c) for c in cols], srows)
    parts.append(f"<h3>Sessions ({len(s)})</h3><details open><summary>start, end and status"
                 "</summary>" + table + more + "</details>")
    parts.append('<h2>Files</h2><p>Next to this report: <a href="summary.json">summary.json</a>'
                 ' (headline numbers and tests), <a href="per_target.csv">per_target.csv</a> '
                 "(per participant, condition and target) and the figures as PNG.</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;
margin-top:1.6em}h3{margin-bottom:.3em}
.meta{color:#666;font-size:.9em}
.warn{background:#fff4e5;border-left:5px solid #D55E00;padding:.7em 1em;margin:1em 0}
table{border-collapse:collapse;margin:.6em 0;font-size:.88em}
th,td{border:1px solid #ddd;padding:.3em .55em;text-align:left;vertical-align:top}
th{background:#f3f3f3}table.num td{text-align:right}table.num td:first-child,
table.num td:nth-child(2){text-align:left}
.static{color:#0072B2;font-weight:600}.dynamic{color:#D55E00;font-weight:600}
.nc{color:#8a4b00}figure{margin:1.2em 0}img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.88em;color:#444;margin-top:.3em}code{font-size:.85em}
details summary{cursor:pointer;color:#0072B2}
"""


# -- console ---------------------------------------------------------------------------

def _rt_from_words(summary: Summary) -> str:
    """Where the RTs count from, in words (``summary.rt_from``)."""
    return ("the onset at the skin (rt_from: skin)" if summary.rt_from == "skin"
            else "the stored onset, the command (rt_from: command)")


def print_summary_table(summary: Summary, console: Console | None = None) -> None:
    """Print accuracy and median RT per condition, on- and between-tactor (rich)."""
    from rich.console import Console
    from rich.table import Table

    con = console or Console()
    table = Table(title="Accuracy and median response time (test block)")
    table.add_column("condition")
    table.add_column("targets")
    table.add_column("n", justify="right")
    table.add_column("accuracy", justify="right")
    table.add_column("median RT (s)", justify="right")
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
    con.print(f"Response times from {_rt_from_words(summary)}: {summary.rt_from_reason}",
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


# -- files -----------------------------------------------------------------------------

def _package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("tactorbelt")
    except PackageNotFoundError:  # pragma: no cover
        return "unknown"


def _sites(data: StoreData, summary: Summary) -> pd.DataFrame | None:
    """The per-site table when the sessions come from two sites or more."""
    from ..tables.tables import per_site

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
    from ..summary import summarize
    from ..tables.load import analysis_seed, load_samples, load_stores
    from .figures import make_figures
    from .tasks_figures import TASK_FIGURE_ORDER

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
        from ..models.glmm import FixefPrior

        try:
            prior = FixefPrior.parse(fixef_prior)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    tick("loading stores")
    data = load_stores(list(paths), sites=sites, include_running=include_running)
    if seed is None:
        seed = analysis_seed(data)
    tick("computing tables and tests")
    from ..models.lme4 import Lme4Unavailable

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
        for name in FIGURE_ORDER:  # stale figures of an earlier run would mislead
            if name not in figures and (out / name).is_file():
                (out / name).unlink()
        for old in [*out.glob("fig1b-*.png"), out / "resolution.png",  # factorial, load
                    *(out / n for n in TASK_FIGURE_ORDER)]:
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
                        package_version=_package_version(), sites=_sites(data, summary)),
            encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write the report to {out}: {exc.strerror}") from None
    tick("done")
    return summary
