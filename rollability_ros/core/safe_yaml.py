"""The one YAML reader for files from disk (parameter files, designs.yaml, bag metadata): plain data, bounded.

:func:`load` is ``yaml.safe_load`` (plain data only: no tag constructs an object or runs code) that also refuses,
with a one-line :class:`YamlLimitError` naming the line, what no hand-written or generated file of ours needs and
what would otherwise end in a traceback or exhaust memory:

- nesting deeper than :data:`MAX_DEPTH` (20,000 ``[`` is a RecursionError in the composer and in every walk after);
- anchors and aliases whose expansion adds more than :data:`MAX_ALIAS_NODES` nodes to the document (a
  "billion laughs" file is a few hundred bytes that expand to 10^9 keys when walked as a tree), or that refer to
  themselves (a cycle, endless when walked); merge keys (``<<: *base``) count the same;
- a key written twice in one mapping (``trials: 2`` then ``trials: 3``): YAML keeps the last without a word.

:class:`YamlLimitError` is a ``yaml.YAMLError``, so a caller's ``except yaml.YAMLError`` covers it; use
:func:`one_line` to turn any YAML error into one line.
"""
import typing

import yaml

#: Deepest nesting of sequences and mappings accepted (the shipped parameter files nest 5 deep).
MAX_DEPTH = 100
#: Most nodes that anchors and aliases may add to a document when it is expanded as a tree.
MAX_ALIAS_NODES = 100_000

_MERGE_TAG = "tag:yaml.org,2002:merge"


class YamlLimitError(yaml.YAMLError):
    """A YAML file is well-formed but nests too deep, expands too far through aliases or repeats a key."""


def _line(node_or_mark: typing.Any) -> str:
    mark = getattr(node_or_mark, "start_mark", node_or_mark)
    return f"line {mark.line + 1}" if mark is not None else "an unknown line"


class _BoundedLoader(yaml.SafeLoader):   # pure Python: the C loader's composer cannot be bounded (it recurses)
    """``SafeLoader`` whose composer counts depth and refuses a key repeated in one mapping."""

    def __init__(self, stream: typing.Union[str, bytes, typing.IO]) -> None:
        super().__init__(stream)
        self._depth = 0

    # the scanner looks ahead past every unclosed '[' / '{' (each may start a key), so 200,000 of them would take
    # minutes before the composer sees the first: it stops at the limit too, for flow and block nesting
    def fetch_flow_collection_start(self, TokenClass: typing.Type[yaml.Token]) -> None:
        """Scan '[' or '{', refusing one that opens more than :data:`MAX_DEPTH` levels."""
        if self.flow_level >= MAX_DEPTH:
            raise YamlLimitError(f"nesting deeper than {MAX_DEPTH} levels at {_line(self.get_mark())}")
        super().fetch_flow_collection_start(TokenClass)

    def add_indent(self, column: int) -> bool:
        """Open a block level, refusing more than :data:`MAX_DEPTH`."""
        if len(self.indents) >= MAX_DEPTH:
            raise YamlLimitError(f"nesting deeper than {MAX_DEPTH} levels at {_line(self.get_mark())}")
        return super().add_indent(column)

    def compose_node(self, parent: typing.Optional[yaml.Node], index: typing.Any) -> typing.Optional[yaml.Node]:
        """Compose one node, refusing nesting deeper than :data:`MAX_DEPTH`."""
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise YamlLimitError(f"nesting deeper than {MAX_DEPTH} levels at {_line(self.peek_event())}")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def compose_mapping_node(self, anchor: typing.Any) -> yaml.MappingNode:
        """Compose one mapping, refusing a scalar key written twice in it (merge keys aside)."""
        node = super().compose_mapping_node(anchor)
        seen: typing.Dict[typing.Tuple[str, str], yaml.Node] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE_TAG:
                continue
            first = seen.setdefault((key_node.tag, key_node.value), key_node)
            if first is not key_node:
                raise YamlLimitError(f"duplicate key {key_node.value!r} at {_line(key_node)} (first at "
                                     f"{_line(first)}): YAML would keep the last one silently; write it once")
        return node


def _check_expansion(root: yaml.Node) -> None:
    """Raise :class:`YamlLimitError` if expanding ``root`` as a tree adds more than :data:`MAX_ALIAS_NODES` nodes
    (shared nodes counted once per reference, each node's size computed once) or never ends (a cycle)."""
    sizes: typing.Dict[int, int] = {}
    open_nodes: typing.Set[int] = set()

    def expanded(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in open_nodes:
            raise YamlLimitError(f"an alias at or after {_line(node)} refers to a node that contains it (a cycle)")
        open_nodes.add(key)
        if isinstance(node, yaml.SequenceNode):
            children = node.value
        elif isinstance(node, yaml.MappingNode):
            children = [item for pair in node.value for item in pair]
        else:
            children = []
        size = 1 + sum(expanded(child) for child in children)
        open_nodes.discard(key)
        sizes[key] = size
        if size - len(sizes) > MAX_ALIAS_NODES:   # len(sizes): distinct nodes seen so far, each written once
            raise YamlLimitError(f"anchors and aliases expand to more than {MAX_ALIAS_NODES} extra nodes (at "
                                 f"{_line(node)}); write the values out instead")
        return size

    expanded(root)   # depth is bounded by MAX_DEPTH, so this recursion is too


def load(stream: typing.Union[str, bytes, typing.IO]) -> typing.Any:
    """Parse one YAML document into plain data (dicts, lists, scalars; None for an empty one); raises
    ``yaml.YAMLError`` (:class:`YamlLimitError` for the limits in the module docstring)."""
    loader = _BoundedLoader(stream)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def one_line(exc: yaml.YAMLError) -> str:
    """The problem of a YAML error on one line, with its line and column (PyYAML's own text spans several)."""
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = " ".join(part for part in (exc.context, exc.problem) if part)
        return f"{problem or type(exc).__name__}{where}"
    return " ".join(str(exc).split())
