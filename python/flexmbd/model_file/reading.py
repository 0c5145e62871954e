"""Reading model files: YAML with the line of every key, safe (plain data only, YAML 1.1
surprises refused), with limits checked before work, and pydantic's errors turned into one
:class:`flexmbd.errors.ModelFileError` naming the file, the line and the key path."""

from __future__ import annotations

import difflib
import re
import stat
import types
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Union

import yaml
from pydantic import BaseModel, Tag, ValidationError

from .._checks import value_text
from ..errors import ModelFileError
from .schema import ModelSpec

# ---------------------------------------------------------------------------------------------
# Reading YAML with the line of every key

Path_ = tuple[str | int, ...]

#: Largest model file (bytes), checked before it is read: meshes and matrices belong in mesh
#: and body files, long tables in body files or splines of a few thousand knots.
MAX_FILE_SIZE = 4 * 1024 * 1024

#: Most items a model file may hold, estimated before YAML reads it as the number of its
#: commas and line breaks (every list item and key needs one of them, but the first).
MAX_ITEMS = 100_000

#: Most values a model file may expand to (aliases can multiply a small file).
MAX_VALUES = 250_000

#: Deepest nesting: the file's mapping is level 1, each list, mapping or value in one is one
#: more (the examples nest 7 deep).
MAX_DEPTH = 64

_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"

#: Integers: decimal (leading zeros are decimal, as in YAML 1.2, not octal), 0b binary, 0x
#: hexadecimal; not YAML 1.1's base 60 (1:30 is a string, not 90).
_INT = re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?[0-9][0-9_]*|[-+]?0x[0-9a-fA-F_]+)$")

#: Floats: 1.5, 1.5e-3, 1e-3 (YAML 1.2: no dot needed, exponent sign optional), .5, .inf,
#: .nan; not YAML 1.1's base 60 (1:30.5 is a string).
_FLOAT = re.compile(
    r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.VERBOSE,
)

#: What YAML 1.1 reads as a number in base 60 (in messages: such values are strings here).
_SEXAGESIMAL = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")

#: Characters YAML does not allow in a file (its reader's own check).
_NOT_PRINTABLE = yaml.reader.Reader.NON_PRINTABLE

#: Line breaks of YAML, to count lines as its error marks do.
_LINE_BREAK = re.compile("\r\n|[\n\r\x85\u2028\u2029]")

#: Names of the ASCII control characters (U+0000 .. U+001F, U+007F).
_CONTROL_NAMES = (
    "NUL SOH STX ETX EOT ENQ ACK BEL BS HT LF VT FF CR SO SI "
    "DLE DC1 DC2 DC3 DC4 NAK SYN ETB CAN EM SUB ESC FS GS RS US"
).split()


class _ReadError(yaml.YAMLError):
    """A value the loader refuses: at `node` (its key path is then known) or at `mark`."""

    def __init__(self, message: str, node: yaml.Node | None = None, mark: Any = None):
        super().__init__(message)
        self.message = message
        self.node = node
        self.mark = mark if node is None else node.start_mark


