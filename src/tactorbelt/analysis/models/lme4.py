"""Fit a mixed model with R's lme4 (``glmer`` / ``lmer``) through ``Rscript``.

The ``--engine lme4`` of ``tactorbelt analyze`` and the cross-check of
:mod:`tactorbelt.analysis.models.glmm`: the model frame is written to a CSV file in a
temporary directory, a short R script fits the model with lme4's defaults (``glmer``:
Laplace, ``nAGQ = 1``, default optimisers and ``vcov``; ``lmer``: REML) and writes
plain CSV tables back, which become a :class:`~tactorbelt.analysis.models.glmm.MixedModelFit`.
No rpy2: only the ``Rscript`` executable and the lme4 package are needed
(Debian/Ubuntu: ``apt install r-base-core r-cran-lme4``).

I/O (temporary files, a subprocess).
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Final

import pandas as pd

from .glmm import FixedEffect, FixefPrior, MixedModelFit, ModelSpec, _fixed_table, term_column

__all__ = ["INSTALL_HINT", "Lme4Unavailable", "condition_tests_lme4", "fit_lme4"]

INSTALL_HINT: Final = ("R with lme4 is needed for --engine lme4: install it with "
                       "'apt install r-base-core r-cran-lme4' (Debian/Ubuntu), or "
                       "install.packages('lme4') in R, so that 'Rscript' is on PATH")

#: R: every message as one character vector, whatever shape lme4 keeps it in (a
#: character vector, or a list when glmer has several convergence messages)
_FLATTEN: Final = r"""
flat_msgs <- function(x) {
  if (is.null(x) || length(x) == 0) return(character(0))
  out <- unlist(lapply(x, function(e) if (inherits(e, "condition")) conditionMessage(e)
                                      else as.character(e)), use.names = FALSE)
  out <- trimws(gsub("[\r\n]+", " ", out))
  out[nzchar(trimws(out))]
}
"""

_SCRIPT: Final = _FLATTEN + r"""
suppressPackageStartupMessages(library(lme4))
args <- commandArgs(trailingOnly = TRUE)
dir <- args[1]; family <- args[2]; form <- as.formula(readLines(file.path(dir, "formula.txt")))
prior <- if (length(args) >= 3 && nzchar(args[3])) args[3] else ""
if (nzchar(prior)) suppressPackageStartupMessages(library(blme))
g <- readLines(file.path(dir, "groups.txt"))
d <- read.csv(file.path(dir, "data.csv"), stringsAsFactors = FALSE,
              colClasses = setNames(rep("character", length(g)), g))
msgs <- character(0)
lt <- family != "binomial" && requireNamespace("lmerTest", quietly = TRUE)
m <- withCallingHandlers(
  if (nzchar(prior)) eval(parse(text = sprintf(
    "bglmer(form, data = d, family = binomial, fixef.prior = %s)", prior))) else
  if (family == "binomial") glmer(form, data = d, family = binomial) else
    if (lt) lmerTest::lmer(form, data = d) else lmer(form, data = d),
  warning = function(w) { msgs <<- c(msgs, conditionMessage(w)); invokeRestart("muffleWarning") },
  message = function(w) { msgs <<- c(msgs, conditionMessage(w)); invokeRestart("muffleMessage") })
cf <- summary(m)$coefficients
fx <- data.frame(term = rownames(cf), estimate = cf[, 1], se = cf[, 2])
if ("df" %in% colnames(cf)) {
  fx$df <- cf[, "df"]; fx$t <- cf[, "t value"]; fx$p <- cf[, "Pr(>|t|)"]
}
write.csv(fx, file.path(dir, "fixef.csv"), row.names = FALSE)
V <- as.matrix(vcov(m))
write.csv(V, file.path(dir, "vcov.csv"), row.names = FALSE)
th <- getME(m, "theta")
write.csv(data.frame(name = names(th), theta = unname(th), lower = getME(m, "lower")),
          file.path(dir, "theta.csv"), row.names = FALSE)
vc <- as.data.frame(VarCorr(m))
write.csv(vc, file.path(dir, "varcorr.csv"), row.names = FALSE)
msgs <- unique(c(flat_msgs(msgs), flat_msgs(m@optinfo$conv$lme4$messages),
                 flat_msgs(m@optinfo$warnings), flat_msgs(m@optinfo$conv$lme4$warnings)))
info <- data.frame(
  key = c("singular", "deviance", "loglik", "lme4_version", "R_version", "nobs"),
  value = c(as.character(isSingular(m)), format(-2 * as.numeric(logLik(m)), digits = 15),
            format(as.numeric(logLik(m)), digits = 15), as.character(packageVersion("lme4")),
            paste(R.version$major, R.version$minor, sep = "."), as.character(nobs(m))))
