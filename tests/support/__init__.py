"""Helpers shared by the test files: ``from support.studies import write_study``.

pytest puts ``tests/`` (the directory of the rootdir conftest; there is no
``tests/__init__.py``) on ``sys.path``, so this package imports as ``support``.

- :mod:`support.studies`: study TOML from the paper's protocol with keyword overrides.
- :mod:`support.inputs`: pygame-like joystick fakes.
- :mod:`support.belts`: firmware, loop-transport, serial-pty and BLE fakes, and the
  belt factories of the contract suite.

Test files never import each other; what two of them share goes here.
"""
