"""Static counts over rollability_ros (ast only, nothing imported): the import graph of the core and its layering,
annotated public functions, ``__all__`` faces and the imports that reach past one, ``hasattr`` / ``getattr`` probes.

``python test/code_counts.py`` prints them (the numbers of issue 29's closing note); test/core/test_layering.py
and test/core/test_mypy.py use the same functions.

Layers: ``rollability_ros/core/__init__.py`` lists the subpackages bottom first; a module may import from its own
subpackage, from those listed before it, and from the shared modules at the core's top level (:data:`SHARED`).
Every import counts, inside functions too (a function-level import is still a dependency, only a later one);
imports under ``if typing.TYPE_CHECKING:`` (annotations only, never executed) do not.
"""
import ast
import functools
import os
import pathlib
import re
import sys

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "rollability_ros"
CORE = PACKAGE / "core"
#: The core's top-level modules (config, optional, registry, records, ...): the shared bottom every subpackage may use.
SHARED = tuple(sorted(path.stem for path in CORE.glob("*.py") if path.stem != "__init__"))


@functools.lru_cache(maxsize=None)
def _parsed(path, mtime_ns, size):
    return ast.parse(pathlib.Path(path).read_text(), path)


def parsed(path):
    """The ast of the file ``path``, parsed once per version of it (the counts read every module many times)."""
    status = os.stat(path)
    return _parsed(str(path), status.st_mtime_ns, status.st_size)


def layer_order():
    """The subpackages in the order ``core/__init__.py`` lists them (``- name  description`` lines)."""
    text = ast.get_docstring(parsed(CORE / "__init__.py"))
    names = re.findall(r"^- (\w+)\s", text, flags=re.M)
    subpackages = sorted(p.name for p in CORE.iterdir() if (p / "__init__.py").is_file())
    assert sorted(names) == subpackages, f"core/__init__.py lists {names}, the core holds {subpackages}"
    return names


def module_name(path):
    """``core/sim/trials.py`` -> ``sim.trials``; ``core/sim/__init__.py`` -> ``sim``; ``core/config.py`` -> ``config``."""
    parts = path.relative_to(CORE).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def core_modules():
    """``{module name: path}`` of every module of the core (the core's own ``__init__`` left out)."""
    return {module_name(path): path for path in sorted(CORE.rglob("*.py")) if path != CORE / "__init__.py"}


def _annotation_only(tree):
    """The import nodes under ``if typing.TYPE_CHECKING:`` (annotations only: never executed)."""
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(child) for statement in node.body for child in ast.walk(statement))
    return skipped


def subpackages():
    """The core's subpackages (folders with an ``__init__.py``), sorted."""
    return sorted(p.name for p in CORE.iterdir() if (p / "__init__.py").is_file())


def face_stub(sub):
    """The face of subpackage ``sub``: ``core/<sub>/__init__.pyi`` (what ``lazy_loader.attach_stub`` and type checkers
    read)."""
    return CORE / sub / "__init__.pyi"


def face_exports(sub):
    """``{name: module below core}`` that the face of subpackage ``sub`` re-exports: the ``from .module import name``
    lines of its stub (``{}`` without one); a whole module re-exported (``from . import module``) maps to itself."""
    exports = {}
    if not face_stub(sub).is_file():
        return exports
    for node in parsed(face_stub(sub)).body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for alias in node.names:
                exports[alias.asname or alias.name] = (f"{sub}.{node.module}" if node.module
                                                       else f"{sub}.{alias.name}")
    return exports


def face_modules(sub):
    """The whole modules the face of ``sub`` exports as names (``from . import module`` in its stub)."""
    if not face_stub(sub).is_file():
        return []
    return sorted(alias.name for node in parsed(face_stub(sub)).body
                  if isinstance(node, ast.ImportFrom) and node.level == 1 and not node.module for alias in node.names)


def face_all(sub):
    """The names in subpackage ``sub``'s ``__all__`` (read statically from its stub), or ``None`` when its face has
    none."""
    if not face_stub(sub).is_file():
        return None
    for node in parsed(face_stub(sub)).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets) and node.value is not None:
                return list(ast.literal_eval(node.value))
    return None


