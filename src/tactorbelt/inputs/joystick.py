"""Joystick cursor source (SDL through pygame-ce), for a flight stick such as the
Thrustmaster HOTAS Warthog used in the paper.

Position control: the stick's deflection places the cursor inside the response
ellipse. :func:`stick_to_cursor` (pure, tested directly) maps the raw axes: inversion,
the square stick range onto the unit disc, a radial dead zone, and a clamp to radius 1.

Threads (see docs/window.md): pygame is initialised and its events are pumped only in
the main thread, by the experiment window (:meth:`JoystickCursor.handle_event` for
hot-plug events, :meth:`JoystickCursor.update` after each pump). :meth:`read` may be
called from any thread (the runner's 100 Hz loop): it only reads the latest state, one
immutable tuple, so it is cheap and needs no lock.

Hot-plug: the source follows ``JOYDEVICEADDED`` / ``JOYDEVICEREMOVED``. While the
chosen stick is unplugged, :attr:`connected` is False and :meth:`read` returns the
centre with no buttons (so nothing is acquired); the window pauses the session.

Imports the standard library, tactorbelt.inputs.base and .kinds; pygame only inside methods
(call :func:`prepare_sdl` before pygame is first imported).
"""

from __future__ import annotations

import math
import os
from typing import Any

from .._errors import ConfigError, DeviceError
from .base import LiveCursor
from .kinds import InputContext, JoystickConfig

__all__ = [
    "JoystickCursor",
    "list_joysticks",
    "prepare_sdl",
    "stick_to_cursor",
]


def prepare_sdl() -> None:
    """Set SDL's environment before pygame is initialised.

    ``SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS=1`` keeps joystick input flowing when the
    window loses focus (an experimenter clicking another window must not freeze the
    participant's stick). Existing values are kept.
    """
    os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def stick_to_cursor(
    ax: float,
    ay: float,
    dead_zone: float = 0.05,
    invert_x: bool = False,
    invert_y: bool = False,
) -> tuple[float, float]:
    """Map raw stick axes to a cursor position inside the unit disc.

    Args:
        ax: raw horizontal axis in [-1, 1] (SDL: + is right).
        ay: raw vertical axis in [-1, 1] (SDL: + is pulled back, towards the user).
        dead_zone: radial dead zone in [0, 1): deflections up to this radius give the
            centre; beyond it the radius is rescaled so full deflection still reaches 1.
        invert_x: mirror left/right.
        invert_y: mirror front/back (for a stick that reports + when pushed forward).

    Returns:
        ``(x, y)`` in cursor units: x right, y up = front (stick pushed forward), with
        ``x*x + y*y <= 1``. The square range of the stick maps onto the disc
        (elliptical grid mapping: the edges of the square land on the circle, the
        axes are unchanged), so a full diagonal deflection reaches the ellipse too.
    """
    if not 0.0 <= dead_zone < 1.0:
        raise ConfigError(f"dead zone must be in [0, 1), got {dead_zone!r}")
    if not (math.isfinite(ax) and math.isfinite(ay)):
        return 0.0, 0.0
    x = min(max(float(ax), -1.0), 1.0)
    y = -min(max(float(ay), -1.0), 1.0)
    if invert_x:
        x = -x
    if invert_y:
        y = -y
    # square [-1, 1]^2 onto the unit disc
    u = x * math.sqrt(max(1.0 - 0.5 * y * y, 0.0))
    v = y * math.sqrt(max(1.0 - 0.5 * x * x, 0.0))
    r = math.hypot(u, v)
    if r <= dead_zone:
        return 0.0, 0.0
    r_new = min((r - dead_zone) / (1.0 - dead_zone), 1.0)
    k = r_new / r
    return u * k, v * k


def list_joysticks() -> list[dict[str, Any]]:
    """The joysticks SDL sees: index, name, GUID, axes, buttons, hats (main thread).

    Initialises pygame's joystick module if needed.
    """
    prepare_sdl()
    import pygame

    pygame.joystick.init()
    out = []
    for i in range(pygame.joystick.get_count()):
        js = pygame.joystick.Joystick(i)
        out.append({
            "index": i,
            "name": js.get_name(),
            "guid": js.get_guid(),
            "axes": js.get_numaxes(),
            "buttons": js.get_numbuttons(),
            "hats": js.get_numhats(),
        })
    return out


