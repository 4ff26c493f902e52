"""The power analysis reads the study once, into one design object (power/design.py), and
every analysis (model participants, factorial, the GLMM for named effect sizes) takes it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from support.studies import make_study
from tactorbelt import ConfigError
from tactorbelt.experiment.study import Study, paper_study, template_toml
from tactorbelt.power.design import PowerDesign
from tactorbelt.power.glmm import NamedEffect
from tactorbelt.power.study import run_power_study


class _ReadOnce:
    """A study that refuses every read once the design has been made of it."""

    def __init__(self, study: Study) -> None:
        self._study = study
        self.closed = False

    def __getattr__(self, name: str) -> Any:
        if self.__dict__["closed"]:
            raise AssertionError(f"study.{name} read after the design was made")
        return getattr(self._study, name)


@pytest.mark.parametrize("template, effect, named", [
    ("paper", None, None),                           # model participants, the paper's test
    ("resolution", "interaction", None),             # factorial
    ("load", "load", None),                          # factorial, under a load
    ("paper", None, NamedEffect(3.0)),               # the report's GLMM
])
def test_the_study_is_read_once_for_every_analysis(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, template: str, effect: str | None,
        named: NamedEffect | None) -> None:
    made: list[PowerDesign] = []
    read = PowerDesign.from_study.__func__  # type: ignore[attr-defined]

    def from_study(cls: type[PowerDesign], study: _ReadOnce) -> PowerDesign:
        made.append(read(cls, study))
        study.closed = True
        return made[-1]

    monkeypatch.setattr(PowerDesign, "from_study", classmethod(from_study))
    study = _ReadOnce(Study.from_toml(template_toml(template)))
    result = run_power_study(study, [3], 2, 1, tmp_path, jobs=1,  # type: ignore[arg-type]
                             effect=effect, named=named)
    assert len(made) == 1
    assert result.study_name == made[0].name and result.rows[0].sims == 2
    assert json.loads((tmp_path / "power.json").read_text())["study"] == made[0].name


def test_the_views_of_the_papers_design_agree() -> None:
    design = PowerDesign.from_study(paper_study())
    assert design.counts == (24,) and design.conditions == ("static", "dynamic")
    assert design.loads == ("none",) and not design.loaded
    protocol = design.protocol()
    assert protocol.targets.m == 24 and protocol.blocks == (("static", 5), ("dynamic", 5))
    assert (protocol.law, protocol.period_s, protocol.threshold) == (
        design.stimulus.law, design.stimulus.period_s, design.threshold)
    factorial = design.factorial()
    assert factorial.parts == (protocol,) and factorial.load_levels == ()
    trials = design.trials()
    assert trials.n == 240 and trials.counts is None
    assert [int((trials.condition == c).sum()) for c in ("static", "dynamic")] == [120, 120]


def test_a_factorial_design_has_a_view_per_target_count() -> None:
    design = PowerDesign.from_study(Study.from_toml(template_toml("resolution")))
    assert design.counts == (12, 24, 36, 48)
    with pytest.raises(ConfigError, match=r"4 target counts .*PowerDesign.factorial"):
        design.protocol()
    factorial = design.factorial()
    assert factorial.counts == design.counts
    assert all(sorted(p.conditions) == ["dynamic", "static"] for p in factorial.parts)
    assert design.trials(36).n == 36 * 2 * 2


def test_a_load_design_carries_each_blocks_load() -> None:
    design = PowerDesign.from_study(Study.from_toml(template_toml("load")))
    assert design.loads == ("none", "nback2") and design.loaded
    levels = {b.load: b.load_level for b in design.blocks}
    assert levels["none"] == 0.0 and levels["nback2"] > 0
    factorial = design.factorial()
    assert set(factorial.loads[0]) == {"none", "nback2"}
    assert factorial.load_levels == (tuple(b.load_level for b in design.blocks),)


def test_a_blocks_stimulus_is_the_studys_with_its_overrides() -> None:
    study = make_study(blocks=[{"condition": "static", "repetitions": 1, "period_s": 2.0},
                               {"condition": "dynamic", "repetitions": 1}])
    design = PowerDesign.from_study(study)
    assert [b.stimulus.period_s for b in design.blocks] == [2.0, 1.0]
    assert design.stimulus.period_s == 1.0
    # one target count: the study's stimulus; per count: its first block's
    assert design.protocol().period_s == 1.0
    assert design.factorial().period_s == 2.0
