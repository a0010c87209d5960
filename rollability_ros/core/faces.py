"""Lazy package faces (PEP 562): a subpackage's ``__init__`` names its public API once, for readers and type
checkers, and imports the module behind a name only when the name is first used.

A lazy face writes its re-exports as ordinary imports under ``if typing.TYPE_CHECKING:`` (mypy and editors see
them; nothing there runs), lists the same names in ``__all__`` and ends with::

    def __getattr__(name: str) -> typing.Any:
        return lazy_attribute(__name__, name)

:func:`lazy_attribute` reads that block of the face's own source (once, with ast) to learn which module holds each
name, imports that module and keeps the value on the package. So ``import rollability_ros.core.sim`` loads nothing
behind the face (no numpy, physics or plotting), and ``from rollability_ros.core.sim import evaluate_profile`` loads
``sim/evaluation`` and what it imports, no more. A name the block does not re-export is an ``AttributeError``, as
for any module (``from package import submodule`` then imports the submodule, as usual).
test/core/test_faces.py checks that ``__all__`` and the block agree and that importing a face loads no heavy module.
"""
import ast
import functools
import importlib
import sys
import typing


@functools.lru_cache(maxsize=None)
def face_exports(package: str) -> typing.Dict[str, typing.Tuple[str, str]]:
    """``{name: (module, attribute)}`` that the face of ``package`` (an imported package) re-exports: the ``from ...
    import`` statements under its ``if typing.TYPE_CHECKING:`` block; a submodule re-exported by name has the
    attribute ``""``."""
    path = sys.modules[package].__file__
    assert path is not None, package
    with open(path, encoding="utf-8") as source:
        tree = ast.parse(source.read(), path)
    exports = {}
    for node in tree.body:
        if not (isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)):
            continue
        for statement in node.body:
            if isinstance(statement, ast.ImportFrom) and statement.level == 0 and statement.module:
                for alias in statement.names:
                    if statement.module == package:
                        exports[alias.asname or alias.name] = (f"{package}.{alias.name}", "")
                    else:
                        exports[alias.asname or alias.name] = (statement.module, alias.name)
    return exports


def lazy_attribute(package: str, name: str) -> typing.Any:
    """The value of ``package.name`` for a lazy face's ``__getattr__``: imports the module behind ``name`` (see
    :func:`face_exports`) and sets the value on the package, so the next use does not come here."""
    try:
        module_name, attribute = face_exports(package)[name]
    except KeyError:
        raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
    module = importlib.import_module(module_name)
    value = getattr(module, attribute) if attribute else module
    setattr(sys.modules[package], name, value)
    return value
