"""Joystick test doubles shared by several test files (``from support.inputs import ...``)."""

from __future__ import annotations


class FakeStick:
    """A pygame-like Joystick whose axes and buttons the test sets."""

    def __init__(self, instance_id: int, name: str = "Thrustmaster HOTAS Warthog Joystick (fake)",
                 n_axes: int = 3, n_buttons: int = 4) -> None:
        self.axes = [0.0] * n_axes
        self.buttons = [0] * n_buttons
        self.instance_id = instance_id
        self.name = name

    def get_name(self) -> str:
        return self.name

    def get_instance_id(self) -> int:
        return self.instance_id

    def get_numaxes(self) -> int:
        return len(self.axes)

    def get_axis(self, i: int) -> float:
        return self.axes[i]

    def get_numbuttons(self) -> int:
        return len(self.buttons)

    def get_button(self, i: int) -> int:
        return self.buttons[i]


class FakeBackend:
    """The joystick backend with one stick that the test can unplug (``plugged``)."""

    def __init__(self, stick: FakeStick | None = None) -> None:
        self.plugged = True
        self.stick = stick or FakeStick(100)

    def count(self) -> int:
        return 1 if self.plugged else 0

    def open(self, index: int) -> FakeStick | None:
        return self.stick if self.plugged and index == 0 else None