def import_targets(node):
    """The dotted names an absolute ``import`` / ``from ... import`` node brings in; None for any other node."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        return [f"{node.module}.{alias.name}" for alias in node.names]
    return None


def imports_of(path, modules, faces=None):
    """``[(target module, line)]``: the core modules ``path`` imports, at module level and inside functions
    (imports under ``if typing.TYPE_CHECKING:``, for annotations only, are left out). ``faces`` (``{subpackage:
    face_exports(subpackage)}``) resolves a name taken from a lazy face to the module behind it."""
    found = []
    prefix = "rollability_ros.core."
    faces = faces or {}
    tree = parsed(path)
    skipped = _annotation_only(tree)
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        targets = import_targets(node)
        if targets is None:
            continue
        for target in targets:
            if not target.startswith(prefix):
                continue
            name = target[len(prefix):]
            sub, _, attribute = name.partition(".")
            if attribute in faces.get(sub, {}):
                name = faces[sub][attribute]
            while name and name not in modules:   # "sim.trials.make_trial_world" -> "sim.trials"
                name = name.rpartition(".")[0]
            if name:
                found.append((name, node.lineno))
    return found


def aliases(modules=None):
    """``{old path: module}`` of the modules that only re-export another (a docstring and one ``from
    rollability_ros.core.X import *``, e.g. ``results.records`` -> ``records``): importing one depends on X."""
    modules = core_modules() if modules is None else modules
    found = {}
    for name, path in modules.items():
        body = parsed(path).body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]
        if (len(body) == 1 and isinstance(body[0], ast.ImportFrom) and [a.name for a in body[0].names] == ["*"]
                and (body[0].module or "").startswith("rollability_ros.core.")):
            found[name] = body[0].module[len("rollability_ros.core."):]
    return found


def import_graph():
    """``{module: {imported module: first line}}`` over the core (each edge once, a module's self-import left out;
    an import of an alias counts as one of the module it re-exports, and aliases are not nodes)."""
    modules = core_modules()
    alias = aliases(modules)
    faces = {sub: face_exports(sub) for sub in subpackages()}
    graph = {}
    for name, path in modules.items():
        if name in alias:
            continue
        edges = {}
        for target, line in imports_of(path, modules, faces):
            target = alias.get(target, target)
            if target != name:
                edges.setdefault(target, line)
        graph[name] = edges
    return graph


def subpackage(module):
    """``sim.trials`` -> ``sim``; a shared top-level module -> itself."""
    return module.split(".")[0]


def upward_imports(graph=None):
    """``[(module, imported module)]`` that import from a subpackage listed after the module's own (or a shared
    module importing a subpackage)."""
    graph = import_graph() if graph is None else graph
    rank = {name: index for index, name in enumerate(layer_order())}
    upward = []
    for module, edges in sorted(graph.items()):
        own = subpackage(module)
        for target in sorted(edges):
            theirs = subpackage(target)
            if theirs in SHARED or theirs == own:
                continue
            if own in SHARED or rank[theirs] > rank[own]:
                upward.append((module, target))
    return upward


def strongly_connected(graph):
    """The strongly connected components of ``graph`` (``{node: iterable of nodes}``) with more than one node,
    each as a sorted tuple, sorted (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(tuple(sorted(component)))
    return sorted(components)


def subpackage_cycles(graph=None):
    """Cycles between subpackages: components of the subpackage graph (shared modules left out)."""
    graph = import_graph() if graph is None else graph
    packages = {}
    for module, edges in graph.items():
        own = subpackage(module)
        if own in SHARED:
            continue
        targets = packages.setdefault(own, set())
        targets.update(subpackage(t) for t in edges if subpackage(t) != own and subpackage(t) not in SHARED)
    return strongly_connected(packages)


def mutual_subpackages(graph=None):
    """Pairs of subpackages that import each other (the simplest cross-subpackage cycles), sorted."""
    graph = import_graph() if graph is None else graph
    edges = {(subpackage(m), subpackage(t)) for m, targets in graph.items() for t in targets}
    return sorted((a, b) for a, b in edges if a < b and (b, a) in edges and SHARED.count(a) == SHARED.count(b) == 0)


def module_cycles(graph=None):
    """Cycles between the modules of one subpackage: components of each subpackage's own module graph."""
    graph = import_graph() if graph is None else graph
    inside = {module: {t for t in edges if subpackage(t) == subpackage(module)} for module, edges in graph.items()}
    return strongly_connected(inside)


def function_level_imports():
    """Imports of core modules made inside functions, over the core."""
    modules = core_modules()
    count = 0
    for path in modules.values():
        tree = parsed(path)
        for function in ast.walk(tree):
            if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(function):
                    if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rollability_ros.core"):
                        count += 1
    return count


def public_functions(root=PACKAGE):
    """``(annotated, total)`` public functions and methods under ``root`` (name without a leading underscore;
    annotated: every parameter but self / cls, and the return)."""
    annotated = total = 0
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(parsed(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
                total += 1
                arguments = node.args.posonlyargs + node.args.args + node.args.kwonlyargs
                params = [a for a in arguments if a.arg not in ("self", "cls")]
                if node.returns is not None and all(a.annotation is not None for a in params):
                    annotated += 1
    return annotated, total


def faces(root=PACKAGE):
    """``(modules with __all__, modules)`` under ``root`` (a face's ``__all__`` is in its ``.pyi`` stub)."""
    paths = sorted(root.rglob("*.py"))
    with_all = sum(1 for path in paths if any(re.search(r"^__all__\s*[:=]", face.read_text(), flags=re.M)
                                              for face in (path, path.with_suffix(".pyi")) if face.is_file()))
    return with_all, len(paths)


def client_of(path):
    """Who imports, for :func:`deep_imports`: ``nodes``, ``cli``, ``core`` (a core module) or ``other``."""
    part = path.relative_to(PACKAGE).parts[0]
    return part if part in ("nodes", "cli", "core") else "other"


def deep_imports(root=PACKAGE):
    """``[(client, "file:line: what")]``: imports under ``root`` that reach past a core subpackage's face from
    outside that subpackage: a module behind the face (``rollability_ros.core.sim.evaluation``), or a name the face's
    ``__all__`` does not list. A subpackage's own modules import each other directly and are not counted."""
    prefix = "rollability_ros.core."
    subs = subpackages()
    exported = {sub: face_all(sub) for sub in subs}
    found = []
    for path in sorted(root.rglob("*.py")):
        relative = path.relative_to(PACKAGE).parts
        own = relative[1] if relative[0] == "core" and len(relative) > 2 else None
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.Import):
                taken = [(alias.name, None) for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                taken = [(node.module, [alias.name for alias in node.names])]
            else:
                continue
            for module, names in taken:
                if not module.startswith(prefix):
                    continue
                parts = module[len(prefix):].split(".")
                if parts[0] not in subs or parts[0] == own:
                    continue
                where = f"{path.relative_to(PACKAGE)}:{node.lineno}"
                if len(parts) > 1:
                    found.append((client_of(path), f"{where}: {module}"))
                elif names is not None:
                    found += [(client_of(path), f"{where}: {module}.{name} (not in __all__)") for name in names
                              if name not in (exported[parts[0]] or ())]
    return found


def probes(root=PACKAGE):
    """``hasattr(`` and ``getattr(`` calls under ``root`` (duck-typed seams show up as these)."""
    count = 0
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr",
                                                                                                   "getattr"):
                count += 1
    return count


#: The calls that turn flat parameters into settings: config's own (``section``, ``from_mapping``,
#: ``settings_from_sections``); the core's functions declared ``@config.edge_parse`` (built on them) join them.
PARSE_CALLS = ("section", "from_mapping", "settings_from_sections")


def _declaration(function):
    """``("edge_parse", None)`` or ``("file_schema", kind)`` for a function declared by ``config.edge_parse`` /
    ``config.file_schema(kind)``, else None."""
    for decorator in function.decorator_list:
        call = decorator if isinstance(decorator, ast.Call) else None
        target = call.func if call else decorator
        name = target.id if isinstance(target, ast.Name) else getattr(target, "attr", None)
        if name == "edge_parse" and call is None:
            return "edge_parse", None
        if name == "file_schema" and call is not None and call.args and isinstance(call.args[0], ast.Constant):
            return "file_schema", call.args[0].value
    return None


def declarations(root=CORE):
    """``{(module path below root, function's qualified name): ("edge_parse", None) or ("file_schema", kind)}``
    of the functions declared by ``@config.edge_parse`` / ``@config.file_schema(kind)``."""
    found = {}

    def visit(node, rel, scope):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                if not isinstance(child, ast.ClassDef) and _declaration(child):
                    found[(rel, ".".join(scope + [child.name]))] = _declaration(child)
                visit(child, rel, scope + [child.name])

    for path in sorted(root.rglob("*.py")):
        visit(parsed(path), path.relative_to(root).as_posix(), [])
    return found


def _calls(root, names):
    """``{(module path below root, enclosing function's qualified name, called name): calls}`` of the calls of
    ``names`` (by name or attribute) in the modules below ``root`` (``config.py`` left out: it defines the parse)."""
    sites = {}

    def visit(node, rel, scope):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                visit(child, rel, scope + [child.name])
                continue
            if isinstance(child, ast.Call):
                func = child.func
                name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
                if name in names:
                    key = (rel, ".".join(scope), name)
                    sites[key] = sites.get(key, 0) + 1
            visit(child, rel, scope)

    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel != "config.py":
            visit(parsed(path), rel, [])
    return sites


def _declared_scope(rel, scope, declared):
    """The declaration of the innermost declared function enclosing ``scope`` in module ``rel``, else None."""
    parts = scope.split(".") if scope else []
    for end in range(len(parts), 0, -1):
        found = declared.get((rel, ".".join(parts[:end])))
        if found:
            return found
    return None


def parse_sites(root=CORE):
    """``{(module path below core, enclosing function's qualified name): calls}``: where flat parameters are still
    parsed below the edge. A call counts when it parses (:data:`PARSE_CALLS`, or a function declared
    ``@config.edge_parse``) outside a declared function: inside an ``edge_parse`` it is the edge's parse; inside a
    ``file_schema`` reader only ``PARSE_CALLS`` pass (it reads its own file and no parameter files)."""
    declared = declarations(root)
    edge = {qualified.rsplit(".", 1)[-1] for (_rel, qualified), (kind, _) in declared.items() if kind == "edge_parse"}
    sites = {}
    for (rel, scope, name), calls in _calls(root, set(PARSE_CALLS) | edge).items():
        inside = _declared_scope(rel, scope, declared)
        if inside is not None and (inside[0] == "edge_parse" or name in PARSE_CALLS):
            continue
        sites[(rel, scope)] = sites.get((rel, scope), 0) + calls
    return sites


def edge_parses_without_edge(root=CORE, edges=(PACKAGE / "cli", PACKAGE / "nodes")):
    """The functions declared ``@config.edge_parse`` that neither an edge (a module below ``edges``) nor another
    edge parse calls: a declaration that no edge honours (``[(module, function)]``)."""
    declared = declarations(root)
    parses = {(rel, qualified) for (rel, qualified), (kind, _) in declared.items() if kind == "edge_parse"}
    names = {qualified.rsplit(".", 1)[-1] for _rel, qualified in parses}
    called = set()
    for edge in edges:
        called |= {name for (_rel, _scope, name) in _calls(edge, names)}
    called |= {name for (rel, scope, name) in _calls(root, names)
               if (_declared_scope(rel, scope, declared) or ("",))[0] == "edge_parse"
               and scope.rsplit(".", 1)[-1] != name}
    return sorted((rel, qualified) for rel, qualified in parses if qualified.rsplit(".", 1)[-1] not in called)


def file_schemas(root=CORE):
    """``{kind: [(module, function), ...]}`` of the ``@config.file_schema(kind)`` readers (one per kind)."""
    kinds = {}
    for site, (kind, what) in declarations(root).items():
        if kind == "file_schema":
            kinds.setdefault(what, []).append(site)
    return kinds


#: Issue 43's limits: lines of a module, lines of a function (``def`` to its last line, decorators left out), public
#: core signatures that mention ``Any``.
MODULE_LINES_LIMIT = 700
FUNCTION_LINES_LIMIT = 80
ANY_SIGNATURES_LIMIT = 40
MYPY_INI = PACKAGE.parent / "mypy.ini"


def module_lines(root=PACKAGE):
    """``{path below root's parent: lines}`` of every module under ``root``, largest first."""
    sizes = {path.relative_to(root.parent).as_posix(): len(path.read_text().splitlines())
             for path in sorted(root.rglob("*.py"))}
    return dict(sorted(sizes.items(), key=lambda item: (-item[1], item[0])))


def function_lines(root=PACKAGE):
    """``{"path:qualified name": lines}`` of every function and method under ``root`` (nested ones too, each
    counted whole), longest first."""
    sizes = {}

    def visit(node, rel, scope):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = scope + [child.name]
                if not isinstance(child, ast.ClassDef):
                    sizes[f"{rel}:{'.'.join(name)}"] = child.end_lineno - child.lineno + 1
                visit(child, rel, name)
            else:
                visit(child, rel, scope)

    for path in sorted(root.rglob("*.py")):
        visit(parsed(path), path.relative_to(root.parent).as_posix(), [])
    return dict(sorted(sizes.items(), key=lambda item: (-item[1], item[0])))


def any_aliases(root=CORE):
    """Names of the core's module-level type aliases whose value mentions ``Any`` (``Mesh = typing.Any``,
    ``Row = typing.Dict[str, typing.Any]``): a signature naming one uses ``Any`` as much as one writing it."""
    names = set()
    for path in sorted(root.rglob("*.py")):
        for node in parsed(path).body:
            if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                    and re.search(r"\bAny\b", ast.unparse(node.value))
                    and re.match(r"(typing\.)?(Any|Callable|Dict|List|Mapping|Sequence|Tuple|Union|Optional)\b",
                                 ast.unparse(node.value))):
                names.add(node.targets[0].id)
    return names


def _mentions_any(annotation, aliases=()):
    """Whether an annotation names ``Any`` (``typing.Any``, ``Any``, inside a subscript or a string too) or one of
    ``aliases`` (type aliases that stand for something with ``Any``)."""
    if annotation is None:
        return False
    text = annotation.value if isinstance(annotation, ast.Constant) and isinstance(annotation.value, str) \
        else ast.unparse(annotation)
    words = set(re.findall(r"\b\w+\b", text))
    return "Any" in words or bool(words & set(aliases))


def any_signatures(root=CORE):
    """``["module:qualified name"]`` of the public functions and methods of the core whose signature (a parameter's
    or the return annotation) mentions ``Any``. Public: the function's, its classes' and its module's names have no
    leading underscore (dunder methods of a public class count: ``__init__`` is the class's signature). A type alias
    of the core that stands for something with ``Any`` (:func:`any_aliases`) counts as ``Any``."""
    found = []
    aliases = any_aliases(root)

    def public(name):
        return not name.startswith("_") or (name.startswith("__") and name.endswith("__"))

    def visit(node, rel, scope):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                if public(child.name):
                    visit(child, rel, scope + [child.name])
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if not public(child.name):
                    continue
                args = child.args
                every = args.posonlyargs + args.args + args.kwonlyargs + [a for a in (args.vararg, args.kwarg) if a]
                if _mentions_any(child.returns, aliases) or any(_mentions_any(a.annotation, aliases) for a in every):
                    found.append(f"{rel}:{'.'.join(scope + [child.name])}")
            elif not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, rel, scope)

    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if all(public(part) for part in path.relative_to(root).with_suffix("").parts):
            visit(parsed(path), rel, [])
    return found


