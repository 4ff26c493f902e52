"""R's tests of the condition, the reference the tests (and benchmarks/bench_condition_tests.py)
hold tactorbelt's against: glmer fits, ``anova(m0, m)``, pbkrtest's ``PBmodcomp`` (on
simulated or given responses, refitted by ``refit`` and afresh) and emmeans' contrasts;
whether R and lme4 are here to run them (:func:`lme4_available`).

The report's ``--engine lme4`` runs only the bootstrap
(:func:`tactorbelt.analysis.models.lme4.condition_tests_lme4`).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from tactorbelt.analysis.models.lme4 import (
    _FLATTEN,
    READ_TWO_MODELS,
    _rscript,
    _write_model,
    run_tests_script,
)

if TYPE_CHECKING:
    import pandas as pd

    from tactorbelt.analysis.models.glmm import ModelSpec


def lme4_available(rscript: str = "Rscript") -> str | None:
    """None when ``Rscript`` runs and lme4 loads; else why not, in words."""
    exe = shutil.which(rscript)
    if exe is None:
        return f"'{rscript}' is not on PATH"
    try:
        r = subprocess.run([exe, "-e", "suppressPackageStartupMessages(library(lme4))"],
                           capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"'{rscript}' failed to run: {exc}"
    if r.returncode != 0:
        return "the R package lme4 is not installed (" + (r.stderr.strip().splitlines()
                                                         or ["no message"])[-1] + ")"
    return None


_TESTS_SCRIPT: Final = _FLATTEN + r"""
suppressPackageStartupMessages(library(lme4))
args <- commandArgs(trailingOnly = TRUE)
dir <- args[1]; nsim <- as.integer(args[2]); seed <- as.integer(args[3])
want_em <- args[4] == "1"
""" + READ_TWO_MODELS + r"""
msgs <- character(0)
m <- withCallingHandlers(glmer(form, data = d, family = binomial),
  warning = function(w) { msgs <<- c(msgs, conditionMessage(w)); invokeRestart("muffleWarning") },
  message = function(w) { msgs <<- c(msgs, conditionMessage(w)); invokeRestart("muffleMessage") })
writeLines(unique(c(flat_msgs(msgs), flat_msgs(m@optinfo$conv$lme4$messages))),
           file.path(dir, "messages.txt"))
cf <- fixef(m)
write.csv(data.frame(term = names(cf), estimate = unname(cf)), file.path(dir, "fixef.csv"),
          row.names = FALSE)
write.csv(as.matrix(vcov(m)), file.path(dir, "vcov.csv"), row.names = FALSE)
m0 <- quiet(glmer(form0, data = d, family = binomial))
a <- anova(m0, m)
out <- c(lrt = a$Chisq[2], lrt_df = a$Df[2], lrt_p = a[["Pr(>Chisq)"]][2],
         deviance = -2 * as.numeric(logLik(m)), deviance0 = -2 * as.numeric(logLik(m0)))
t0 <- proc.time()[["elapsed"]]
if (file.exists(file.path(dir, "sims.csv")) || nsim > 0) {
  suppressPackageStartupMessages(library(pbkrtest))
  if (file.exists(file.path(dir, "sims.csv"))) {
    Y <- read.csv(file.path(dir, "sims.csv"))
    ref <- vapply(Y, function(y) {
      s0 <- quiet(refit(m0, newresp = y)); s1 <- quiet(refit(m, newresp = y))
      2 * (as.numeric(logLik(s1)) - as.numeric(logLik(s0)))
    }, numeric(1))
    pb <- PBmodcomp(m, m0, ref = ref)
    resp <- all.vars(form)[1]
    fresh <- vapply(Y, function(y) {
      d2 <- d; d2[[resp]] <- y
      s0 <- quiet(glmer(form0, data = d2, family = binomial))
      s1 <- quiet(glmer(form, data = d2, family = binomial))
      2 * (as.numeric(logLik(s1)) - as.numeric(logLik(s0)))
    }, numeric(1))
    out <- c(out, pb_p_fresh = PBmodcomp(m, m0, ref = fresh)$test["PBtest", "p.value"])
    writeLines(format(unname(fresh), digits = 15), file.path(dir, "ref_fresh.txt"))
  } else {
    pb <- quiet(PBmodcomp(m, m0, nsim = nsim, seed = seed))
    ref <- pb$ref
  }
  if (is.null(ref)) ref <- attr(pb, "ref")
  out <- c(out, pb_p = pb$test["PBtest", "p.value"], pb_nsim = length(ref),
           pb_npos = sum(ref > 0))
  writeLines(format(unname(ref), digits = 15), file.path(dir, "ref.txt"))
}
out <- c(out, seconds_tests = proc.time()[["elapsed"]] - t0)
write.csv(data.frame(key = names(out), value = format(unname(out), digits = 15)),
          file.path(dir, "tests.csv"), row.names = FALSE)