class _Loader(yaml.SafeLoader):
    """The safe loader (plain data only: no Python tags, nothing executed) with YAML 1.2
    numbers (``1e-5`` is a number; ``1:30`` and other base-60 forms are strings), a limit
    on nesting, and constructor errors reported at their node."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self.depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        # Nesting deeper than MAX_DEPTH is refused before the recursion of the composer.
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise _ReadError(f"nested more than {MAX_DEPTH} levels deep", mark=mark)
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except yaml.YAMLError:
            raise
        except (ValueError, TypeError, KeyError, IndexError, AttributeError, ArithmeticError):
            tag = str(node.tag).replace("tag:yaml.org,2002:", "!!")
            value = node.value if isinstance(node, yaml.ScalarNode) else f"a {node.id}"
            raise _ReadError(f"{value_text(value)} is not a valid {tag} value", node) from None

    def construct_int(self, node: Any) -> int:
        """An integer: decimal (leading zeros too), 0b binary or 0x hexadecimal."""
        text = str(self.construct_scalar(node)).replace("_", "")
        sign = -1 if text.startswith("-") else 1
        digits = text.lstrip("+-")
        base = {"0b": 2, "0x": 16}.get(digits[:2], 10)
        return sign * int(digits[2:] if base != 10 else digits, base)

    def construct_float(self, node: Any) -> float:
        """A float, not in base 60 (``!!float 1:30`` is refused)."""
        if ":" in str(node.value):
            raise ValueError("base-60 numbers are not read")
        return float(super().construct_yaml_float(node))


# Only the resolvers of ints and floats change: the others (bool, null, ...) stay YAML 1.1's.
_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_INT_TAG, _INT, list("-+0123456789"))
_Loader.add_implicit_resolver(_FLOAT_TAG, _FLOAT, list("-+0123456789."))
_Loader.add_constructor(_INT_TAG, _Loader.construct_int)
_Loader.add_constructor(_FLOAT_TAG, _Loader.construct_float)


def yaml_value(text: str) -> Any:
    """`text` read as a YAML value the way model files read theirs (YAML 1.2 numbers: ``1:2``
    is text, not the base-60 number 62; plain data only). Raises `yaml.YAMLError`."""
    loader = _Loader(text)
    try:
        return loader.get_single_data()
    except _ReadError as error:
        raise yaml.YAMLError(error.message) from None
    finally:
        loader.dispose()


def _key_path(path: Path_) -> str:
    text = ""
    for part in path:
        name = _short(part, 60)
        text += f"[{part}]" if isinstance(part, int) else (f".{name}" if text else name)
    return text


class _Source:
    """A model file's name, folder and the line of every key path (1-based)."""

    def __init__(self, path: Path, display: str):
        self.path = path
        self.display = display
        self.folder = path.parent
        self.lines: dict[Path_, int] = {}
        self.paths: dict[int, Path_] = {}

    def line(self, path: Path_) -> int | None:
        """The line of `path`, or of its nearest parent that is in the file."""
        for k in range(len(path), -1, -1):
            if path[:k] in self.lines:
                return self.lines[path[:k]]
        return None

    def error(self, path: Path_, message: str, line: int | None = None) -> ModelFileError:
        """The error at `path` (at `line` if given, else the line of `path`)."""
        line = self.line(path) if line is None else line
        where = f"{self.display}: line {line}" if line is not None else self.display
        key = _key_path(path) or None
        text = f"{where}: {key}: {message}" if key else f"{where}: {message}"
        return ModelFileError(text, file=self.display, line=line, key=key)

    def check(self, text: str) -> None:
        """Checks the text before YAML reads it: its estimated item count (MAX_ITEMS) and
        characters YAML does not allow (control characters such as NUL and BEL)."""
        breaks = sum(text.count(c) for c in "\n\r\x85\u2028\u2029") - text.count("\r\n")
        items = text.count(",") + breaks
        if items > MAX_ITEMS:
            raise ModelFileError(
                f"{self.display}: the model file holds about {items} items (commas and line "
                f"breaks), more than the limit of {MAX_ITEMS}: put meshes, matrices and long "
                "tables in mesh or body files",
                file=self.display,
            )
        found = _NOT_PRINTABLE.search(text)
        if found is not None:
            start = found.start()
            before = list(_LINE_BREAK.finditer(text, 0, start))
            line = len(before) + 1
            column = start - (before[-1].end() if before else 0) + 1
            code = ord(found.group())
            if code < 0x20:
                name = f" ({_CONTROL_NAMES[code]})"
            elif code == 0x7F:
                name = " (DEL)"
            else:
                name = ""
            kind = "control character" if code < 0x20 or 0x7F <= code < 0xA0 else "character"
            raise ModelFileError(
                f"{self.display}: line {line}, column {column}: {kind} U+{code:04X}{name} is "
                "not allowed in YAML; remove it",
                file=self.display,
                line=line,
            )

    def read(self, text: str) -> Any:
        """Parses the YAML text, recording the lines of its keys; one error for syntax errors,
        duplicate keys, tags that are not plain data, values that a tag cannot read and
        nesting deeper than MAX_DEPTH."""
        self.check(text)
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                raise ModelFileError(
                    f"{self.display}: the model file is empty", file=self.display, line=None
                )
            self._walk(node, (), [0])
            return loader.construct_document(node)
        except _ReadError as error:
            raise self._read_error(error) from None
        except yaml.MarkedYAMLError as error:
            raise self._yaml_error(error) from None
        except yaml.YAMLError as error:
            raise ModelFileError(f"{self.display}: {error}", file=self.display) from None
        finally:
            loader.dispose()

    def _read_error(self, error: _ReadError) -> ModelFileError:
        if error.node is not None and id(error.node) in self.paths:
            path = self.paths[id(error.node)]
            return self.error(path, error.message, error.node.start_mark.line + 1)
        mark = error.mark
        if mark is None:
            return ModelFileError(f"{self.display}: {error.message}", file=self.display)
        line = mark.line + 1
        return ModelFileError(
            f"{self.display}: line {line}, column {mark.column + 1}: {error.message}",
            file=self.display,
            line=line,
        )

    def _yaml_error(self, error: yaml.MarkedYAMLError) -> ModelFileError:
        mark = error.problem_mark or error.context_mark
        problem = error.problem or error.context or "invalid YAML"
        unknown_tag = re.search(r"constructor for the tag '([^']*)'", problem)
        if unknown_tag:
            tag = unknown_tag.group(1).replace("tag:yaml.org,2002:", "!!")
            problem = (
                f"the tag {tag!r} is not allowed: model files hold plain data "
                "(mappings, lists, strings, numbers, booleans); nothing is executed"
            )
        else:
            problem = f"YAML syntax error: {problem}"
        if mark is None:
            return ModelFileError(f"{self.display}: {problem}", file=self.display)
        line = mark.line + 1
        return ModelFileError(
            f"{self.display}: line {line}, column {mark.column + 1}: {problem}",
            file=self.display,
            line=line,
        )

    def _walk(self, node: yaml.Node, path: Path_, count: list[int]) -> None:
        count[0] += 1
        if count[0] > MAX_VALUES:
            raise ModelFileError(
                f"{self.display}: the model file expands to more than {MAX_VALUES} values "
                "(through aliases?)",
                file=self.display,
            )
        if len(path) > MAX_DEPTH:
            # Only aliases get here (the loader limits the nesting): one inside its own anchor.
            message = f"nested more than {MAX_DEPTH} levels deep (an alias inside its anchor?)"
            raise self.error(path[:1], message, node.start_mark.line + 1)
        self.lines.setdefault(path, node.start_mark.line + 1)
        self.paths.setdefault(id(node), path)
        if isinstance(node, yaml.MappingNode):
            seen: dict[str, int] = {}
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = str(key_node.value)
                line = key_node.start_mark.line + 1
                if key in seen and isinstance(key_node, yaml.ScalarNode):
                    message = f"duplicate key {value_text(key)} (first at line {seen[key]})"
                    raise self.error(path + (key,), message, line)
                seen[key] = line
                self.lines[path + (key,)] = line
                self.paths.setdefault(id(key_node), path + (key,))
                self._walk(value_node, path + (key,), count)
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                self._walk(item, path + (index,), count)


