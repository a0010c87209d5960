"""Registration tables: the implementations of one swap (valve board, speed gate, ...) by the setting's value.

A table maps a name to ``"package.module:Class"`` (imported when that name is chosen, so a board's library loads
only where it is used) or to the class itself (registered at run time, e.g. by a test). Adding an implementation
is one new module plus one entry; the table's :meth:`Registry.get` is the only place that looks at the name.
"""
import importlib
import typing

#: The contract of one table.
T = typing.TypeVar("T")


class Registry(typing.Generic[T]):
    """One swap's table: ``name -> subclass of base`` (given directly or as ``"module:Class"``); declared as
    ``Registry[Base]`` so that :meth:`get` is typed (an abstract ``base`` cannot bind the type variable).

    Parameters
    ----------
    field : str
        The setting that names an entry (``"backend"``), for the one-line refusal of an unknown name.
    base : type or str
        The contract every entry must subclass, or its ``"module:Class"`` (imported at the first :meth:`get`: a
        table declared below the module of its contract, as ``sim/engines.py``'s, names it so).
    entries : dict, optional
        The built-in entries.
    """

    def __init__(self, field: str, base: typing.Union[type, str], entries: typing.Optional[dict] = None):
        self.field = field
        self._base = base
        self._entries: dict = {}
        for name, target in (entries or {}).items():
            self.register(name, target)

    def register(self, name: str, target: typing.Union[str, type]) -> None:
        """Add ``name``; ``ValueError`` when it is empty or taken (unregister first to replace one)."""
        if not isinstance(name, str) or not name:
            raise ValueError(f"{self.field} names must be non-empty strings, got {name!r}")
        if name in self._entries:
            raise ValueError(f"{self.field} {name!r} is already registered")
        if not isinstance(target, (str, type)):
            raise TypeError(f"{self.field} {name!r}: register a class or 'module:Class', got {target!r}")
        self._entries[name] = target

    def unregister(self, name: str) -> None:
        """Remove ``name`` if present."""
        self._entries.pop(name, None)

    def names(self) -> tuple:
        """The registered names, in registration order."""
        return tuple(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def check(self, name: str) -> None:
        """``ValueError`` naming the known entries unless ``name`` is one (does not import it)."""
        if name not in self._entries:
            raise ValueError(f"{self.field} must be one of {self.names()}, got {name!r}")

    @property
    def base(self) -> type:
        """The contract every entry subclasses (imported now if given as ``"module:Class"``)."""
        base = _resolve(self._base) if isinstance(self._base, str) else self._base
        self._base = base
        return base

    def get(self, name: str) -> typing.Type[T]:
        """The class registered as ``name`` (imported now if given as ``"module:Class"``)."""
        self.check(name)
        target = self._entries[name]
        if isinstance(target, str):
            target = _resolve(target)
        base = self.base
        if not (isinstance(target, type) and issubclass(target, base)):
            raise TypeError(f"{self.field} {name!r} is {target!r}, not a {base.__name__}")
        return typing.cast(typing.Type[T], target)


def _resolve(target: str) -> typing.Any:
    """The attribute ``"module:Class"`` names, its module imported."""
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)