BENCH = PACKAGE.parent / "bench"


def bench_tier(name):
    """The bench scripts bench/smoke.py's tuple ``name`` (``SMOKE``: the README's test command; test/test_bench_smoke.py
    runs it) names that exist and declare ``--smoke``, their tiny size."""
    for node in parsed(BENCH / "smoke.py").body:
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AnnAssign) else [])
        if targets and node.value is not None and any(isinstance(target, ast.Name) and target.id == name
                                                      for target in targets):
            return [bench for bench in ast.literal_eval(node.value) if (BENCH / f"{bench}.py").is_file()
                    and '"--smoke"' in (BENCH / f"{bench}.py").read_text(encoding="utf-8")]
    return []


def bench_coverage():
    """``(bench scripts, run at a tiny size by the test command, type-checked by it)``: the scripts in bench/ (its
    runner smoke.py left out), those bench/smoke.py's ``SMOKE`` runs with ``--smoke`` (test/test_bench_smoke.py), and
    those under mypy (test/core/test_mypy.py checks ``bench`` whole: all of them, when it names it)."""
    scripts = sorted(path.stem for path in BENCH.glob("*.py") if path.stem != "smoke")
    smoke = [name for name in bench_tier("SMOKE") if name in scripts]
    checked = scripts if '"bench"' in (PACKAGE.parent / "test" / "core" / "test_mypy.py").read_text() else []
    return scripts, smoke, checked


