"""Mixed models by maximum likelihood, computed the way ``lme4`` computes them.

Two models, both over the trials table's own column names (docs/analysis.md):

- :func:`fit_glmm`: a binomial GLMM with a logit link, fitted by maximum likelihood
  with the Laplace approximation, as ``lme4::glmer(..., family = binomial)`` does by
  default (``nAGQ = 1``).
- :func:`fit_lmm`: a linear mixed model fitted by REML, as ``lme4::lmer`` does by default.

Why an implementation of our own: statsmodels has no Laplace GLMM (its
``BinomialBayesMixedGLM`` is variational Bayes, whose posterior SDs are not glmer's
standard errors), GPBoost's grouped random coefficients are uncorrelated with the
intercept (no ``(1 + condition | participant)``), and pymer4 needs R. The algorithm is
lme4's (Bates et al. 2015, "Fitting linear mixed-effects models using lme4", J. Stat.
Softw. 67(1); the GLMM part is ``vignette("PIRLS")`` / the ``glmer`` sources):

- Random effects ``b = Lambda(theta) u`` with spherical ``u ~ N(0, I)``; ``Lambda`` is
  block-diagonal with one lower-triangular factor ``T_k`` per random-effects term
  (``theta`` = the lower triangles, column by column; diagonal elements >= 0).
- Penalised IRLS (Newton steps with step halving) finds the conditional modes ``u``
  given ``(theta, beta)``; the Laplace deviance is
  ``sum(deviance residuals) + |u|^2 + log det(L L')`` with
  ``L L' = Lambda' Z' W Z Lambda + I`` at the modes (``W``: the IRLS weights).
- Stage 1 (glmer's ``nAGQ = 0``) optimises ``theta`` only, with ``beta`` and ``u``
  jointly at their penalised modes; stage 2 optimises the Laplace deviance over
  ``(theta, beta)`` from there (L-BFGS-B, bounds for the diagonal of ``theta``, central
  difference gradients).
- Standard errors: as glmer's default ``vcov`` (``use.hessian = TRUE``), twice the
  inverse of the finite-difference Hessian of the deviance over ``(theta, beta)``
  (lme4's ``deriv12``, step 1e-4), its ``beta`` block; when that Hessian is not
  positive definite, the conditional ``(R_X' R_X)^{-1}`` given ``theta``, as lme4
  falls back (and says so in ``messages``).
- A fit is *singular* when an element of ``theta`` with lower bound 0 is below 1e-4
  (lme4's ``isSingular`` rule).

Fixed effects use R's default treatment coding: for a text column the alphabetically
first level is the reference and the columns are named ``<column><level>``; a numeric
column (a 0/1 ``on_tactor``) enters as it is, named by the column; interactions are
``a:b``, columns of the first factor varying fastest; terms ordered by degree. Columns
that are linear combinations of earlier ones are dropped, as lme4 drops them (named in
``messages``).

Speed: Bernoulli rows with the same covariates and groups are pooled into binomial
counts (the same likelihood); the random effects of the term with the most levels
(participants) are eliminated block by block and the other terms (targets) form a
small dense Schur complement, so 100 participants x 480 trials fit in a few seconds.

Pure: NumPy, SciPy and pandas; no I/O.
"""

from __future__ import annotations

import functools
import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Final, ParamSpec, TypeVar

import numpy as np
import pandas as pd
from scipy.optimize import minimize  # SciPy's OpenBLAS loaded before one_blas_thread looks
from scipy.special import expit
from scipy.stats import norm

__all__ = [
    "SINGULAR_TOL",
    "FixedEffect",
    "FixefPrior",
    "GlmmData",
    "LmmData",
    "MixedModelFit",
    "ModelSpec",
    "RandomTerm",
    "fit_glmm",
    "fit_lmm",
    "fit_simplified",
    "fixed_design",
    "glmm_fit",
    "one_blas_thread",
    "simplify_step",
    "term_column",
    "term_levels",
]

#: lme4's ``isSingular`` tolerance on the elements of theta bounded below by 0.
SINGULAR_TOL: Final = 1e-4
#: lme4's ``deriv12`` step for the Hessian behind glmer's standard errors.
HESSIAN_STEP: Final = 1e-4
#: The smallest IRLS weight per trial, as R's ``binomial()`` bounds ``mu.eta`` and the
#: variance (``DBL_EPSILON``): a cell whose fitted probability rounds to 0 or 1 keeps a
#: positive weight instead of making the system singular (only ``|eta| > 36`` reaches it).
WEIGHT_FLOOR: Final = float(np.finfo(float).eps)
#: The smallest diagonal element of theta the optimiser tries under a covariance prior
#: (which is infinite at 0).
PRIOR_THETA_FLOOR: Final = 1e-6
Z95: Final = 1.959963984540054


@dataclass(frozen=True)
class RandomTerm:
    """One random-effects term ``(1 + slopes | group)``.

    Attributes:
        group: the grouping column (``participant``, ``target``).
        slopes: columns with a random slope per group level (``condition``).
    """

    group: str
    slopes: tuple[str, ...] = ()

    def lme4(self) -> str:
        """The term in lme4 syntax."""
        return "(" + " + ".join(("1", *self.slopes)) + f" | {self.group})"


@dataclass(frozen=True)
class ModelSpec:
    """A mixed model: response, fully crossed fixed factors, random terms.

    ``fixed = ("condition", "on_tactor")`` means ``condition * on_tactor`` (both main
    effects and their interaction).
    """

    response: str
    fixed: tuple[str, ...]
    random: tuple[RandomTerm, ...]
    #: ``"log"``: the model is of ``log(response)`` (written so in the formula).
    transform: str | None = None

    def formula(self) -> str:
        """The model in lme4 syntax."""
        rhs = " * ".join(self.fixed) if self.fixed else "1"
        lhs = f"{self.transform}({self.response})" if self.transform else self.response
        return f"{lhs} ~ " + " + ".join((rhs, *(t.lme4() for t in self.random)))

    def replace_term(self, drop: RandomTerm, keep: RandomTerm | None = None) -> ModelSpec:
        """The same model with ``drop`` replaced by ``keep`` (or removed)."""
        terms = (keep if t == drop else t for t in self.random)
        return replace(self, random=tuple(t for t in terms if t is not None))

    def response_values(self, df: pd.DataFrame) -> np.ndarray:
        y = df[self.response].to_numpy(dtype=float)
        return np.log(y) if self.transform == "log" else y


