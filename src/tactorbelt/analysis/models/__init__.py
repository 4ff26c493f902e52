"""The models room: the report's mixed models. :mod:`.fit` builds them from the trials
and fits them (:func:`.fit.fit_model`, the one public fit function; ``mixed_model`` and
``rt_model`` for the report); :mod:`.glmm` (Laplace GLMM, LMM), :mod:`.lrt`
(likelihood-ratio, Wald and parametric-bootstrap tests of the condition),
:mod:`.satterthwaite`, :mod:`.contrasts`, :mod:`.separation` and :mod:`.lme4` (R through
Rscript) are its parts.

Imports only the tables room below it.
"""