# Pydantic errors as one message with its line ---------------------------------------------------


def _unwrap(annotation: Any) -> Any:
    """The type inside Annotated[...] and Optional[...]."""
    while True:
        if typing.get_origin(annotation) is Annotated:
            annotation = typing.get_args(annotation)[0]
            continue
        if typing.get_origin(annotation) in (Union, types.UnionType):
            members = [a for a in typing.get_args(annotation) if a is not type(None)]
            if len(members) == 1:
                annotation = members[0]
                continue
        return annotation


def _union_member(annotation: Any, tag: Any) -> Any:
    """The member of a tagged union whose tag (pydantic Tag, or the `type` literal) is `tag`."""
    for member in typing.get_args(annotation):
        if typing.get_origin(member) is Annotated:
            if any(isinstance(m, Tag) and m.tag == tag for m in typing.get_args(member)[1:]):
                return member
        inner = _unwrap(member)
        if (
            isinstance(inner, type)
            and issubclass(inner, BaseModel)
            and "type" in inner.model_fields
        ):
            if tag in typing.get_args(inner.model_fields["type"].annotation):
                return member
    return None


def _locate(loc: Sequence[str | int]) -> tuple[Path_, type[BaseModel] | None]:
    """The key path in the file of a pydantic error location (its union tags dropped), and the
    schema model at its end (or None)."""
    annotation: Any = ModelSpec
    path: list[str | int] = []
    for part in loc:
        annotation = _unwrap(annotation)
        origin = typing.get_origin(annotation)
        if origin in (Union, types.UnionType):
            annotation = _union_member(annotation, part)  # `part` is the tag of a member
            continue
        path.append(part)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            known = annotation.model_fields.get(str(part))
            annotation = None if known is None else known.annotation
        elif origin in (list, dict):
            annotation = typing.get_args(annotation)[-1]
        else:
            annotation = None
    annotation = _unwrap(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return tuple(path), annotation
    return tuple(path), None


#: What each shape tag of `_shape_tag` stands for, in messages.
_SHAPES = {
    "(number)": "a number",
    "(name)": "a name",
    "(list)": "a list of numbers",
    "(matrix)": "a 3 x 3 matrix",
    "(mapping)": "a mapping",
    "(mappings)": "a list of mappings",
}


def _short(name: Any, limit: int = 40) -> str:
    """A name for a message, at most `limit` characters."""
    text = str(name)
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: Most names a message lists (known bodies, markers, ...).
_LISTED = 20


def _listing(names: Any) -> str:
    """Names for a message ("none" if there are none): each shortened, at most _LISTED (a
    model file may name an item with a string of megabytes, or have thousands of items)."""
    items = [_short(name) for name in names]
    if not items:
        return "none"
    more = len(items) - _LISTED
    return ", ".join(items[:_LISTED]) + (f", ... ({more} more)" if more > 0 else "")


def _validation_message(error: dict[str, Any]) -> tuple[Path_, str]:
    """The key path and the message of one pydantic error."""
    kind = error["type"]
    ctx = error.get("ctx") or {}
    loc = error["loc"]
    path, _ = _locate(loc)
    if kind == "missing":
        return path[:-1], f"missing key {value_text(loc[-1])}"
    if kind == "extra_forbidden":
        key = str(loc[-1])
        _, model = _locate(loc[:-1])
        if model is None:
            return path, f"unknown key {value_text(key)}"
        allowed = list(model.model_fields)
        close = difflib.get_close_matches(key, allowed, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        return path, f"unknown key {value_text(key)} (allowed: {', '.join(allowed)}){hint}"
    if kind == "union_tag_not_found" and isinstance(error.get("input"), dict):
        value = error["input"]
        if "type" in value:
            return path + ("type",), f"type must be a name, got {value_text(value['type'])}"
        return path, "missing key 'type'"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        value = error.get("input")
        tags = [t.strip("'") for t in str(ctx.get("expected_tags", "")).split(", ")]
        named = [t for t in tags if t and not t.startswith("(")]
        if isinstance(value, dict) and named:
            if "type" not in value:
                return path, "missing key 'type'"
            return path + (
                "type",
            ), f"unknown type {value_text(value['type'])} (one of: {', '.join(named)})"
        kinds = [_SHAPES[t] for t in tags if t in _SHAPES]
        if named:
            kinds.append(f"a mapping with type {', '.join(named)}")
        expected = ", ".join(kinds) if kinds else "another kind of value"
        return path, f"expected {expected}; got {value_text(value)}"
    if kind == "fixed_length":
        return path, error["msg"]
    if kind in ("too_short", "too_long"):
        count = ctx.get("actual_length")
        bound = ctx.get("min_length" if kind == "too_short" else "max_length")
        more = "at least" if kind == "too_short" else "at most"
        return path, f"expected {more} {bound} items, got {count}"
    message = error["msg"]
    if "input" in error and kind not in ("model_type", "dict_type"):
        message += f", got {value_text(error['input'])}"
    value = error.get("input")
    if isinstance(value, str) and _SEXAGESIMAL.match(value) and kind in ("float_type", "int_type"):
        message += " (base-60 numbers such as 1:30 are not read: write 90)"
    return path, message


def _validation_error(source: _Source, error: ValidationError) -> ModelFileError:
    errors = error.errors()
    # An unknown key first: a misspelt key also makes the key it stands for missing.
    first = min(errors, key=lambda e: e["type"] != "extra_forbidden")
    path, message = _validation_message(first)
    if len(errors) > 1:
        others = len(errors) - 1
        message += f" (and {others} more error{'s' if others > 1 else ''})"
    return source.error(path, message)


def _read_text(location: Path, display: str) -> str:
    """The text of a model file (universal newlines), read only if it is a regular file of at
    most MAX_FILE_SIZE bytes."""
    try:
        # A pipe or a device would block or never end: regular files only.
        status = location.stat()
        if not stat.S_ISREG(status.st_mode):
            raise ModelFileError(f"{display}: not a regular file", file=display)
        with location.open("rb") as stream:
            raw = stream.read(MAX_FILE_SIZE + 1)
        if len(raw) > MAX_FILE_SIZE:
            size = max(status.st_size, len(raw))
            raise ModelFileError(
                f"{display}: the model file has {size} bytes, more than the limit of "
                f"{MAX_FILE_SIZE} ({MAX_FILE_SIZE // 1024**2} MiB): put meshes, matrices and "
                "long tables in mesh or body files",
                file=display,
            )
        text = raw.decode("utf-8")
    except FileNotFoundError:
        raise ModelFileError(f"{display}: no such model file", file=display) from None
    except (OSError, UnicodeDecodeError) as error:
        raise ModelFileError(
            f"{display}: cannot read the model file ({error})", file=display
        ) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")
