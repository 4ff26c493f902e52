"""Helpers shared by the test files: ``from support.studies import write_study``.

pytest puts ``tests/`` (the directory of the rootdir conftest; there is no
``tests/__init__.py``) on ``sys.path``, so this package imports as ``support``.

- :mod:`support.studies`: study TOML from the paper's protocol with keyword overrides.
- :mod:`support.inputs`: pygame-like joystick fakes.
- :mod:`support.belts`: firmware, loop-transport, serial-pty and BLE fakes, and the
  belt factories of the contract suite.
- :mod:`support.xvfb`, :mod:`support.xinput`, :mod:`support.recordingbelt`: a real
  PsychoPy window under Xvfb, input into it, a belt whose commands another process reads.
- :mod:`support.toy_task`: a toy secondary-task kind; :mod:`support.jack_filter`: a
  JACK client with a known first-order response.

docs/testing.md lists every helper.

Test files never import each other; what two of them share goes here.
"""