write.csv(info, file.path(dir, "info.csv"), row.names = FALSE)
writeLines(msgs, file.path(dir, "messages.txt"))
"""


class Lme4Unavailable(RuntimeError):
    """Rscript or the lme4 package is missing."""


def _rscript(rscript: str) -> str:
    """The path of ``rscript``, or Lme4Unavailable saying how to install R."""
    exe = shutil.which(rscript)
    if exe is None:
        raise Lme4Unavailable(f"'{rscript}' is not on PATH. {INSTALL_HINT}")
    return exe


def _write_model(d: Path, df: pd.DataFrame, spec: ModelSpec) -> None:
    """The model's data, formula and grouping factors, as the R scripts read them."""
    _frame(df, spec).to_csv(d / "data.csv", index=False)
    (d / "formula.txt").write_text(spec.formula() + "\n")
    (d / "groups.txt").write_text("".join(f"{t.group}\n" for t in spec.random))


def _r_env() -> dict[str, str]:
    """R's environment with one BLAS thread: threaded sums change glmer's path in the
    4th digit from run to run."""
    return {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _frame(df: pd.DataFrame, spec: ModelSpec) -> pd.DataFrame:
    """The columns the formula uses; booleans as 0/1 (lme4 then names them plainly)."""
    cols = list(dict.fromkeys([spec.response, *(term_column(f) for f in spec.fixed),
                               *(t.group for t in spec.random),
                               *(s for t in spec.random for s in t.slopes)]))
    out = df[cols].copy()
    for c in cols:
        if pd.api.types.is_bool_dtype(out[c]):
            out[c] = out[c].astype(int)
    return out


def fit_lme4(df: pd.DataFrame, spec: ModelSpec, *, family: str = "binomial",
             rscript: str = "Rscript", timeout_s: float = 600.0,
             fixef_prior: FixefPrior | None = None) -> MixedModelFit:
    """Fit ``spec`` with ``lme4::glmer(family = binomial)`` (or ``lmer`` for ``gaussian``).

    With ``fixef_prior``: ``blme::bglmer(family = binomial, fixef.prior = ...)`` (bglmer's
    default covariance prior), from R's blme package.

    Raises:
        Lme4Unavailable: no ``Rscript`` or no lme4 (the message says how to install).
        RuntimeError: R failed (its last error lines are quoted).
    """
    exe = _rscript(rscript)
    with tempfile.TemporaryDirectory(prefix="tactorbelt-lme4-") as tmp:
        d = Path(tmp)
        _write_model(d, df, spec)
        run_tests_script(exe, d, _SCRIPT, [family, "" if fixef_prior is None
                                           else fixef_prior.blme()], timeout_s, who="lme4")
        fx = pd.read_csv(d / "fixef.csv")
        vcov = pd.read_csv(d / "vcov.csv").to_numpy(dtype=float)
        th = pd.read_csv(d / "theta.csv")
        vc = pd.read_csv(d / "varcorr.csv")
        info = dict(pd.read_csv(d / "info.csv", dtype=str).itertuples(index=False,
                                                                      name=None))
        msgs = [m for m in (d / "messages.txt").read_text().splitlines() if m.strip()]
    names = fx["term"].astype(str).tolist()
    beta = fx["estimate"].to_numpy(dtype=float)
    fixed: dict[str, FixedEffect] = _fixed_table(names, beta, vcov)
    random: dict[str, dict[str, object]] = {}
    for row in vc.itertuples(index=False):
        grp, v1, v2, sdcor = str(row.grp), row.var1, row.var2, float(str(row.sdcor))
        entry = random.setdefault(grp, {"sd": {}})
        if grp == "Residual":
            entry["sd"]["(Intercept)"] = sdcor  # type: ignore[index]
        elif isinstance(v2, str) and v2:
            entry.setdefault("corr", {})[f"{v1},{v2}"] = (  # type: ignore[index]
                sdcor if math.isfinite(sdcor) else None)
        else:
            entry["sd"][str(v1)] = sdcor  # type: ignore[index]
    groups = {g: int(df[g].nunique()) for g in (t.group for t in spec.random)}
    for g, n in groups.items():
        if g in random:
            random[g]["levels"] = n
    satt = None
    if "df" in fx:
        satt = {str(r["term"]): {"df": float(r["df"]), "t": float(r["t"]), "p": float(r["p"])}
                for r in fx.to_dict("records")}
    dev = float(info["deviance"])
    return MixedModelFit(
        spec=spec, family=family, fixed_effects=fixed, vcov=vcov, random_effects=random,
        theta=th["theta"].to_numpy(dtype=float), singular=info["singular"] == "TRUE",
        theta_names=th["name"].astype(str).tolist(),
        deviance=dev, loglik=float(info["loglik"]),
        vcov_method=(("blme's " if fixef_prior is not None else "lme4's ")
                     + "vcov(): finite-difference Hessian over (theta, beta)"
                     if family == "binomial" else "lme4's vcov(): sigma^2 (R_X' R_X)^-1"),
        converged=not any("converge" in m.lower() for m in msgs),
        messages=[*msgs, f"lme4 {info['lme4_version']}, R {info['R_version']}"],
        n_obs=int(info["nobs"]), n_cells=int(info["nobs"]), groups=groups,
        criterion=("REML" if family != "binomial" else "ML (Laplace)" if fixef_prior is None
                   else "penalised ML (Laplace), bglmer"),
        satterthwaite=satt, fixef_prior=fixef_prior,
    )


#: R: the two models' formulas (``form``, ``form0``) and the data of a tests script's
#: directory, and ``quiet`` (a script's ``dir`` is set before it).
READ_TWO_MODELS: Final = r"""
form <- as.formula(readLines(file.path(dir, "formula.txt")))
form0 <- as.formula(readLines(file.path(dir, "formula0.txt")))
g <- readLines(file.path(dir, "groups.txt"))
d <- read.csv(file.path(dir, "data.csv"), stringsAsFactors = FALSE,
              colClasses = setNames(rep("character", length(g)), g))
quiet <- function(expr) suppressWarnings(suppressMessages(expr))
"""

_PB_SCRIPT: Final = r"""
suppressPackageStartupMessages(library(lme4))
args <- commandArgs(trailingOnly = TRUE)
dir <- args[1]; nsim <- as.integer(args[2]); seed <- as.integer(args[3])
""" + READ_TWO_MODELS + r"""
m <- quiet(glmer(form, data = d, family = binomial))
m0 <- quiet(glmer(form0, data = d, family = binomial))
a <- anova(m0, m)
out <- c(lrt = a$Chisq[2], lrt_df = a$Df[2], lrt_p = a[["Pr(>Chisq)"]][2],
         deviance = -2 * as.numeric(logLik(m)), deviance0 = -2 * as.numeric(logLik(m0)))
t0 <- proc.time()[["elapsed"]]
suppressPackageStartupMessages(library(pbkrtest))
pb <- quiet(PBmodcomp(m, m0, nsim = nsim, seed = seed))
ref <- pb$ref
if (is.null(ref)) ref <- attr(pb, "ref")
out <- c(out, pb_p = pb$test["PBtest", "p.value"], pb_nsim = length(ref),
         pb_npos = sum(ref > 0), seconds_tests = proc.time()[["elapsed"]] - t0)
write.csv(data.frame(key = names(out), value = format(unname(out), digits = 15)),
          file.path(dir, "tests.csv"), row.names = FALSE)
"""


def run_tests_script(exe: str, d: Path, script: str, args: list[str],
                     timeout_s: float, who: str = "R") -> None:
    """Run an R script (written to ``d/tests.R``) on the model files in ``d``; ``who``:
    ``lme4`` for the model fit (its messages name the package missing, blme or lme4).

    Raises:
        Lme4Unavailable: an R package is missing; RuntimeError: R failed or timed out.
    """
    (d / "tests.R").write_text(script)
    try:
        r = subprocess.run([exe, str(d / "tests.R"), str(d), *args],
                           capture_output=True, text=True, timeout=timeout_s, env=_r_env())
    except subprocess.TimeoutExpired as exc:
        raise RuntimeError(f"{who} took longer than {timeout_s:g} s") from exc
    if r.returncode != 0:
        err = r.stderr.strip()
        missing = "there is no package called" in err
        if missing and who == "lme4" and "blme" in err:
            raise Lme4Unavailable("the R package blme is not installed (the penalised fit's "
                                  "reference): 'apt install r-cran-blme' or "
                                  "install.packages('blme') in R")
        if missing and who == "lme4" and "lme4" in err:
            raise Lme4Unavailable(f"the R package lme4 is not installed. {INSTALL_HINT}")
        if missing and who == "R":
            raise Lme4Unavailable("an R package is missing: " + err.splitlines()[-1])
        raise RuntimeError(f"{who} failed: " + " | ".join(err.splitlines()[-5:]))


def condition_tests_lme4(df: pd.DataFrame, spec: ModelSpec, spec0: ModelSpec, *,
                         n_sim: int, seed: int = 0, rscript: str = "Rscript",
                         timeout_s: float = 3600.0) -> dict[str, float]:
    """pbkrtest's ``PBmodcomp(m, m0, nsim = n_sim, seed = seed)`` in R for the accuracy
    GLMM ``spec`` against ``spec0`` (both fitted by ``glmer``): ``pb_p``, ``pb_nsim``,
    ``pb_npos``, with ``anova(m0, m)``'s ``lrt``, ``lrt_df``, ``lrt_p``.

    (The R cross-checks of the tests, with given responses and emmeans' contrasts, are
    ``tests/support/r_reference.py``.)

    Raises:
        Lme4Unavailable: no Rscript, lme4 or pbkrtest; RuntimeError: R failed.
    """
    exe = _rscript(rscript)
    with tempfile.TemporaryDirectory(prefix="tactorbelt-lme4-") as tmp:
        d = Path(tmp)
        _write_model(d, df, spec)
        (d / "formula0.txt").write_text(spec0.formula() + "\n")
        run_tests_script(exe, d, _PB_SCRIPT, [str(int(n_sim)), str(int(seed))], timeout_s)
        vals = dict(pd.read_csv(d / "tests.csv").itertuples(index=False, name=None))
    return {k: float(v) for k, v in vals.items()}