@dataclass
class FixedEffect:
    """One fixed-effect coefficient with its Wald statistics (log-odds for the GLMM)."""

    estimate: float
    se: float
    z: float
    p: float
    ci_low: float
    ci_high: float

    def to_dict(self) -> dict[str, float | None]:
        return {k: (v if math.isfinite(v) else None) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class FixefPrior:
    """A normal prior on the fixed effects, as ``blme::bglmer(fixef.prior = normal(sd =
    c(sd0, sd)))`` (with bglmer's default covariance prior, ``wishart(df = level.dim +
    2.5, scale = Inf)``, on every random-effects term).

    The fit maximises the Laplace log-likelihood plus the log prior: the deviance gains
    ``sum(beta_j^2 / sd_j^2)`` (plus the prior's constant ``p log(2 pi) + 2 sum log
    sd_j``) and, per random-effects term, ``-2 (df - q - 1) sum log diag(T)`` = ``-3 sum
    log diag(T)`` (blme's ``getPolynomialTerm`` of that Wishart; it keeps variances off
    0). The standard errors are glmer's, from the Hessian of that penalised deviance.

    Attributes:
        sd0: the intercept's prior SD.
        sd: the prior SD of every other fixed effect.
    """

    sd0: float = 10.0
    sd: float = 2.5
    #: ``"normal:SD"`` was given (one SD for every fixed effect)
    single: bool = False

    #: the Wishart's ``df - level.dim``: bglmer's default covariance prior
    COV_DF_EXTRA = 2.5

    @classmethod
    def parse(cls, text: str) -> FixefPrior:
        """``normal:SD`` (every fixed effect) or ``normal:SD0,SD`` (intercept, the rest).

        Raises:
            ValueError: anything else, or an SD that is not a positive finite number.
        """
        kind, sep, rest = text.strip().partition(":")
        if kind.strip().lower() != "normal" or not sep:
            raise ValueError(f"--fixef-prior {text!r}: expected normal:SD or normal:SD0,SD "
                             "(for example normal:2.5 or normal:10,2.5)")
        parts = [x.strip() for x in rest.split(",")]
        try:
            vals = [float(x) for x in parts]
        except ValueError:
            raise ValueError(f"--fixef-prior {text!r}: the SDs must be numbers") from None
        if len(vals) not in (1, 2) or not all(math.isfinite(v) and v > 0 for v in vals):
            raise ValueError(f"--fixef-prior {text!r}: one or two positive finite SDs "
                             "(normal:SD or normal:SD0,SD)")
        if len(vals) == 1:
            return cls(vals[0], vals[0], single=True)
        return cls(vals[0], vals[1])

    def sds(self, p: int) -> np.ndarray:
        """The prior SD of each of ``p`` fixed effects, as blme spreads ``sd``."""
        if self.single:
            return np.full(p, self.sd0)
        return np.r_[self.sd0, np.full(max(p - 1, 0), self.sd)][:p]

    def blme(self) -> str:
        """The prior as blme writes it in the call."""
        sd = (_r_number(self.sd0) if self.single
              else f"c({_r_number(self.sd0)}, {_r_number(self.sd)})")
        return f"normal(sd = {sd})"

    def call(self) -> str:
        """The bglmer call this fit equals."""
        return (f"blme::bglmer(..., family = binomial, fixef.prior = {self.blme()}, "
                "cov.prior = wishart(df = level.dim + 2.5, scale = Inf))")

    def to_json(self) -> dict[str, Any]:
        return {"prior": self.blme(), "sd_intercept": self.sd0,
                "sd": self.sd0 if self.single else self.sd,
                "cov_prior": "wishart(df = level.dim + 2.5, scale = Inf) (bglmer's default)",
                "call": self.call()}


@dataclass
class MixedModelFit:
    """A fitted mixed model, in the terms lme4 prints.

    Attributes:
        spec: the model fitted.
        family: ``binomial`` (logit link) or ``gaussian``.
        fixed_effects: keyed by lme4's term names (``(Intercept)``, ``conditionstatic``).
        vcov: the fixed effects' covariance matrix, in that order.
        random_effects: per term, the SDs by column (``(Intercept)``, ``conditionstatic``)
            and correlations; ``sigma`` for the residual of an LMM.
        theta: lme4's theta (relative Cholesky factors, column-wise lower triangles).
        singular: an element of theta bounded by 0 is below :data:`SINGULAR_TOL`.
        deviance, loglik: ``-2 log L`` (Laplace or REML criterion) and ``log L``.
        vcov_method: how ``vcov`` was computed.
        messages: convergence and rank notes.
        n_obs, n_cells: observations and pooled binomial cells.
        groups: number of levels per grouping column.
    """

    spec: ModelSpec
    family: str
    fixed_effects: dict[str, FixedEffect]
    vcov: np.ndarray
    random_effects: dict[str, dict[str, Any]]
    theta: np.ndarray
    singular: bool
    deviance: float
    loglik: float
    vcov_method: str
    converged: bool
    messages: list[str] = field(default_factory=list)
    theta_names: list[str] = field(default_factory=list)
    n_obs: int = 0
    n_cells: int = 0
    groups: dict[str, int] = field(default_factory=dict)
    criterion: str = "ML (Laplace)"
    #: per fixed effect, lmerTest's Satterthwaite ``df``, ``t``, ``p`` (an LMM fitted by
    #: R with lmerTest; None otherwise)
    satterthwaite: dict[str, dict[str, float]] | None = None
    #: the prior of a penalised fit (blme's bglmer), None for maximum likelihood
    fixef_prior: FixefPrior | None = None

    def zero_components(self) -> list[str]:
        """Names of theta elements bounded by 0 and estimated below :data:`SINGULAR_TOL`
        (``participant.conditionstatic``: a slope at 0 or a correlation of +-1)."""
        out = []
        for nm, th in zip(self.theta_names, self.theta, strict=False):
            parts = nm.split(".")
            diagonal = len(parts) == 2 or (len(parts) == 3 and parts[1] == parts[2])
            if diagonal and th < SINGULAR_TOL:
                out.append(nm)
        return out


# -- BLAS threads ------------------------------------------------------------------------

_CONTROLLER: list[Any] = []
P = ParamSpec("P")
R = TypeVar("R")


def one_blas_thread(f: Callable[P, R]) -> Callable[P, R]:
    """``f`` run with BLAS on one thread (threadpoolctl, when installed).

    The fits do thousands of small matrix operations; a threaded OpenBLAS makes its
    threads wait for each other on every one, which on a busy 2-core machine made a
    parametric bootstrap 3.6 times slower. Without threadpoolctl: no change.
    """

    @functools.wraps(f)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # pragma: no cover - threadpoolctl comes with SciPy's stack
            return f(*args, **kwargs)
        if not _CONTROLLER:
            _CONTROLLER.append(ThreadpoolController())
        with _CONTROLLER[0].limit(limits=1, user_api="blas"):
            return f(*args, **kwargs)

    return run


# -- design matrices ---------------------------------------------------------------------

_FACTOR_CALL = re.compile(r"^factor\((\w+)\)$")


def term_column(term: str) -> str:
    """The data column of a fixed-effect term: ``factor(n_targets)`` -> ``n_targets``."""
    m = _FACTOR_CALL.match(term)
    return m.group(1) if m else term


def _r_number(v: float) -> str:
    """A number as R's ``as.character`` writes it (``24``, ``0.5``), for level names."""
    f = float(v)
    return str(int(f)) if f.is_integer() and abs(f) < 1e15 else repr(f)


def term_levels(df: pd.DataFrame, term: str) -> list[Any] | None:
    """The levels of a factor term in R's order (None for a numeric column).

    A text column: its values sorted as text (R's ``factor``). ``factor(col)`` of a
    numeric column: its values sorted as numbers (``factor(n_targets)``: 12, 24, 36, 48).
    """
    col = term_column(term)
    s = df[col]
    if pd.api.types.is_bool_dtype(s) or not pd.api.types.is_numeric_dtype(s):
        return sorted(set(s.astype(str).tolist()))
    if term == col:
        return None
    return sorted({float(v) for v in s.dropna().to_numpy(dtype=float)})


def _factor_columns(df: pd.DataFrame, term: str,
                    levels: list[Any] | None = None) -> tuple[list[np.ndarray], list[str]]:
    """The contrast columns of one term, R's treatment coding (``levels``: the fitted
    data's, when ``df`` is a reference grid)."""
    col = term_column(term)
    s = df[col]
    if levels is None:
        levels = term_levels(df, term)
    if levels is None:
        return [s.to_numpy(dtype=float)], [term]
    numbers = bool(levels) and isinstance(levels[0], float)
    vals = s.to_numpy(dtype=float) if numbers else s.astype(str).to_numpy()
    return ([(vals == lv).astype(float) for lv in levels[1:]],
            [f"{term}{_r_number(lv) if numbers else lv}" for lv in levels[1:]])


def fixed_design(df: pd.DataFrame, fixed: Sequence[str], *,
                 levels: dict[str, list[Any] | None] | None = None,
                 check_rank: bool = True) -> tuple[np.ndarray, list[str], list[str]]:
    """``model.matrix(~ a * b * ...)`` with R's defaults.

    Args:
        df: the data (or a reference grid, with ``levels`` of the fitted data).
        fixed: the terms, fully crossed; ``factor(col)`` codes a numeric column as a
            factor, as R does.
        levels: per term, the levels to code (default: the data's own).
        check_rank: drop columns that are linear combinations of earlier ones.

    Returns:
        ``(X, names, dropped)``: the design (with ``(Intercept)`` first), its column
        names, and the names of columns dropped because they are linear combinations of
        earlier ones (lme4 drops them too).
    """
    n = len(df)
    cols: list[np.ndarray] = [np.ones(n)]
    names: list[str] = ["(Intercept)"]
    per = {c: _factor_columns(df, c, None if levels is None else levels.get(c))
           for c in fixed}
    for degree in range(1, len(fixed) + 1):
        for combo in itertools.combinations(fixed, degree):
            parts = [per[c] for c in combo]
            # R: the first factor's columns vary fastest
            for idx in itertools.product(*(range(len(p[0])) for p in reversed(parts))):
                idx = idx[::-1]
                col = np.ones(n)
                for p, i in zip(parts, idx, strict=True):
                    col = col * p[0][i]
                cols.append(col)
                names.append(":".join(p[1][i] for p, i in zip(parts, idx, strict=True)))
    x = np.column_stack(cols)
    if not check_rank:
        return x, names, []
    keep: list[int] = []
    dropped: list[str] = []
    xu = np.unique(x, axis=0)  # the same rank, far fewer rows
    for j in range(x.shape[1]):
        trial = [*keep, j]
        tol = 1e-7 * max(1.0, float(np.abs(xu).max(initial=0.0))) * max(xu.shape[0], 1)
        if np.linalg.matrix_rank(xu[:, trial], tol=tol) == len(trial):
            keep.append(j)
        else:
            dropped.append(names[j])
    return x[:, keep], [names[j] for j in keep], dropped


@dataclass
class _Term:
    name: str
    group: np.ndarray  # level index per row
    z: np.ndarray  # (N, b) columns of the term
    columns: list[str]
    n_levels: int

    @property
    def b(self) -> int:
        return self.z.shape[1]

    @property
    def n_theta(self) -> int:
        return self.b * (self.b + 1) // 2

    def theta_names(self) -> list[str]:
        """lme4's names of this term's theta elements (``group.col`` or ``group.row.col``)."""
        c = self.columns
        return [f"{self.name}.{c[i]}" if i == j else f"{self.name}.{c[i]}.{c[j]}"
                for j in range(self.b) for i in range(j, self.b)]

    def tri(self, th: np.ndarray) -> np.ndarray:
        t = np.zeros((self.b, self.b))
        j, i = np.triu_indices(self.b)  # the lower triangle, column by column
        t[i, j] = th
        return t


def _split(terms: list[_Term], theta: np.ndarray) -> list[np.ndarray]:
    """``theta`` cut into each term's elements."""
    return np.split(np.asarray(theta, dtype=float),
                    np.cumsum([t.n_theta for t in terms])[:-1])


def _lower(terms: list[_Term]) -> list[float]:
    return [0.0 if i == j else -np.inf for t in terms for j in range(t.b) for i in range(j, t.b)]


def _theta_names(terms: list[_Term]) -> list[str]:
    return [nm for t in terms for nm in t.theta_names()]


def _is_singular(theta: np.ndarray, lower: list[float]) -> bool:
    """lme4's ``isSingular``: an element of theta bounded by 0 below :data:`SINGULAR_TOL`."""
    return bool(any(th < SINGULAR_TOL for th, lb in zip(theta, lower, strict=True)
                    if lb == 0.0))


def _messages(dropped: list[str], vcov_notes: list[str], ok: bool, optimizer: str,
              singular: bool) -> list[str]:
    """lme4's messages on a fit: the columns :func:`fixed_design` dropped, how vcov fell
    back, the optimiser's message when it did not converge, a singular fit."""
    out = (["fixed-effect model matrix is rank deficient so dropping "
            f"{len(dropped)} column(s): " + ", ".join(dropped)] if dropped else [])
    out += vcov_notes + ([] if ok else [f"optimizer: {optimizer}"])
    return out + (["boundary (singular) fit: see help('isSingular')"] if singular else [])


def _random_terms(df: pd.DataFrame, spec: ModelSpec) -> list[_Term]:
    terms: list[_Term] = []
    for rt in spec.random:
        codes = np.unique(df[rt.group].astype(str).to_numpy(), return_inverse=True)[1].ravel()
        levels = int(codes.max()) + 1 if codes.size else 0
        zc: list[np.ndarray] = [np.ones(len(df))]
        zn = ["(Intercept)"]
        for s in rt.slopes:
            c, nm = _factor_columns(df, s)
            zc += c
            zn += nm
        terms.append(_Term(rt.group, codes.astype(np.int64), np.column_stack(zc), zn, levels))
    # lme4 orders terms by decreasing number of levels
    terms.sort(key=lambda t: -t.n_levels)
    return terms


# -- the penalised least-squares system, structured --------------------------------------

def _bsum(idx: np.ndarray, weights: np.ndarray, n: int) -> np.ndarray:
    """``bincount`` with weights, always float (also for empty input)."""
    out: np.ndarray = np.bincount(idx.ravel(), weights=weights.ravel(), minlength=n).astype(float)
    return out


def _block_inverse(a: np.ndarray) -> tuple[np.ndarray, float]:
    """Inverses and the summed ``log det`` of positive-definite blocks ``(m, b, b)``.

    Closed forms for 1x1 and 2x2 blocks (a random intercept, or intercept and one
    slope: the usual case, and much faster than a batched LAPACK call per block).
    """
    b = a.shape[1]
    if b == 1:
        return 1.0 / a, float(np.log(a[:, 0, 0]).sum())
    if b == 2:
        p, q, r = a[:, 0, 0], a[:, 0, 1], a[:, 1, 1]
        det = p * r - q * q
        if np.any(det <= 0):
            raise np.linalg.LinAlgError("a random-effects block is not positive definite")
        inv = np.empty_like(a)
        inv[:, 0, 0], inv[:, 1, 1] = r / det, p / det
        inv[:, 0, 1] = inv[:, 1, 0] = -q / det
        return inv, float(np.log(det).sum())
    chol = np.linalg.cholesky(a)
    logdet = 2.0 * float(np.log(np.diagonal(chol, axis1=1, axis2=2)).sum())
    return np.linalg.inv(a), logdet


@dataclass
class _Rows:
    """The dense part of ``[Z Lambda | X]``, stored by row: ``vals`` at columns ``cols``."""

    cols: np.ndarray  # (N, s) int
    vals: np.ndarray  # (N, s)
    r: int

    def dot(self, x: np.ndarray) -> np.ndarray:
        return (self.vals * x[self.cols]).sum(axis=1)

    def tdot(self, resid: np.ndarray) -> np.ndarray:
        return _bsum(self.cols, self.vals * resid[:, None], self.r)


class _System:
    """``A = Lambda' Z' W Z Lambda + P`` with the first term's levels as diagonal blocks.

    Unknowns: ``u_1`` (term 1, ``m1`` blocks of size ``b1``) and a dense part ``[u_2,
    ..., u_K, beta?]`` (``beta`` only for joint solves, unpenalised). Every sum over
    rows is a ``bincount`` over the few non-zeros of each row (no large matrix product).
    """

    def __init__(self, terms: list[_Term], x: np.ndarray | None) -> None:
        self.terms = terms
        self.x = x
        t1 = terms[0]
        self.g1 = t1.group
        self.m1, self.b1 = t1.n_levels, t1.b
        cols: list[np.ndarray] = []
        r = 0
        for t in terms[1:]:
            for j in range(t.b):
                cols.append(r + t.group * t.b + j)
            r += t.n_levels * t.b
        self.r_u = r
        self.p = 0 if x is None else x.shape[1]
        n = t1.group.size
        for j in range(self.p):
            cols.append(np.full(n, r + j))
        self.r = r + self.p
        self.cols = (np.column_stack(cols).astype(np.int64) if cols
                     else np.zeros((n, 0), dtype=np.int64))
        s = self.cols.shape[1]
        b1 = self.b1
        self.idx11 = ((self.g1[:, None, None] * b1 + np.arange(b1)[None, :, None]) * b1
                      + np.arange(b1)[None, None, :]).reshape(n, -1)
        self.idx12 = ((self.g1[:, None, None] * b1 + np.arange(b1)[None, :, None]) * self.r
                      + self.cols[:, None, :]).reshape(n, -1)
        # rows of the dense part repeat (targets x fixed-effect patterns): A22 sums the
        # weights per distinct row first
        key = np.column_stack([self.cols.astype(float)]
                              + [t.z for t in terms[1:]]
                              + ([x] if x is not None else []))
        _, first, pat = np.unique(key, axis=0, return_index=True, return_inverse=True)
        self.pat, self.pat_first = pat.ravel(), first
        pc = self.cols[first]
        self.idx22 = (pc[:, :, None] * self.r + pc[:, None, :]).reshape(first.size, -1)
        self.s = s

    def rows(self, thetas: list[np.ndarray]) -> tuple[np.ndarray, _Rows]:
        """``V1`` (N, b1) and the dense rows of ``[Z Lambda | X]``."""
        ts = [t.tri(th) for t, th in zip(self.terms, thetas, strict=True)]
        v1 = self.terms[0].z @ ts[0]
        vals = [t.z @ tk for t, tk in zip(self.terms[1:], ts[1:], strict=True)]
        if self.x is not None:
            vals.append(self.x)
        v = np.column_stack(vals) if vals else np.zeros((v1.shape[0], 0))
        return v1, _Rows(self.cols, v, self.r)

    def eta_random(self, v1: np.ndarray, d: _Rows, u1: np.ndarray,
                   ud: np.ndarray) -> np.ndarray:
        """``Z Lambda u`` (+ ``X beta`` when ``ud`` holds beta)."""
        return (v1 * u1[self.g1]).sum(axis=1) + d.dot(ud)

    def factor(self, v1: np.ndarray, d: _Rows, w: np.ndarray) -> dict[str, Any]:
        """Blocks of ``A`` and what solving and ``log det`` need."""
        m1, b1, r = self.m1, self.b1, self.r
        wv1 = v1 * w[:, None]
        a11 = _bsum(self.idx11, wv1[:, :, None] * v1[:, None, :], m1 * b1 * b1).reshape(
            m1, b1, b1)
        a11 = a11 + np.eye(b1)
        if r:
            a12 = _bsum(self.idx12, wv1[:, :, None] * d.vals[:, None, :], m1 * b1 * r).reshape(
                m1, b1, r)
            wp = np.bincount(self.pat, weights=w, minlength=self.pat_first.size)
            vp = d.vals[self.pat_first]
            a22 = _bsum(self.idx22, wp[:, None, None] * vp[:, :, None] * vp[:, None, :],
                        r * r).reshape(r, r)
            a22[np.arange(self.r_u), np.arange(self.r_u)] += 1.0
        else:
            a12 = np.zeros((m1, b1, 0))
            a22 = np.zeros((0, 0))
        inv11, logdet11 = _block_inverse(a11)
        inv_a12 = np.einsum("gij,gjr->gir", inv11, a12) if r else a12
        s = a22 - np.einsum("gbr,gbs->rs", a12, inv_a12) if r else a22
        return {"a11": a11, "inv11": inv11, "a12": a12, "inv_a12": inv_a12, "s": s,
                "logdet11": logdet11}

    def logdet_u(self, f: dict[str, Any]) -> float:
        """``log det(Lambda' Z' W Z Lambda + I)`` (the random effects only)."""
        ld = f["logdet11"]
        if self.r_u:
            suu = f["s"][: self.r_u, : self.r_u]
            ld += 2.0 * float(np.log(np.diag(np.linalg.cholesky(suu))).sum())
        return float(ld)

    def solve(self, f: dict[str, Any], r1: np.ndarray, r2: np.ndarray,
              strict: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``A^-1 [r1, r2]``; a singular dense part: least squares, or (``strict``)
        LinAlgError."""
        t1 = np.einsum("gij,gj->gi", f["inv11"], r1)
        if not self.r:
            return t1, r2
        rhs = r2 - np.einsum("gbr,gb->r", f["a12"], t1)
        x2 = np.linalg.solve(f["s"], rhs) if strict else _solve_or_lstsq(f["s"], rhs)
        x1 = t1 - np.einsum("gbr,r->gb", f["inv_a12"], x2)
        return x1, x2

    def beta_block(self, f: dict[str, Any]) -> np.ndarray:
        """``R_X' R_X``: the Schur complement of the random effects in the dense part."""
        s, r_u = f["s"], self.r_u
        sbb = s[r_u:, r_u:]
        if r_u:
            sbb = sbb - s[r_u:, :r_u] @ np.linalg.solve(s[:r_u, :r_u], s[:r_u, r_u:])
        return np.asarray(sbb)

    def scatter1(self, v1: np.ndarray, resid: np.ndarray) -> np.ndarray:
        b1 = self.b1
        idx = (self.g1[:, None] * b1 + np.arange(b1)[None, :]).ravel()
        return _bsum(idx, v1 * resid[:, None], self.m1 * b1).reshape(self.m1, b1)


def _solve_or_lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b``; where ``a`` is singular (a direction the data do not identify: the
    coefficient of a cell at 0 or 100 % once its weights reach the floor), the
    minimum-norm least-squares solution, which leaves that direction where it is."""
    try:
        out: np.ndarray = np.linalg.solve(a, b)
        return out
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.lstsq(a, b, rcond=None)[0])


def _inv_or_pinv(a: np.ndarray) -> np.ndarray:
    """``a^-1``, or the pseudo-inverse where ``a`` is singular."""
    try:
        out: np.ndarray = np.linalg.inv(a)
        return out
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.pinv(a))


# -- the binomial GLMM -------------------------------------------------------------------

def _weights(mu: np.ndarray, m: np.ndarray, floor: bool = False) -> np.ndarray:
    """The IRLS weights ``m mu (1 - mu)`` (``floor``: at least :data:`WEIGHT_FLOOR` per
    trial)."""
    w = m * mu * (1.0 - mu)
    return np.maximum(w, m * WEIGHT_FLOOR) if floor else w


def _binom_dev(eta: np.ndarray, y: np.ndarray, m: np.ndarray) -> float:
    """``-2 log L`` of binomial counts (without the binomial coefficients, which Bernoulli
    rows do not have): the sum of Bernoulli deviance residuals."""
    return 2.0 * float((y * np.logaddexp(0.0, -eta) + (m - y) * np.logaddexp(0.0, eta)).sum())


class _Laplace:
    """The Laplace deviance of a binomial GLMM as a function of (theta, beta)."""

    def __init__(self, terms: list[_Term], x: np.ndarray, y: np.ndarray, m: np.ndarray) -> None:
        self.terms, self.x, self.y, self.m = terms, x, y, m
        self.sys_u = _System(terms, None)
        self.sys_j = _System(terms, x)
        self.n_theta = sum(t.n_theta for t in terms)
        self.p = x.shape[1]
        self.u1 = np.zeros((self.sys_u.m1, self.sys_u.b1))
        self.u2 = np.zeros(self.sys_u.r_u)
        self.beta_joint = np.zeros(self.p)
        #: set once a fit's PIRLS met a singular system from u = 0 (separation): weights
        #: with a floor and least-squares steps from then on
        self.robust = False
        #: 1 / prior variance per fixed effect, None without a prior (FixefPrior)
        self.prior_prec: np.ndarray | None = None
        self.prior_const = 0.0
        #: per theta element: the covariance prior's weight on -log(theta) (diagonals)
        self.cov_weight = np.zeros(self.n_theta)

    def set_prior(self, prior: FixefPrior | None) -> None:
        """Penalise the deviance as bglmer does (None: maximum likelihood)."""
        if prior is None:
            self.prior_prec, self.prior_const = None, 0.0
            self.cov_weight = np.zeros(self.n_theta)
            return
        sds = prior.sds(self.p)
        self.prior_prec = 1.0 / sds**2
        self.prior_const = self.p * math.log(2.0 * math.pi) + 2.0 * float(np.log(sds).sum())
        lower = _lower(self.terms)
        w = 2.0 * (prior.COV_DF_EXTRA - 1.0)
        self.cov_weight = np.array([w if lb == 0.0 else 0.0 for lb in lower])

    def _cov_penalty(self, theta: np.ndarray) -> float:
        if not self.cov_weight.any():
            return 0.0
        on = self.cov_weight > 0
        th = theta[on]
        if np.any(th <= 0.0):
            return math.inf
        return -float((self.cov_weight[on] * np.log(th)).sum())

    def penalty(self, par: np.ndarray) -> float:
        """The prior's part of the penalised deviance at ``(theta, beta)`` (0 without)."""
        if self.prior_prec is None:
            return 0.0
        beta = par[self.n_theta:]
        return (float((self.prior_prec * beta**2).sum()) + self._cov_penalty(par[: self.n_theta])
                + self.prior_const)

    def penalty_grad(self, par: np.ndarray) -> np.ndarray:
        g = np.zeros(par.size)
        if self.prior_prec is None:
            return g
        th = par[: self.n_theta]
        on = self.cov_weight > 0
        with np.errstate(divide="ignore"):
            g[: self.n_theta][on] = -self.cov_weight[on] / th[on]
        g[self.n_theta:] = 2.0 * self.prior_prec * par[self.n_theta:]
        return g

    def _pirls(self, theta: np.ndarray, beta: np.ndarray | None,
               tol: float = 1e-11) -> tuple[float, dict[str, Any]]:
        """Penalised IRLS; ``beta=None``: beta jointly with u (glmer's nAGQ = 0).

        Starts from the previous call's modes; where that start diverges (a singular
        system, a non-finite deviance: the optimiser's previous trial point was far
        off), starts again from u = 0 (and beta = 0), as glmer does for a fresh fit.
        """
        if self.robust:
            out = self._pirls_from(theta, beta, tol, warm=True, robust=True)
            if math.isfinite(out[0]):
                return out
            return self._pirls_from(theta, beta, tol, warm=False, robust=True)
        try:
            out = self._pirls_from(theta, beta, tol, warm=True)
            if math.isfinite(out[0]):
                return out
        except np.linalg.LinAlgError:
            pass
        try:
            return self._pirls_from(theta, beta, tol, warm=False)
        except np.linalg.LinAlgError:
            # a cell at 0 or 100 %: its weights reach 0 and the system is singular even
            # from u = 0; from here on (this fit) weights keep a floor and a singular
            # step is solved by least squares (docs/analysis.md, "Separation")
            self.robust = True
            return self._pirls_from(theta, beta, tol, warm=False, robust=True)

    def _pirls_from(self, theta: np.ndarray, beta: np.ndarray | None, tol: float,
                    warm: bool, robust: bool = False) -> tuple[float, dict[str, Any]]:
        joint = beta is None
        sysm = self.sys_j if joint else self.sys_u
        v1, d = sysm.rows(_split(self.terms, theta))
        if warm:
            u1 = self.u1.copy()
            ud = np.r_[self.u2, self.beta_joint] if joint else self.u2.copy()
        else:
            u1 = np.zeros_like(self.u1)
            ud = np.zeros(sysm.r_u + (self.p if joint else 0))
        off = 0.0 if joint else self.x @ beta
        y, m = self.y, self.m
        r_u = sysm.r_u

        def objective(u1: np.ndarray, ud: np.ndarray) -> tuple[float, np.ndarray]:
            eta = off + sysm.eta_random(v1, d, u1, ud)
            return _binom_dev(eta, y, m) + float((u1 * u1).sum() + (ud[:r_u] ** 2).sum()), eta

        pen, eta = objective(u1, ud)
        for _ in range(200):
            mu = expit(eta)
            w = _weights(mu, m, robust)
            f = sysm.factor(v1, d, w)
            resid = y - m * mu
            g1 = sysm.scatter1(v1, resid) - u1
            g2 = d.tdot(resid)
            g2[:r_u] -= ud[:r_u]
            x1, x2 = sysm.solve(f, g1, g2, strict=not robust)
            step = 1.0
            for _ in range(30):
                new_pen, new_eta = objective(u1 + step * x1, ud + step * x2)
                if new_pen <= pen + 1e-12 * abs(pen):
                    break
                step /= 2.0
            u1, ud = u1 + step * x1, ud + step * x2
            change = pen - new_pen
            pen, eta = new_pen, new_eta
            if change < tol * (1.0 + abs(pen)) and max(
                    float(np.abs(step * x1).max(initial=0.0)),
                    float(np.abs(step * x2).max(initial=0.0))) < 1e-7:
                break
        mu = expit(eta)
        w = _weights(mu, m, robust)
        f = sysm.factor(v1, d, w)
        ld = sysm.logdet_u(f)
        self.u1, self.u2 = u1, ud[:r_u]
        if joint:
            self.beta_joint = ud[r_u:]
        return pen + ld, {"eta": eta, "factor": f, "system": sysm, "u1": u1, "ud": ud,
                          "v1": v1, "d": d, "w": w, "mu": mu}

    def beta_gradient(self, st: dict[str, Any]) -> np.ndarray:
        """The gradient of the Laplace deviance over beta (theta fixed), analytically.

        ``D(beta) = dev(eta*) + |u*|^2 + log det A`` with ``A = Lambda'Z'WZ Lambda + I``
        at the conditional modes ``u*(beta)``. The first two terms: by the envelope
        theorem ``-2 X'(y - m mu)``. The log det: ``sum_i h_i w'_i deta_i/dbeta`` with
        ``h_i = V_i A^-1 V_i'`` (``V = Z Lambda``), ``w' = dW/deta = m mu (1 - mu)
        (1 - 2 mu)`` and ``deta/dbeta = X - V A^-1 V'WX`` (the modes move with beta).
        """
        sysm, f, v1, d = st["system"], st["factor"], st["v1"], st["d"]
        mu, w = st["mu"], st["w"]
        x = self.x
        g_dev = -2.0 * (x.T @ (self.y - self.m * mu))
        h = self._leverage(st)["h"]
        # deta/dbeta = X - V A^-1 V' W X, one solve per column of X
        wx = w[:, None] * x
        dx = x.copy()
        for j in range(x.shape[1]):
            t1, t2 = sysm.solve(f, sysm.scatter1(v1, wx[:, j]), d.tdot(wx[:, j]))
            dx[:, j] -= sysm.eta_random(v1, d, t1, t2)
        wprime = w * (1.0 - 2.0 * mu)
        return np.asarray(g_dev + dx.T @ (h * wprime))

    @staticmethod
    def _leverage(st: dict[str, Any]) -> dict[str, Any]:
        """``h_i = V_i A^-1 V_i'`` and the pieces of ``A^-1`` per row (cached in ``st``)."""
        if "leverage" in st:
            return dict(st["leverage"])
        sysm, f, v1, d = st["system"], st["factor"], st["v1"], st["d"]
        g1 = sysm.g1
        inv11 = f["inv11"][g1]  # (N, b1, b1)
        h = (np.matmul(inv11, v1[:, :, None])[:, :, 0] * v1).sum(axis=1)
        pg = qs = None
        if sysm.r:
            pg = f["inv_a12"][g1]  # (N, b1, r): P_g = A11^-1 A12
            q = np.matmul(v1[:, None, :], pg)[:, 0, :]
            np.subtract.at(q, (np.arange(g1.size)[:, None], d.cols), d.vals)
            qs = q @ _inv_or_pinv(f["s"])  # (N, r): S^-1 q_i
            h = h + (q * qs).sum(axis=1)
        st["leverage"] = {"h": h, "inv11": inv11, "pg": pg, "qs": qs}
        return dict(st["leverage"])

    def theta_gradient(self, st: dict[str, Any]) -> np.ndarray:
        """The gradient of the Laplace deviance over theta (beta fixed), analytically.

        With ``V = Z Lambda``, ``V_k = Z dLambda/dtheta_k`` (``theta_k`` is element
        ``(i, j)`` of a term's ``T``: row r of ``V_k`` holds ``z_r[i]`` at the column
        of its level and ``j``), ``r = y - m mu``, ``s_k = V_k u*``::

            dD/dtheta_k = -2 r's_k + 2 sum_i w_i (V_k A^-1 V')_ii
                          + sum_i h_i w'_i deta_i/dtheta_k
            deta/dtheta_k = s_k + V A^-1 (V_k' r - V' W s_k)

        (the modes move with theta: implicit differentiation of ``V'r = u``).
        Bilinear forms in ``A^-1`` use its block structure: for rows with term-1
        parts ``x1, y1`` (level g) and dense parts ``x2, y2``,
        ``x'A^-1 y = x1' A11^-1 y1 + (P_g'x1 - x2)' S^-1 (P_g'y1 - y2)``.
        """
        sysm, f, v1, d = st["system"], st["factor"], st["v1"], st["d"]
        mu, w = st["mu"], st["w"]
        u1, ud = st["u1"], st["ud"]
        resid = self.y - self.m * mu
        g1 = sysm.g1
        rows = np.arange(g1.size)
        lev = self._leverage(st)
        h, inv11, pg, qs = lev["h"], lev["inv11"], lev["pg"], lev["qs"]
        r = sysm.r
        wprime = w * (1.0 - 2.0 * mu)
        grad = np.zeros(self.n_theta)
        k = 0
        dense_col = 0
        for ti, t in enumerate(self.terms):
            first = ti == 0
            for j in range(t.b):
                for i in range(j, t.b):
                    zi = t.z[:, i]
                    if first:
                        s_k = zi * u1[g1, j]
                        # a1 = zi e_j (term-1 block), a2 = 0
                        bil = zi * (inv11[:, j, :] * v1).sum(axis=1)
                        if r:
                            bil = bil + zi * (pg[:, j, :] * qs).sum(axis=1)
                        rhs1 = np.zeros((sysm.m1, sysm.b1))
                        np.add.at(rhs1[:, j], g1, zi * resid)
                        rhs2 = np.zeros(r)
                    else:
                        col = d.cols[:, dense_col + j]
                        s_k = zi * ud[col]
                        bil = -zi * qs[rows, col]  # a1 = 0, a2 = zi at col
                        rhs1 = np.zeros((sysm.m1, sysm.b1))
                        rhs2 = _bsum(col, zi * resid, r)
                    ws = w * s_k
                    rhs1 = rhs1 - sysm.scatter1(v1, ws)
                    rhs2 = rhs2 - d.tdot(ws)
                    du1, du2 = sysm.solve(f, rhs1, rhs2)
                    deta = s_k + sysm.eta_random(v1, d, du1, du2)
                    grad[k] = (-2.0 * float(resid @ s_k) + 2.0 * float(w @ bil)
                               + float((h * wprime) @ deta))
                    k += 1
            if not first:
                dense_col += t.b
        return grad

    def dev_and_grad(self, par: np.ndarray, lower: np.ndarray) -> tuple[float, np.ndarray]:
        """The deviance and its gradient over (theta, beta), both analytic
        (:meth:`theta_gradient`, :meth:`beta_gradient`)."""
        th, beta = par[: self.n_theta], par[self.n_theta:]
        dev, st = self._pirls(th, beta)
        grad = np.r_[self.theta_gradient(st), self.beta_gradient(st)]
        return dev + self.penalty(par), grad + self.penalty_grad(par)  # 0 without a prior

    def dev_theta(self, theta: np.ndarray) -> float:
        """Stage 1's criterion (beta at the joint mode); with a prior, bglmer's stage 1
        adds the covariance prior and the fixed-effect prior at beta = 0 (a constant)."""
        return self._pirls(theta, None)[0] + (self._cov_penalty(theta) + self.prior_const)

    def dev(self, par: np.ndarray) -> float:
        """The Laplace deviance at ``(theta, beta)``, penalised by the prior if any."""
        return self.likelihood_dev(par) + self.penalty(par)

    def likelihood_dev(self, par: np.ndarray) -> float:
        """``-2 log L`` (Laplace) at ``(theta, beta)``, without the prior."""
        return self._pirls(par[: self.n_theta], par[self.n_theta:])[0]

    def rx(self, par: np.ndarray) -> np.ndarray:
        """``R_X' R_X`` at ``(theta, beta)``: half the Hessian of the deviance over beta
        when the modes are held (the conditional information)."""
        _, st = self._pirls(par[: self.n_theta], par[self.n_theta:])
        mu = expit(st["eta"])
        w = _weights(mu, self.m, self.robust)
        v1, d = self.sys_j.rows(_split(self.terms, par[: self.n_theta]))
        f = self.sys_j.factor(v1, d, w)
        sbb = self.sys_j.beta_block(f)
        if self.prior_prec is not None:
            sbb = sbb + np.diag(self.prior_prec)
        return np.asarray(sbb)


def _central_grad(f: Any, x: np.ndarray, lower: np.ndarray, h: float = 1e-5,
                  central: bool = True) -> np.ndarray:
    g = np.zeros_like(x)
    f0 = None if central else f(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        if f0 is not None:
            g[i] = (f(x + e) - f0) / h
        elif x[i] - h < lower[i]:  # one-sided at a bound
            g[i] = (f(x + e) - f(x)) / h
        else:
            g[i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


def deriv12(f: Any, x: np.ndarray, delta: float = HESSIAN_STEP) -> np.ndarray:
    """Finite-difference Hessian as lme4's ``deriv12`` computes it (central, step delta)."""
    k = x.size
    f0 = f(x)
    h = np.zeros((k, k))
    e = np.eye(k) * delta
    for i in range(k):
        h[i, i] = (f(x + e[i]) + f(x - e[i]) - 2.0 * f0) / delta**2
    for i in range(k):
        for j in range(i):
            h[i, j] = h[j, i] = (f(x + e[i] + e[j]) - f(x + e[i] - e[j]) - f(x - e[i] + e[j])
                                 + f(x - e[i] - e[j])) / (4.0 * delta**2)
    return h


def _differences(f: Any, central: bool = True) -> Any:
    """``fg`` for :func:`_minimize` from ``f`` alone: central-difference gradients
    (one-sided at a bound; forward differences throughout with ``central=False``, for
    starting values)."""
    return lambda x, lo: (f(x), _central_grad(f, x, lo, central=central))


def _minimize(fg: Any, x0: np.ndarray, lower: Sequence[float], *, ftol: float = 1e-12,
              gtol: float = 1e-6, maxiter: int = 500) -> tuple[np.ndarray, bool, str]:
    """L-BFGS-B with ``fg(x, lower) -> (f, gradient)`` (``lower`` as an array)."""
    lo = np.array([(-np.inf if not math.isfinite(b) else b) for b in lower])
    bounds = [(None if not math.isfinite(b) else b, None) for b in lower]
    x0 = np.maximum(x0, np.where(np.isfinite(lo), lo, -np.inf))
    res = minimize(lambda x: fg(x, lo), x0, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol})
    msg = str(res.message)
    ok = bool(res.success) or "ABNORMAL" in msg.upper()
    return np.asarray(res.x, dtype=float), ok, msg


def _escape_boundary(lap: _Laplace, par: np.ndarray, dev: float, lower: list[float],
                     ok: bool, msg: str) -> tuple[np.ndarray, float, bool, str]:
    """Leave a variance component at 0 only where 0 is a minimum along it.

    The deviance is even in a diagonal element of theta at 0, so its gradient there is
    0 whether 0 is a minimum or a maximum along it; a gradient method started at 0 (a
    simplified model started from a singular fit) stays there. Where a positive value
    of such an element lowers the deviance, stage 2 is run again from it (lme4's
    derivative-free optimisers probe such steps by themselves).
    """
    for _ in range(4):
        zero = [i for i, lb in enumerate(lower) if lb == 0.0 and par[i] < SINGULAR_TOL]
        best = None
        for i in zero:
            for delta in (0.05, 0.2, 0.5, 1.0):
                trial = par.copy()
                trial[i] = delta
                d = lap.dev(trial)
                if d < dev - 1e-6 and (best is None or d < best[0]):
                    best = (d, trial)
        lap.dev(par)  # the modes back at the optimum
        if best is None:
            break
        new, ok_new, msg_new = _stage2(lap, best[1], lower)
        d_new = lap.dev(new)
        if d_new >= dev:
            lap.dev(par)
            break
        par, dev, ok, msg = new, d_new, ok_new, msg_new
    return par, dev, ok, msg


def _stage2(lap: _Laplace, par0: np.ndarray, lower: list[float]) -> tuple[np.ndarray, bool, str]:
    """Minimise the Laplace deviance over (theta, beta) from ``par0``.

    beta is preconditioned: optimised as ``gamma = C'(beta - beta0)`` with ``C C'`` the
    conditional information ``2 R_X' R_X`` at the start, so the optimiser sees a
    Hessian near the identity (the design's dummy columns are strongly correlated
    otherwise, and L-BFGS-B crawls).
    """
    k = lap.n_theta
    beta0 = par0[k:].copy()
    try:
        c = np.linalg.cholesky(2.0 * lap.rx(par0))
    except np.linalg.LinAlgError:
        c = np.eye(lap.p)

    def to_par(z: np.ndarray) -> np.ndarray:
        return np.r_[z[:k], beta0 + np.linalg.solve(c.T, z[k:])]

    def fg(z: np.ndarray, lo: np.ndarray) -> tuple[float, np.ndarray]:
        f, g = lap.dev_and_grad(to_par(z), lo)
        return f, np.r_[g[:k], np.linalg.solve(c, g[k:])]

    z, ok, msg = _minimize(fg, np.r_[par0[:k], np.zeros(lap.p)], lower + [-np.inf] * lap.p,
                           gtol=1e-5, maxiter=1000)
    return to_par(z), ok, msg


def _pool(x: np.ndarray, terms: list[_Term], y: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[_Term], np.ndarray]:
    """Pool rows with equal covariates and groups: ``(x, sum of y, count, terms, cell of
    each row)``."""
    key = np.column_stack([x] + [np.c_[t.group, t.z] for t in terms])
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    n_cells = uniq.shape[0]
    ys = np.bincount(inv, weights=y, minlength=n_cells)
    ms = np.bincount(inv, minlength=n_cells).astype(float)
    first = np.zeros(n_cells, dtype=np.int64)
    first[inv[::-1]] = np.arange(len(inv))[::-1]
    pooled = [_Term(t.name, t.group[first], t.z[first], t.columns, t.n_levels) for t in terms]
    return x[first], ys, ms, pooled, inv


def _fixed_table(names: list[str], beta: np.ndarray, vcov: np.ndarray) -> dict[str, FixedEffect]:
    out: dict[str, FixedEffect] = {}
    se = np.sqrt(np.maximum(np.diag(vcov), 0.0))
    for nm, b, s in zip(names, beta, se, strict=True):
        z = b / s if s > 0 else math.nan
        p = float(2.0 * norm.sf(abs(z))) if math.isfinite(z) else math.nan
        out[nm] = FixedEffect(float(b), float(s), float(z), p, float(b - Z95 * s),
                              float(b + Z95 * s))
    return out


def _random_table(terms: list[_Term], thetas: list[np.ndarray],
                  scale: float = 1.0) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for t, th in zip(terms, thetas, strict=True):
        tm = t.tri(th) * scale
        cov = tm @ tm.T
        sd = np.sqrt(np.diag(cov))
        entry: dict[str, Any] = {"sd": {c: float(s) for c, s in zip(t.columns, sd, strict=True)},
                                 "levels": t.n_levels}
        if t.b > 1:
            with np.errstate(invalid="ignore", divide="ignore"):
                corr = cov / np.outer(sd, sd)
            entry["corr"] = {f"{t.columns[j]},{t.columns[i]}": (float(corr[i, j]) if
                                                              np.isfinite(corr[i, j]) else None)
                             for j in range(t.b) for i in range(j + 1, t.b)}
        out[t.name] = entry
    return out


def _check(df: pd.DataFrame, spec: ModelSpec) -> None:
    missing = [c for c in (spec.response, *(term_column(f) for f in spec.fixed),
                           *(t.group for t in spec.random),
                           *(s for t in spec.random for s in t.slopes)) if c not in df]
    if missing:
        raise ValueError("the data lack column(s) " + ", ".join(missing))
    if not spec.random:
        raise ValueError("a mixed model needs at least one random-effects term")
    for t in spec.random:
        if df[t.group].nunique() < 2:
            raise ValueError(f"grouping factor {t.group} needs at least 2 levels")


def _hessian_vcov(lap: _Laplace, par: np.ndarray) -> np.ndarray | None:
    """glmer's default vcov: ``2 solve(H)[beta, beta]`` (None unless positive definite)."""
    hess = deriv12(lap.dev, par)
    lap.dev(par)  # leave the modes at the optimum
    try:
        hinv = np.linalg.inv(hess)
    except np.linalg.LinAlgError:
        return None
    hb = hinv[lap.n_theta:, lap.n_theta:]
    hb = hb + hb.T
    if np.all(np.isfinite(hb)) and np.all(np.linalg.eigvalsh(hb) > 0):
        return np.asarray(hb)
    return None


def _start(previous: MixedModelFit | None, theta_names: list[str],
           beta_names: list[str] | None = None) -> np.ndarray | None:
    """Starting values from a fit of a larger model on the same data, when it has them all."""
    if previous is None:
        return None
    th = dict(zip(previous.theta_names, previous.theta, strict=False))
    if not all(nm in th for nm in theta_names):
        return None
    out = [th[nm] for nm in theta_names]
    if beta_names is not None:
        if list(previous.fixed_effects) != beta_names:
            return None
        out += [previous.fixed_effects[nm].estimate for nm in beta_names]
    return np.asarray(out, dtype=float)


class GlmmData:
    """A binomial GLMM's data, prepared once: design, random terms, pooled cells.

    Refits with other responses (the parametric bootstrap) reuse the design and the
    pooling (which depend on covariates and groups only) and the structured system.
    """

    def __init__(self, df: pd.DataFrame, spec: ModelSpec) -> None:
        _check(df, spec)
        self.spec = spec
        self.y = spec.response_values(df)
        self.x, self.names, self.dropped = fixed_design(df, spec.fixed)
        self.terms = _random_terms(df, spec)
        self.xc, self.ys, self.ms, self.pterms, self.inv = _pool(self.x, self.terms, self.y)
        self.n_obs = len(df)
        self._lap: _Laplace | None = None

    @property
    def theta_names(self) -> list[str]:
        return _theta_names(self.pterms)

    def pooled(self, y: np.ndarray) -> np.ndarray:
        """Per-row responses summed per pooled cell."""
        out: np.ndarray = np.bincount(self.inv, weights=y, minlength=self.ms.size)
        return out

    def laplace(self, ys: np.ndarray | None = None) -> _Laplace:
        """The Laplace deviance for pooled successes ``ys`` (default: the data's)."""
        if self._lap is None:
            self._lap = _Laplace(self.pterms, self.xc, self.ys, self.ms)
        lap = self._lap
        lap.y = self.ys if ys is None else ys
        lap.u1 = np.zeros_like(lap.u1)
        lap.u2 = np.zeros_like(lap.u2)
        lap.beta_joint = np.zeros(lap.p)
        lap.robust = False
        lap.set_prior(None)
        return lap

    def linear_predictor(self, fit: MixedModelFit, rng: np.random.Generator,
                         n_sim: int) -> np.ndarray:
        """``(n_sim, N)`` linear predictors with new random effects drawn from ``fit``
        (``b = Lambda(theta) u``, ``u ~ N(0, I)``; lme4's ``simulate(use.u = FALSE)``)."""
        beta = np.array([fit.fixed_effects[nm].estimate for nm in self.names])
        th = dict(zip(fit.theta_names, fit.theta, strict=True))
        fixed = self.x @ beta
        eta = np.repeat(fixed[None, :], n_sim, axis=0)
        for t in self.terms:
            tm = t.tri(np.array([th[nm] for nm in t.theta_names()]))
            u = rng.standard_normal((n_sim, t.n_levels, t.b))
            b = u @ tm.T  # (n_sim, levels, b)
            eta += np.einsum("snb,nb->sn", b[:, t.group, :], t.z)
        return eta

    def simulate(self, fit: MixedModelFit, rng: np.random.Generator, n_sim: int) -> np.ndarray:
        """``(n_sim, N)`` 0/1 responses simulated from ``fit`` (a fit of this model)."""
        eta = self.linear_predictor(fit, rng, n_sim)
        return (rng.random(eta.shape) < expit(eta)).astype(float)


@one_blas_thread
def fit_glmm(df: pd.DataFrame, spec: ModelSpec, *, skip_se_if_simplified: bool = False,
             start: MixedModelFit | None = None, se: bool = True,
             keep_slopes: bool = False, fixef_prior: FixefPrior | None = None) -> MixedModelFit:
    """A binomial (logit) GLMM by maximum likelihood, Laplace approximation (glmer's nAGQ=1).

    Args:
        df: one row per Bernoulli trial; ``spec.response`` is 0/1 (or bool).
        spec: fixed factors (fully crossed) and random terms.
        skip_se_if_simplified: leave out the Hessian (NaN SEs) when the fit is singular
            and :func:`simplify_step` (with ``keep_slopes``) would replace it.
        start: a fit of a model with these and more random effects on the same data (the
            previous step of :func:`fit_simplified`): stage 2 starts from its estimates
            instead of running stage 1 (the dropped components were at 0).
        se: compute the standard errors (False: NaN, for refits that need the deviance
            only).
        fixef_prior: fit with this prior, as ``blme::bglmer`` (:class:`FixefPrior`).

    Raises:
        ValueError: a missing column, fewer than 2 levels of a grouping factor.
    """
    data = GlmmData(df, spec)
    par0 = _start(start, data.theta_names, data.names)
    return glmm_fit(data, skip_se_if_simplified=skip_se_if_simplified, start_par=par0, se=se,
                    keep_slopes=keep_slopes, fixef_prior=fixef_prior)


def glmm_fit(data: GlmmData, y: np.ndarray | None = None, *,
             skip_se_if_simplified: bool = False, start_par: np.ndarray | None = None,
             se: bool = True, keep_slopes: bool = False,
             fixef_prior: FixefPrior | None = None) -> MixedModelFit:
    """:func:`fit_glmm` on prepared data, optionally with another per-row response ``y``
    (a refit, as lme4's ``refit(m, newresp = y)``) and a starting ``(theta, beta)``."""
    spec = data.spec
    lap = data.laplace(None if y is None else data.pooled(np.asarray(y, dtype=float)))
    lap.set_prior(fixef_prior)
    names, pterms = data.names, data.pterms
    lower = _lower(lap.terms)
    # the covariance prior is infinite at a variance of 0: its optimiser stays inside
    opt_lower = (lower if fixef_prior is None
                 else [PRIOR_THETA_FLOOR if b == 0.0 else b for b in lower])
    par0 = start_par
    ok1 = True
    if par0 is None:
        theta0 = np.array([1.0 if b == 0.0 else 0.0 for b in lower])
        # stage 1 (nAGQ = 0): theta only, beta at the joint penalised mode
        theta1, ok1, _ = _minimize(_differences(lap.dev_theta, central=False), theta0,
                                   opt_lower, ftol=1e-8, gtol=1e-2)
        lap.dev_theta(theta1)
        par0 = np.r_[theta1, lap.beta_joint]
    # stage 2 (nAGQ = 1): the Laplace deviance over (theta, beta)
    par, ok2, msg2 = _stage2(lap, par0, opt_lower)
    dev = lap.dev(par)
    if fixef_prior is None:
        par, dev, ok2, msg2 = _escape_boundary(lap, par, dev, lower, ok2, msg2)
    theta, beta = par[: lap.n_theta], par[lap.n_theta:]
    theta_names = data.theta_names
    singular = _is_singular(theta, lower)
    zero = [nm for nm, th, lb in zip(theta_names, theta, lower, strict=True)
            if lb == 0.0 and th < SINGULAR_TOL]
    vcov_method = ("2 x inverse of the finite-difference Hessian of the Laplace deviance over "
                   "(theta, beta), as glmer's default vcov")
    if fixef_prior is not None:
        vcov_method = ("2 x inverse of the finite-difference Hessian of the penalised "
                       "deviance over (theta, beta), as bglmer's vcov")
    vcov: np.ndarray | None
    vcov_notes: list[str] = []
    if not se:
        vcov = np.full((lap.p, lap.p), np.nan)
        vcov_method = "not computed (a refit: only the deviance is needed)"
    elif (singular and skip_se_if_simplified
          and simplify_step(spec, zero, keep_slopes)[0] is not None):
        vcov = np.full((lap.p, lap.p), np.nan)
        vcov_method = "not computed: a singular fit the simplification rule replaces"
    else:
        vcov = _hessian_vcov(lap, par)
        if vcov is None:
            vcov = _inv_or_pinv(lap.rx(par))  # the conditional covariance of beta given theta
            vcov_method = "(R_X' R_X)^-1 given theta (the Hessian was not positive definite)"
            vcov_notes = ["variance-covariance matrix computed from finite-difference Hessian "
                          "is not positive definite: falling back to var-cov estimated from RX"]
    return MixedModelFit(
        spec=spec, family="binomial", fixed_effects=_fixed_table(names, beta, vcov),
        vcov=vcov, random_effects=_random_table(pterms, _split(pterms, theta)), theta=theta,
        singular=singular, deviance=dev,
        loglik=-(dev if fixef_prior is None else lap.likelihood_dev(par)) / 2.0,
        vcov_method=vcov_method,
        converged=ok1 and ok2, messages=_messages(data.dropped, vcov_notes, ok2, msg2, singular),
        n_obs=data.n_obs, n_cells=int(lap.y.size),
        theta_names=theta_names,
        groups={t.name: t.n_levels for t in data.terms},
        criterion="ML (Laplace)" if fixef_prior is None else "penalised ML (Laplace), bglmer",
        fixef_prior=fixef_prior,
    )


# -- the linear mixed model (REML) --------------------------------------------------------

class LmmData:
    """A linear mixed model's data, pooled (counts, sums and sums of squares per cell
    of equal covariates and groups), and its profiled criterion as a function of theta.
    """

    def __init__(self, df: pd.DataFrame, spec: ModelSpec) -> None:
        _check(df, spec)
        self.spec = spec
        y_obs = spec.response_values(df)
        x_obs, self.names, self.dropped = fixed_design(df, spec.fixed)
        self.n, self.p = x_obs.shape
        x, self.ysum, self.w, self.terms, inv = _pool(x_obs, _random_terms(df, spec), y_obs)
        self.y2sum = np.bincount(inv, weights=y_obs**2, minlength=self.w.size)
        self.sysm = _System(self.terms, x)
        self.lower = _lower(self.terms)
        self.theta_names = _theta_names(self.terms)

    def state(self, theta: np.ndarray) -> dict[str, Any]:
        """At ``theta``: the profiled REML criterion ``crit``, ``log det(L L')``
        (``ldl2``), ``log det(R_X' R_X)`` (``ldx``), the penalised weighted RSS
        (``pwrss``), ``beta`` and ``R_X' R_X`` (``sbb``)."""
        sysm, w, ysum, n, p = self.sysm, self.w, self.ysum, self.n, self.p
        v1, d = sysm.rows(_split(self.terms, theta))
        f = sysm.factor(v1, d, w)
        r1 = sysm.scatter1(v1, ysum)
        r2 = d.tdot(ysum)
        x1, x2 = sysm.solve(f, r1, r2)
        fitted = sysm.eta_random(v1, d, x1, x2)
        rss = float((self.y2sum - 2.0 * fitted * ysum + w * fitted**2).sum())
        pwrss = rss + float((x1**2).sum() + (x2[: sysm.r_u] ** 2).sum())
        ld = sysm.logdet_u(f)
        sbb = sysm.beta_block(f)
        ldx = 2.0 * float(np.log(np.diag(np.linalg.cholesky(sbb))).sum())
        dof = n - p
        crit = ld + ldx + dof * (1.0 + math.log(2.0 * math.pi * pwrss / dof))
        return {"crit": crit, "ldl2": ld, "ldx": ldx, "pwrss": pwrss, "beta": x2[sysm.r_u:],
                "sbb": sbb}


@one_blas_thread
def fit_lmm(df: pd.DataFrame, spec: ModelSpec, *,
            start: MixedModelFit | None = None) -> MixedModelFit:
    """A linear mixed model by REML, as ``lme4::lmer``.

    The profiled criterion of Bates et al. (2015, eq. 34/41) is minimised over theta
    (L-BFGS-B, diagonal of theta >= 0); ``vcov = sigma^2 (R_X' R_X)^{-1}`` as lmer's.
    z and p are Wald (normal) values; :func:`tactorbelt.analysis.models.satterthwaite.satterthwaite`
    gives lmerTest's t tests.
    """
    data = LmmData(df, spec)
    n, p, lower = data.n, data.p, data.lower
    theta0 = _start(start, data.theta_names)
    if theta0 is None:
        theta0 = np.array([1.0 if b == 0.0 else 0.0 for b in lower])
    theta, ok, msg = _minimize(_differences(lambda t: data.state(t)["crit"]), theta0,
                               lower)
    st = data.state(theta)
    crit = st["crit"]
    sigma2 = st["pwrss"] / (n - p)
    vcov = sigma2 * np.linalg.inv(st["sbb"])
    singular = _is_singular(theta, lower)
    sigma = math.sqrt(sigma2)
    re = _random_table(data.terms, _split(data.terms, theta), scale=sigma)
    re["Residual"] = {"sd": {"(Intercept)": sigma}}
    return MixedModelFit(
        spec=spec, family="gaussian", fixed_effects=_fixed_table(data.names, st["beta"], vcov),
        vcov=vcov, random_effects=re, theta=theta, singular=singular, deviance=crit,
        loglik=-crit / 2.0, vcov_method="sigma^2 (R_X' R_X)^-1, as lmer's vcov",
        converged=ok, messages=_messages(data.dropped, [], ok, msg, singular), n_obs=n,
        n_cells=int(data.w.size),
        theta_names=data.theta_names,
        groups={t.name: t.n_levels for t in data.terms},
        criterion="REML",
    )


# -- the simplification rule --------------------------------------------------------------

Fitter = Callable[["pd.DataFrame", ModelSpec], MixedModelFit]


@one_blas_thread
def fit_simplified(df: pd.DataFrame, spec: ModelSpec, fitter: Fitter, *,
                   keep_slopes: bool = False) -> tuple[MixedModelFit, list[dict[str, Any]]]:
    """Fit the maximal model and simplify it while the fit is singular.

    The rule (Barr et al. 2013: start maximal; Matuschek et al. 2017: drop variance
    components the data do not support), applied after each singular fit, first
    applicable step only:

    1. a random term with slopes whose slope SD is 0 or whose correlation is +-1 (a
       zero diagonal element of its theta) loses its slopes (``(1 + condition |
       participant)`` -> ``(1 | participant)``);
    2. else an intercept-only term after the first (``(1 | target)``) estimated at SD 0
       is dropped, the last listed first;
    3. else the singular fit is kept and reported as singular: the first term (the
       participant intercept) is never dropped, so trials stay clustered by
       participant (at SD 0 the model equals a logistic regression).

    Returns:
        The final fit and one record per fit: ``formula``, ``singular``,
        ``zero_components`` and the ``action`` taken.
    """
    steps: list[dict[str, Any]] = []
    while True:
        fit = fitter(df, spec)
        zero = fit.zero_components()
        step: dict[str, Any] = {"formula": spec.formula(), "singular": fit.singular,
                                "zero_components": zero, "action": "kept"}
        steps.append(step)
        if not fit.singular:
            return fit, steps
        nxt, step["action"] = simplify_step(spec, zero, keep_slopes)
        if nxt is None:
            return fit, steps
        spec = nxt


def simplify_step(spec: ModelSpec, zero: Sequence[str],
                  keep_slopes: bool = False) -> tuple[ModelSpec | None, str]:
    """One step of :func:`fit_simplified`'s rule after a singular fit (None: keep it).

    Args:
        spec: the model that was fitted.
        zero: its theta elements at 0 (:meth:`MixedModelFit.zero_components`).
        keep_slopes: never drop a random slope (step 1 is skipped).
    """
    groups = {z.split(".")[0] for z in zero}
    for t in spec.random:
        if t.slopes and t.group in groups and not keep_slopes:
            return (spec.replace_term(t, RandomTerm(t.group)),
                    f"singular: dropped the random slope(s) of {t.group}")
    for t in reversed(spec.random[1:]):
        if not t.slopes and t.group in groups:
            return spec.replace_term(t), f"singular: dropped the random intercept of {t.group}"
    return None, "singular: nothing left to drop; the singular fit is reported"
