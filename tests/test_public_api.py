import subprocess
import sys

import tactorbelt


def test_public_names_are_exactly_all():
    expected = {
        "Belt", "ConfigError", "DeviceError", "Layout", "ProtocolError", "StoreError",
        "Stimulus", "StudyFileError", "TactorbeltError", "TargetSet", "__version__",
        "amplitudes", "make_stimulus", "normalize", "open_belt", "wrap",
    }
    assert set(tactorbelt.__all__) == expected
    for name in expected:
        assert getattr(tactorbelt, name) is not None


def test_error_hierarchy():
    assert issubclass(tactorbelt.ProtocolError, tactorbelt.DeviceError)
    for cls in (tactorbelt.ConfigError, tactorbelt.StudyFileError, tactorbelt.StoreError,
                tactorbelt.DeviceError):
        assert issubclass(cls, tactorbelt.TactorbeltError)


def test_help_imports_no_heavy_library():
    code = (
        "import sys\n"
        "from tactorbelt.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "heavy = [m for m in ('numpy', 'matplotlib', 'pandas', 'pygame', 'serial', 'bleak',"
        " 'scipy', 'statsmodels', 'pylsl', 'pyarrow') if m in sys.modules]\n"
        "print('HEAVY', heavy)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout
    assert "HEAVY []" in out


def test_every_subcommand_has_help():
    from tactorbelt.cli import COMMANDS

    for name in COMMANDS:
        proc = subprocess.run([sys.executable, "-m", "tactorbelt", name, "--help"],
                              capture_output=True, text=True)
        assert proc.returncode == 0, (name, proc.stderr)
        assert "Usage:" in proc.stdout


def test_belt_refuses_bad_frames_and_durations():
    import pytest

    from tactorbelt import ConfigError, Layout, make_stimulus, open_belt

    with open_belt("sim") as belt:
        for bad in ([0.1] * 5, [[0.1] * 3] * 2, [0.1] * 5 + [float("nan")], [0.1] * 5 + [1.5],
                    "abc"):
            with pytest.raises(ConfigError):
                belt.set_amplitudes(bad)
        with pytest.raises(ConfigError):
            belt.play(make_stimulus(Layout.even(6), 45.0), duration_s="long")  # type: ignore[arg-type]
        assert all(v == 0 for v in belt.levels)
