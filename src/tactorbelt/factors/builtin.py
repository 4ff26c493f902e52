"""The factors of a between-tactor study: condition, target count and load."""

from __future__ import annotations

from .declaration import Factor

__all__ = ["BUILTIN", "CONDITION", "LOAD", "TARGETS"]

#: How a between-tactor target is rendered; every ``[[test]]`` block names one.
CONDITION = Factor(
    key="condition", column="condition", type="text",
    description="Rendering of between-tactor targets.",
    # the stimulus modes (tactorbelt.stimuli.MODES; a test holds them equal)
    levels={"static": "constant amplitudes",
            "dynamic": "trapezoidal perturbation between the two nearest tactors"},
    changes="stimulus", name_rank=0, cross_rank=1, max_levels=2,
)

#: How many targets a block has (at k*360/n); a block without ``targets`` has the
#: study's ``[targets] count``.
TARGETS = Factor(
    key="targets", column="n_targets", type="int",
    description="Target count of the trial's block (targets at k*360/n_targets); "
                "the response snaps to these.",
    term="factor(n_targets)", changes="targets", name_rank=1, cross_rank=0,
    measure="scale", low=1, high=360,
)

#: The secondary task during a block: ``none``, or the name of a ``[tasks.NAME]`` table.
LOAD = Factor(
    key="load", column="load", type="text",
    description="Secondary task during the block ('none' without one).",
    default="none", changes="task", name_rank=2, cross_rank=2,
    block_name=lambda level: "" if level == "none" else str(level),
)

#: In the order the mixed model lists them.
BUILTIN: tuple[Factor, ...] = (CONDITION, TARGETS, LOAD)