def check_untyped_defs(ini=MYPY_INI):
    """Whether mypy.ini's ``[mypy]`` section turns ``check_untyped_defs`` on (mypy checks unannotated bodies)."""
    import configparser

    parser = configparser.ConfigParser()
    parser.read(ini)
    return parser.getboolean("mypy", "check_untyped_defs", fallback=False)


def type_only_imports(path, modules):
    """``[(target module, line)]``: the core modules ``path`` imports under ``if typing.TYPE_CHECKING:`` only."""
    prefix = "rollability_ros.core."
    tree = parsed(path)
    skipped = _annotation_only(tree)
    found = []
    for node in ast.walk(tree):
        if id(node) not in skipped:
            continue
        targets = import_targets(node)
        if targets is None:
            continue
        for target in targets:
            name = target[len(prefix):] if target.startswith(prefix) else ""
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name:
                found.append((name, node.lineno))
    return found


def type_only_back_references(graph=None):
    """``[(module, imported module)]``: imports under ``if typing.TYPE_CHECKING:`` in a module of the core (faces
    left out) of a module that imports it back at run time, directly or through others: a cycle that exists only
    for the type checker (a contract module naming its caller's types)."""
    graph = import_graph() if graph is None else graph
    modules = core_modules()
    alias = aliases(modules)

    def reaches(start, goal):
        seen, todo = set(), [start]
        while todo:
            node = todo.pop()
            if node == goal:
                return True
            if node not in seen:
                seen.add(node)
                todo.extend(graph.get(node, ()))
        return False

    found = set()
    for name, path in modules.items():
        if name in alias or path.name == "__init__.py":
            continue
        for target, _ in type_only_imports(path, modules):
            target = alias.get(target, target)
            if target != name and target in graph and reaches(target, name):
                found.add((name, target))
    return sorted(found)