def _matches(config: JoystickConfig, index: int, name: str) -> bool:
    dev = config.device
    if dev is None:
        return "throttle" not in name.lower()
    if isinstance(dev, int):
        return index == dev
    return dev.lower() in name.lower()


class _PygameJoysticks:
    """The default device backend: SDL joysticks through pygame-ce."""

    def count(self) -> int:
        import pygame

        pygame.joystick.init()
        return int(pygame.joystick.get_count())

    def open(self, device_index: int) -> Any:
        import pygame

        try:
            return pygame.joystick.Joystick(device_index)
        except pygame.error:
            return None


class JoystickCursor(LiveCursor):
    """A joystick as a cursor source, with hot-plug.

    Create it after pygame is initialised (the window does this), in the main thread.
    If no matching stick is plugged in yet, it waits for one (``connected`` False).

    Args:
        config: device choice and axis mapping.
        backend: where devices come from: an object with ``count()`` and
            ``open(device_index)`` returning a pygame-like Joystick (``get_name``,
            ``get_instance_id``, ``get_numaxes``, ``get_axis``, ``get_numbuttons``,
            ``get_button``) or None. Default: SDL through pygame-ce. Tests pass a fake.
    """

    def __init__(self, config: JoystickConfig | None = None, backend: Any = None) -> None:
        super().__init__()
        self.config = config or JoystickConfig()
        self._backend = backend if backend is not None else _PygameJoysticks()
        self._js: Any = None
        self._instance_id: int | None = None
        self.raw_axes: tuple[float, float] = (0.0, 0.0)
        for i in range(self._backend.count()):
            if self._try_open(i):
                break

    # -- device choice -----------------------------------------------------------------
    def _try_open(self, device_index: int) -> bool:
        js = self._backend.open(device_index)
        if js is None:
            return False
        name = str(js.get_name())
        if not _matches(self.config, device_index, name):
            return False
        need = max(self.config.axis_x, self.config.axis_y) + 1
        if js.get_numaxes() < need:
            raise DeviceError(
                f"joystick {device_index} ({name!r}) has {js.get_numaxes()} axes; "
                f"axis_x={self.config.axis_x} and axis_y={self.config.axis_y} need {need}"
            )
        self._js = js
        self._instance_id = int(js.get_instance_id())
        self.name = name
        self.update()
        return True

    @property
    def connected(self) -> bool:
        return self._js is not None

    @property
    def instance_id(self) -> int | None:
        """SDL's instance id of the open stick (events carry it), or None."""
        return self._instance_id

    def describe_wanted(self) -> str:
        """What the source waits for, in words (for the window's message)."""
        dev = self.config.device
        if dev is None:
            return "a joystick"
        if isinstance(dev, int):
            return f"joystick {dev}"
        return f"a joystick named like {dev!r}"

    # -- main thread -------------------------------------------------------------------
    def handle_event(self, event: Any) -> None:
        import pygame

        if event.type == pygame.JOYDEVICEADDED and self._js is None:
            try:
                self._try_open(int(event.device_index))
            except DeviceError as exc:  # a device that does not fit: keep waiting
                self.problem = str(exc)
        elif (event.type == pygame.JOYDEVICEREMOVED and self._js is not None
              and int(event.instance_id) == self._instance_id):
            self._js = None
            self._instance_id = None
            self.raw_axes = (0.0, 0.0)
            self.set_state(0.0, 0.0, 0)

    def update(self) -> None:
        js = self._js
        if js is None:
            return
        try:
            ax = float(js.get_axis(self.config.axis_x))
            ay = float(js.get_axis(self.config.axis_y))
            buttons = 0
            for b in range(min(js.get_numbuttons(), 31)):
                if js.get_button(b):
                    buttons |= 1 << b
        except Exception:  # the device vanished between the pump and this read
            return
        self.raw_axes = (ax, ay)
        x, y = stick_to_cursor(ax, ay, self.config.dead_zone, self.config.invert_x,
                               self.config.invert_y)
        self.set_state(x, y, buttons)

    def close(self) -> None:
        self._js = None


def cursor(ctx: InputContext) -> JoystickCursor:
    """The ``joystick`` input kind's cursor (:mod:`tactorbelt.inputs.kinds`): the stick
    ``ctx.joystick`` names (index, name substring, or a full JoystickConfig)."""
    stick = ctx.joystick
    if isinstance(stick, JoystickConfig):
        return JoystickCursor(stick)
    return JoystickCursor(JoystickConfig(
        device=JoystickConfig.parse_device(stick) if isinstance(stick, str) else stick))