if (want_em) {
  suppressPackageStartupMessages(library(emmeans))
  by_count <- grepl("factor(n_targets)", paste(deparse(form), collapse = ""), fixed = TRUE)
  em <- if (by_count)
    emmeans(m, ~ condition | n_targets, at = list(on_tactor = 0)) else
    emmeans(m, ~ condition, at = list(on_tactor = 0))
  lo <- as.data.frame(test(pairs(em), adjust = "holm", by = NULL))
  pr <- as.data.frame(test(pairs(regrid(em)), adjust = "holm", by = NULL))
  lo$scale <- "log-odds"; pr$scale <- "probability"
  if (!"n_targets" %in% names(lo)) { lo$n_targets <- NA; pr$n_targets <- NA }
  keep <- c("contrast", "n_targets", "estimate", "SE", "z.ratio", "p.value", "scale")
  write.csv(rbind(lo[, keep], pr[, keep]), file.path(dir, "contrasts.csv"), row.names = FALSE)
}
"""


def r_condition_tests(df: pd.DataFrame, spec: ModelSpec, spec0: ModelSpec, *,
                      n_sim: int = 0, seed: int = 0, responses: Any = None,
                      contrasts: bool = False, rscript: str = "Rscript",
                      timeout_s: float = 3600.0) -> dict[str, Any]:
    """R's tests of the condition for the accuracy GLMM ``spec`` against ``spec0``.

    Fits both with ``glmer`` and returns ``anova(m0, m)`` (``lrt``, ``lrt_df``,
    ``lrt_p``; ``beta``, ``vcov`` and ``messages`` of the fit of ``spec``), with
    ``n_sim`` or ``responses`` pbkrtest's ``PBmodcomp(m, m0)``
    (``pb_p``, ``pb_nsim``, ``pb_npos``, ``ref``; ``responses``: an ``(n_sim, N)`` array
    of 0/1 responses to refit instead of ``simulate(m0)``; then also ``ref_fresh`` and
    ``pb_p_fresh``: the same with both models fitted afresh to each response, not by
    ``refit``, which starts from the data's estimates and sometimes stops short of the
    optimum), and with ``contrasts`` the
    emmeans contrasts ``test(pairs(emmeans(m, ~ condition | n_targets, at =
    list(on_tactor = 0))), adjust = "holm", by = NULL)`` on the log-odds and (``regrid``)
    probability scales (``contrasts``: a DataFrame with columns ``contrast, n_targets,
    estimate, SE, z, p_value, scale``).

    Raises:
        Lme4Unavailable: no Rscript or lme4; RuntimeError: R failed.
    """
    import numpy as np
    import pandas as pd

    exe = _rscript(rscript)
    with tempfile.TemporaryDirectory(prefix="tactorbelt-lme4-") as tmp:
        d = Path(tmp)
        _write_model(d, df, spec)
        (d / "formula0.txt").write_text(spec0.formula() + "\n")
        if responses is not None:
            y = np.asarray(responses, dtype=int)
            pd.DataFrame(y.T, columns=[f"s{i}" for i in range(y.shape[0])]).to_csv(
                d / "sims.csv", index=False)
        run_tests_script(exe, d, _TESTS_SCRIPT,
                         [str(int(n_sim)), str(int(seed)), "1" if contrasts else "0"], timeout_s)
        vals = dict(pd.read_csv(d / "tests.csv").itertuples(index=False, name=None))
        out: dict[str, Any] = {k: float(v) for k, v in vals.items()}
        fx = pd.read_csv(d / "fixef.csv")
        out["beta"] = dict(zip(fx["term"].astype(str), fx["estimate"].astype(float),
                               strict=True))
        out["vcov"] = pd.read_csv(d / "vcov.csv").to_numpy(dtype=float)
        out["messages"] = [m for m in (d / "messages.txt").read_text().splitlines()
                           if m.strip() and m.strip() != "NULL"]
        for name in ("ref", "ref_fresh"):
            if (d / f"{name}.txt").exists():
                out[name] = np.array([float(v) for v in
                                      (d / f"{name}.txt").read_text().split()])
        if contrasts:
            out["contrasts"] = pd.read_csv(d / "contrasts.csv").rename(
                columns={"p.value": "p_value", "z.ratio": "z"})
    return out