def names_past_faces(roots=(PACKAGE,)):
    """``["file: subpackage.module.name"]`` of the names that code outside a core subpackage uses through one of its
    modules rather than through the face's ``__all__``: ``module.name`` after ``from rollability_ros.core.sim import
    evaluation`` (a face exporting a whole module) or after ``import rollability_ros.core.sim.evaluation``, and
    ``from rollability_ros.core.sim.evaluation import name`` (a deep import). Sorted, each (file, name) once. A
    module bound by an import is followed in the function (or module) that imports it and the functions inside it,
    until a name there is assigned anew."""
    prefix = "rollability_ros.core."
    subs = set(subpackages())
    found = set()
    scopes = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)

    def own_nodes(scope):
        """The nodes of ``scope``'s body, not descending into functions and classes defined in it."""
        todo = list(ast.iter_child_nodes(scope))
        while todo:
            node = todo.pop()
            yield node
            if not isinstance(node, scopes):
                todo.extend(ast.iter_child_nodes(node))

    def visit(scope, outer, where, own):
        bound = dict(outer)
        nodes = list(own_nodes(scope))
        for node in nodes:
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                bound.pop(node.id, None)
        for node in nodes:
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith(prefix):
                parts = node.module[len(prefix):].split(".")
                if parts[0] not in subs or parts[0] == own:
                    continue
                for alias in node.names:
                    if len(parts) == 1 and (CORE / parts[0] / f"{alias.name}.py").is_file():
                        bound[alias.asname or alias.name] = f"{parts[0]}.{alias.name}"
                    elif len(parts) > 1:
                        found.add(f"{where}: {'.'.join(parts)}.{alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name[len(prefix):].split(".") if alias.name.startswith(prefix) else []
                    if len(parts) > 1 and parts[0] in subs and parts[0] != own:
                        bound[alias.asname or alias.name] = ".".join(parts)
        for node in nodes:
            if isinstance(node, ast.Attribute) and ast.unparse(node.value) in bound:
                found.add(f"{where}: {bound[ast.unparse(node.value)]}.{node.attr}")
            elif isinstance(node, scopes):
                visit(node, bound, where, own)

    for root in roots:
        for path in sorted(root.rglob("*.py")):
            relative = path.relative_to(root).parts
            own = relative[1] if root == PACKAGE and relative[0] == "core" and len(relative) > 2 else None
            visit(parsed(path), {}, path.relative_to(PACKAGE.parent).as_posix(), own)
    return sorted(found)


def main():
    graph = import_graph()
    upward = upward_imports(graph)
    annotated, total = public_functions()
    with_all, modules = faces()
    print(f"core modules: {len(graph)} (and {len(aliases())} old paths re-exporting one); imports of core modules "
          f"inside functions: {function_level_imports()}")
    print(f"upward imports: {len(upward)}")
    for module, target in upward:
        print(f"  {module} -> {target} (line {graph[module][target]})")
    print(f"cycles between subpackages: {len(subpackage_cycles(graph))} {subpackage_cycles(graph)}")
    print(f"subpackage pairs importing each other: {len(mutual_subpackages(graph))} {mutual_subpackages(graph)}")
    print(f"cycles inside subpackages: {len(module_cycles(graph))} {module_cycles(graph)}")
    print(f"annotated public functions: {annotated} of {total} ({100 * annotated / total:.0f}%)")
    print(f"__all__ faces: {with_all} of {modules} modules; subpackages with a face: "
          f"{sum(face_all(sub) is not None for sub in subpackages())} of {len(subpackages())}")
    deep = deep_imports()
    print("imports past a subpackage's face: " + ", ".join(
        f"{client} {sum(1 for c, _ in deep if c == client)}" for client in ("nodes", "cli", "core", "other")))
    print(f"hasattr/getattr calls: {probes()}")
    sites = parse_sites()
    print(f"flat parameters parsed below the edge (calls in the core outside config.py, its declared edge parses "
          f"and file schema readers): {sum(sites.values())} in {len(sites)} functions")
    for (module, function), calls in sorted(sites.items()):
        print(f"  core/{module} {function}: {calls}")
    print_limits(graph)
    return 0


def print_limits(graph):
    """Issue 43's counts, each with its limit and what is over it."""
    sizes = module_lines()
    over = {path: lines for path, lines in sizes.items() if lines > MODULE_LINES_LIMIT}
    print(f"largest module: {max(sizes.values())} lines (limit {MODULE_LINES_LIMIT}); over the limit: {len(over)}")
    for path, lines in over.items():
        print(f"  {path}: {lines}")
    lengths = function_lines()
    over = {name: lines for name, lines in lengths.items() if lines > FUNCTION_LINES_LIMIT}
    print(f"longest function: {max(lengths.values())} lines (limit {FUNCTION_LINES_LIMIT}); over the limit: "
          f"{len(over)}")
    for name, lines in over.items():
        print(f"  {name}: {lines}")
    print(f"public core signatures using Any: {len(any_signatures())} (limit {ANY_SIGNATURES_LIMIT})")
    print(f"mypy check_untyped_defs: {'on' if check_untyped_defs() else 'off'}")
    scripts, smoke, checked = bench_coverage()
    print(f"bench scripts type-checked by the test command: {len(checked)} of {len(scripts)}")
    print(f"bench scripts run at a tiny size by the test command: {len(smoke)} of {len(scripts)} ({', '.join(smoke)})")
    print(f"bench scripts not run at a tiny size by the test command: {len(scripts) - len(smoke)}")
    back = type_only_back_references(graph)
    print(f"TYPE_CHECKING back-references: {len(back)}")
    for module, target in back:
        print(f"  {module} -> {target}")
    print(f"alias modules: {len(aliases())} {sorted(aliases())}")
    past = names_past_faces()
    print(f"names used past a face (package): {len(past)} uses of {len({w.split(': ')[1] for w in past})} names")
    for where in past:
        print(f"  {where}")
    outside = names_past_faces((PACKAGE.parent / "test", PACKAGE.parent / "bench"))
    print(f"names used past a face (tests and benches, not limited): {len(outside)}")


if __name__ == "__main__":
    sys.exit(main())
