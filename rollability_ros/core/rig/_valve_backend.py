"""The valve backend contract and its table: what :class:`~rollability_ros.core.rig.valve.ValveController` calls.

A backend is what physically opens and closes the launcher's solenoid valve. It implements :class:`ValveBackend`:
``open()`` (acquire the device, valve closed), ``open_valve(pulse_ms)``, ``close_valve()`` and ``release()``
(drive closed, then free the device) are required; the rest have defaults for a board without the feature
(device-side arming, faults reported by the device, a diagnostics line, a reason to refuse firing). The controller
calls every method unconditionally and never asks what kind of backend it holds.

Adding a board: one module with a ``ValveBackend`` subclass (``name``, the four required methods, the optional
ones it supports, ``from_config`` when it reads ``valve.*``) plus one line in :data:`VALVE_BACKENDS`
(``"my_board": "package.module:MyBoardBackend"``), or :func:`register_valve_backend` at run time.
"""
import abc
import inspect
import typing

from rollability_ros.core.registry import Registry

if typing.TYPE_CHECKING:  # annotations only: valve imports this module
    from rollability_ros.core.rig.relay_protocol import DeviceLimits
    from rollability_ros.core.rig.valve import ValveConfig

#: Longest one backend call may take when the backend declares no other ``call_timeout_s``, s.
DEFAULT_CALL_TIMEOUT_S = 2.0


class ValveBackend(abc.ABC):
    """One valve driver. Errors are raised (any exception); the controller turns them into latched faults.

    None may rely on a released line or a closed port to close the valve: ``release()`` commands it closed first.

    Attributes
    ----------
    name : str
        ``valve.backend`` value and the ``backend`` field of ``msg/ValveState.msg``; required (non-empty).
    call_timeout_s : float
        Longest one call may take, s; the controller bounds each call by it.
    boot_wait_s : float
        Extra time ``open()`` may take while the device boots, s.
    limits : relay_protocol.DeviceLimits or None
        The device's own limits when it reports them.
    """

    name: str = ""
    call_timeout_s: float = DEFAULT_CALL_TIMEOUT_S
    boot_wait_s: float = 0.0
    limits: typing.Optional["DeviceLimits"] = None

    def __init_subclass__(cls, **kwargs: typing.Any) -> None:
        super().__init_subclass__(**kwargs)
        if not inspect.isabstract(cls) and not (isinstance(cls.name, str) and cls.name):
            raise TypeError(f"valve backend {cls.__name__} must set a non-empty class attribute name")

    @classmethod
    def from_config(cls, config: "ValveConfig") -> "ValveBackend":
        """The backend for ``config`` (a :class:`~rollability_ros.core.rig.valve.ValveConfig`), not yet opened."""
        return cls()

    # ---------------------------------------------------------------- required
    @abc.abstractmethod
    def open(self) -> None:
        """Acquire the device with the valve closed from the first instant."""

    @abc.abstractmethod
    def open_valve(self, pulse_ms: typing.Optional[float] = None) -> None:
        """Open the valve; ``pulse_ms`` (ms) is the pulse the controller times (a board may time it too)."""

    @abc.abstractmethod
    def close_valve(self) -> None:
        """Close the valve now."""

    @abc.abstractmethod
    def release(self) -> None:
        """Drive the valve closed, then free the device."""

    # ------------------------------------------------- optional, with defaults
    def arm(self) -> None:
        """Arm the device itself (default: the device has no arming of its own)."""

    def disarm(self) -> None:
        """Disarm the device itself (default: nothing to disarm)."""

    def clear(self) -> None:
        """Acknowledge a fault the device latched itself (default: it latches none)."""

    def fire_refusal(self) -> str:
        """A reason this backend must not fire at all, or "" (default: none)."""
        return ""

    def set_fault_listener(self, callback: typing.Callable[[str], None]) -> None:
        """Remember ``callback(reason)`` for faults the device reports on its own (default: it reports none)."""

    def link_state(self) -> str:
        """One line for diagnostics (default: ``"<name>: no device"``)."""
        return f"{self.name}: no device"

    def stalled(self) -> str:
        """A reason when a call of this backend's own (a keep-alive) overran its bound, else "" (default: none)."""
        return ""

    def startup_warning(self) -> str:
        """A warning the node logs once at start-up, or "" (default: none)."""
        return ""


#: ``valve.backend`` -> its :class:`ValveBackend` (``"module:Class"`` entries are imported when chosen).
VALVE_BACKENDS: Registry[ValveBackend] = Registry("backend", ValveBackend, {
    "dry_run": "rollability_ros.core.rig.valve_backends:DryRunBackend",
    "gpio": "rollability_ros.core.rig.valve_backends:GpioHolderBackend",
    "serial_relay": "rollability_ros.core.rig.valve_backends:SerialRelayBackend",
})


def register_valve_backend(name: str, backend_class: typing.Union[str, type]) -> None:
    """Add a board to :data:`VALVE_BACKENDS` at run time (a class or ``"module:Class"``)."""
    VALVE_BACKENDS.register(name, backend_class)


def make_valve_backend(config: "ValveConfig") -> ValveBackend:
    """The backend ``config.backend`` names, built from ``config`` and not yet opened (the only place that looks at
    the name)."""
    return VALVE_BACKENDS.get(config.backend).from_config(config)
