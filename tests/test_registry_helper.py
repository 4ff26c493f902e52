"""The one registry helper (tactorbelt._registry): resolve, check_option, Registry,
parse_url and lazy_attributes, as the registries of belts, sensors and kinds use them."""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass

import pytest

from tactorbelt._errors import ConfigError
from tactorbelt._registry import (
    Registry,
    UrlOption,
    check_option,
    lazy_attributes,
    parse_url,
    resolve,
)


def test_resolve_imports_module_attr() -> None:
    import os.path

    assert resolve("os.path:join") is os.path.join
    with pytest.raises(ModuleNotFoundError):
        resolve("tactorbelt.no_such_module:x")


def test_check_option_names_value_and_allowed() -> None:
    check_option("law", "linear", ("linear", "cosine"))
    with pytest.raises(ConfigError, match=r"^unknown law 'x'; allowed: linear, cosine$"):
        check_option("law", "x", ("linear", "cosine"))
    with pytest.raises(ConfigError, match=r"allowed: none$"):
        check_option("kind", "x", ())


@dataclass(frozen=True)
class _Kind:
    name: str
    needs_display: bool = False


def test_registry_by_name_in_order_and_checked() -> None:
    reg: Registry[_Kind] = Registry("input kind", [_Kind("keyboard"), _Kind("mouse", True)])
    assert reg.names() == ("keyboard", "mouse")
    assert "mouse" in reg and len(reg) == 2 and list(reg) == ["keyboard", "mouse"]
    assert reg.get("mouse").needs_display
    with pytest.raises(ConfigError, match=r"unknown input kind 'pen'; allowed: keyboard, mouse"):
        reg.get("pen")
    with pytest.raises(ValueError, match="registered twice"):
        Registry("input kind", [_Kind("a"), _Kind("a")])


@dataclass(frozen=True)
class _Entry:
    scheme: str
    examples: tuple[str, ...]
    target: str = ""
    options: tuple[UrlOption, ...] = ()


_ENTRIES = {e.scheme: e for e in (
    _Entry("sim", ("sim",), options=(UrlOption("n", int, "count", 1, 8),
                                     UrlOption("on", bool, "a switch"),
                                     UrlOption("rate", float, "rate", 0.5, 2.0),
                                     UrlOption("map", str, "a map"))),
    _Entry("port", ("port:auto",), target="PORT"),
)}


def test_parse_url_types_and_checks_options() -> None:
    entry, target, opts = parse_url("sim?n=3&on=yes&rate=1.5&map=0,1", _ENTRIES, "belt URL")
    assert entry.scheme == "sim" and target == ""
    assert opts == {"n": 3, "on": True, "rate": 1.5, "map": "0,1"}
    assert parse_url("port:/dev/x", _ENTRIES, "belt URL")[1] == "/dev/x"


@pytest.mark.parametrize(("url", "message"), [
    ("", r"belt URL must be a non-empty string"),
    ("nope:1", r"unknown belt URL 'nope:1'; allowed: sim, port"),
    ("port", r"belt URL 'port' needs a target, e.g. port:auto"),
    ("sim?n", r"expected key=value after '\?'"),
    ("sim?x=1", r"unknown option 'x' in belt URL 'sim\?x=1'; allowed: n, on, rate, map"),
    ("sim?n=9", r"option 'n' of belt URL 'sim\?n=9' must be in 1..8, got '9'"),
    ("sim?n=a", r"must be an integer"),
    ("sim?rate=nan", r"must be in 0.5..2"),
    ("sim?on=maybe", r"must be true or false"),
])
def test_parse_url_errors_name_the_url(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_url(url, _ENTRIES, "belt URL")


def test_parse_url_noun_target_word_and_no_target() -> None:
    with pytest.raises(ConfigError, match=r"sensor URL 'port' needs a device, e.g. port:auto"):
        parse_url("port", _ENTRIES, "sensor URL", target_word="device")
    with pytest.raises(ConfigError, match=r"sensor URL 'sim:3' takes no target"):
        parse_url("sim:3", _ENTRIES, "sensor URL", no_target=True)
    with pytest.raises(ConfigError, match=r"of sensor URL"):
        parse_url("sim?n=0", _ENTRIES, "sensor URL")
    with pytest.raises(ConfigError, match=r"allowed: sim:X, port:PORT"):
        parse_url("x", _ENTRIES, "belt URL", allowed=("sim:X", "port:PORT"))


def test_lazy_attributes_imports_on_first_use(monkeypatch: pytest.MonkeyPatch) -> None:
    pkg = types.ModuleType("_lazy_pkg")
    pkg.__path__ = []  # a package
    sub = types.ModuleType("_lazy_pkg.sub")
    sub.thing = 42  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "_lazy_pkg", pkg)
    monkeypatch.setitem(sys.modules, "_lazy_pkg.sub", sub)
    getattr_ = lazy_attributes("_lazy_pkg", {"thing": ".sub", "join": "os.path"})
    assert getattr_("thing") == 42
    import os.path

    assert getattr_("join") is os.path.join
    with pytest.raises(AttributeError, match="module '_lazy_pkg' has no attribute 'nope'"):
        getattr_("nope")


def test_registry_module_imports_only_stdlib_and_errors() -> None:
    import ast
    from pathlib import Path

    import tactorbelt._registry as mod

    tree = ast.parse(Path(mod.__file__).read_text())
    local = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.level]
    assert local == ["_errors"]


def test_the_export_reads_actuators_and_carrier_from_the_belts_registry_entry(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """No branch on a scheme's name: a backend that declares a carrier gets one in the
    BIDS stimulus system (the audio belt's default, or its URL's carrier_hz)."""
    from dataclasses import replace

    from tactorbelt.devices.audio import DEFAULT_CARRIER_HZ
    from tactorbelt.devices.registry import BACKENDS
    from tactorbelt.experiment.export import _stimulus_system

    assert _stimulus_system({"belt": "audio:default"})["CarrierFrequency"] == DEFAULT_CARRIER_HZ
    toy = replace(BACKENDS["sim"], scheme="toy", actuator="a toy LRA", carrier_hz=170.0)
    monkeypatch.setitem(BACKENDS, "toy", toy)
    system = _stimulus_system({"belt": "toy?carrier_hz=200"})
    assert system["ActuatorType"] == "a toy LRA" and system["CarrierFrequency"] == 200.0
    assert "CarrierFrequency" not in _stimulus_system({"belt": "sim"})
    assert _stimulus_system({"belt": "nope:1"})["ActuatorType"] == "unknown"
