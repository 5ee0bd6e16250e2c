"""Turning YAML and pydantic failures into lines a person can act on.

``PATH:LINE: nodes[1].machine: 'g4dn.xlrge' is not a known instance type; did you mean
'g4dn.xlarge'?`` — file, line, field path, the problem, and the nearest valid value or key.
"""

from __future__ import annotations

import difflib
import ipaddress
import re
import typing
from collections.abc import Iterable, Sequence
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from fogiac.errors import ManifestError

Loc = tuple[str | int, ...]

_FIELD_NAME = re.compile(r"^[a-z_][a-z0-9_]*$")
_TYPE_TAGS = {"str", "int", "float", "bool", "list", "dict", "tuple", "set", "none"}
_MISMATCH = {"literal_error", "model_type", "tuple_type", "list_type", "dict_type", "string_type",
             "model_attributes_type", "ip_v4_network", "bool_parsing", "int_parsing", "int_type",
             "too_short"}


# pydantic's messages name Python types ("a valid tuple"); a manifest author writes YAML.
_YAML_SHAPES = {"tuple_type": "a list", "list_type": "a list", "dict_type": "a mapping (key: value lines)",
                "model_type": "a mapping (key: value lines)", "model_attributes_type": "a mapping (key: value lines)"}


def _network_problem(value: object) -> str:
    """An IPv4 CIDR that does not parse: host bits set (and the network meant), or not a CIDR at all."""
    try:
        meant = ipaddress.IPv4Network(str(value), strict=False)
    except ValueError:
        return f"{value!r} is not an IPv4 network in CIDR form, like 10.10.0.0/16"
    return f"{value!r} has host bits set; did you mean {meant}?"


class FieldProblem(ValueError):
    """A validation failure that knows its field (relative to the model) and valid choices."""

    def __init__(
        self,
        message: str,
        *,
        field: str | None = None,
        choices: Sequence[str] = (),
        value: object = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.field = field
        self.choices = tuple(choices)
        self.value = value if value is not None else _quoted(message)


class FieldProblems(FieldProblem):
    """Several problems one rule found (every duplicate name, every node without topics): each is
    reported by its own path in the one run, not only the first."""

    def __init__(self, problems: Sequence[FieldProblem]) -> None:
        super().__init__(problems[0].message, field=problems[0].field, choices=problems[0].choices,
                         value=problems[0].value)
        self.problems = tuple(problems)


def raise_all(problems: Sequence[FieldProblem]) -> None:
    """Raise what a rule found: nothing, the one problem, or all of them together."""
    if len(problems) == 1:
        raise problems[0]
    if problems:
        raise FieldProblems(problems)


def each_problem(err: FieldProblem) -> tuple[FieldProblem, ...]:
    return err.problems if isinstance(err, FieldProblems) else (err,)


def problem_text(err: FieldProblem) -> str:
    return err.message + suggest(err.value, err.choices) if err.choices else err.message


def _quoted(message: str) -> str | None:
    match = re.match(r"^'([^']*)'", message)
    return match.group(1) if match else None


def suggest(value: object, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for a close match, else a list of a few valid values, else ''."""
    choices = list(choices)
    if isinstance(value, str):
        close = difflib.get_close_matches(value, choices, n=1, cutoff=0.6)
        if close:
            return f"; did you mean {close[0]!r}?"
    if 0 < len(choices) <= 12:  # the manifest's top level has 9 keys: a typo there still lists them
        return "; valid: " + ", ".join(repr(c) for c in choices)
    return ""


MAX_BYTES = 1 << 20  # a manifest of 100 nodes is ~20 KB
MAX_DEPTH = 24  # the schema nests 5 deep; env and tags add one
_OPEN = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
_CLOSE = (yaml.MappingEndEvent, yaml.SequenceEndEvent)


def _line(event: yaml.Event) -> int:
    return event.start_mark.line + 1 if event.start_mark else 1


def _screen(text: str, *, source: str) -> None:
    """Refuse, from the event stream alone, what would make composing the tree blow up: aliases
    (a few hundred bytes expand to gigabytes, or cycle), nesting deeper than any manifest needs
    (the composer recurses), and oversized files. The parser itself keeps no recursion."""
    if len(text) > MAX_BYTES:
        raise ManifestError([f"{source}:1: the manifest is {len(text)} characters; the limit is {MAX_BYTES}"])
    depth = 0
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.AliasEvent):
            raise ManifestError([f"{source}:{_line(event)}: YAML alias *{event.anchor} is not "
                                 "allowed in a manifest; write the value out"])
        if isinstance(event, _OPEN):
            depth += 1
            if depth > MAX_DEPTH:
                raise ManifestError([f"{source}:{_line(event)}: nested deeper than {MAX_DEPTH} levels"])
        elif isinstance(event, _CLOSE):
            depth -= 1


def parse_yaml(text: str, *, source: str) -> tuple[Any, dict[Loc, int]]:
    """The manifest's data and the line of each of its keys and list items (:func:`line_index`), which
    :func:`format_errors` places its lines by: this module is entered once to read and once to report."""
    try:
        _screen(text, source=source)
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        line = mark.line + 1 if mark else 1
        raise ManifestError([f"{source}:{line}: invalid YAML: {err.problem or err.context}"]) from None
    except yaml.YAMLError as err:  # e.g. a ReaderError for bytes YAML forbids; its text spans lines
        raise ManifestError([f"{source}:1: invalid YAML: {' '.join(str(err).split())}"]) from None
    duplicates = list(_duplicate_keys(root, ()))
    if duplicates:
        raise ManifestError(
            [f"{source}:{line}: {path_str(path)}: key given twice" for path, line in duplicates]
        )
    return data, line_index(root)


def _duplicate_keys(node: yaml.Node | None, path: Loc) -> Iterable[tuple[Loc, int]]:
    if isinstance(node, yaml.MappingNode):
        seen: set[object] = set()
        for key, value in node.value:
            name = key.value if isinstance(key, yaml.ScalarNode) else repr(key)
            if name in seen and name != "<<":
                yield path + (name,), key.start_mark.line + 1
            seen.add(name)
            yield from _duplicate_keys(value, path + (name,))
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            yield from _duplicate_keys(item, path + (i,))


def line_index(root: yaml.Node | None) -> dict[Loc, int]:
    """Map every key path and list item to its 1-based line in the file."""
    lines: dict[Loc, int] = {(): 1}

    def walk(node: yaml.Node, path: Loc) -> None:
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                name = key.value if isinstance(key, yaml.ScalarNode) else repr(key)
                lines[path + (name,)] = key.start_mark.line + 1
                walk(value, path + (name,))
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                lines[path + (i,)] = item.start_mark.line + 1
                walk(item, path + (i,))

    if root is not None:
        walk(root, ())
    return lines


_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_:/.-]+$")


def path_str(path: Loc) -> str:
    """``nodes[1].machine``; odd keys (spaces, newlines, empty) are quoted so a line stays one line."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        elif _PLAIN_KEY.match(str(part)):
            out += ("." if out else "") + str(part)
        else:
            out += f"[{str(part)!r}]"
    return out or "(top)"


def _parse_path(text: str) -> Loc:
    parts: list[str | int] = []
    for name, index in re.findall(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]", text):
        parts.append(name if name else int(index))
    return tuple(parts)


def _clean_loc(loc: Loc, data: Any) -> tuple[Loc, bool]:
    """Drop pydantic's union-branch tags from ``loc``; say whether the leaf is absent."""
    path: list[str | int] = []
    cur: Any = data
    for part in loc:
        if isinstance(part, int) and isinstance(cur, (list, tuple)) and 0 <= part < len(cur):
            path.append(part)
            cur = cur[part]
        elif isinstance(cur, dict) and part in cur:
            path.append(part)
            cur = cur[part]
        elif isinstance(part, str) and _FIELD_NAME.match(part) and part not in _TYPE_TAGS:
            path.append(part)
            return tuple(path), True
    return tuple(path), False


def _field_names(model: type[BaseModel]) -> list[str]:
    return [info.alias or name for name, info in model.model_fields.items()]


def _model_at(model: type[BaseModel], path: Loc) -> type[BaseModel] | None:
    current: Any = model
    for part in path:
        if isinstance(part, int):
            continue
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        fields = {info.alias or name: info for name, info in current.model_fields.items()}
        info = fields.get(str(part))
        if info is None:  # a block a plug-in owns (Manifest.owned_block): its own model names its keys
            owner = getattr(current, "owned_block", None)
            current = owner(str(part)) if owner is not None else None
            continue
        current = _inner_model(info.annotation)
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _inner_model(annotation: Any) -> Any:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _inner_model(arg)
        if found is not None:
            return found
    return None


def _describe(error: ErrorDetails, data_path: Loc, model: type[BaseModel]) -> tuple[Loc, str]:
    kind = error["type"]
    ctx = error.get("ctx") or {}
    exc = ctx.get("error")
    if isinstance(exc, FieldProblem):  # a group's others come through format_errors
        path = data_path + (_parse_path(exc.field) if exc.field else ())
        return path, problem_text(exc)
    value = error.get("input")
    if kind == "extra_forbidden":
        parent = _model_at(model, data_path[:-1])
        allowed = _field_names(parent) if parent else []
        return data_path, f"unknown key{suggest(str(data_path[-1]), allowed)}"
    if kind == "missing":
        return data_path, "required key is missing"
    if kind == "literal_error":
        expected = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
        return data_path, f"{value!r} is not one of {', '.join(repr(e) for e in expected)}" + (
            suggest(value, expected) if isinstance(value, str) and suggest(value, expected).startswith("; did") else ""
        )
    if kind == "ip_v4_network":
        return data_path, _network_problem(value)
    if kind in _YAML_SHAPES:
        example = f"; write [{value}]" if isinstance(value, (str, int, float)) and str(value).isprintable() \
            and kind in ("tuple_type", "list_type") else ""  # a newline in the example would split the line
        shown = "" if isinstance(value, (dict, list)) else f"{value!r}: "
        return data_path, f"{shown}should be {_YAML_SHAPES[kind]}{example}"
    message = error["msg"]
    for prefix in ("Value error, ", "Assertion failed, "):
        message = message.removeprefix(prefix)
    message = message.replace("Input should be", "should be")
    if kind in _MISMATCH and not isinstance(value, (dict, list)):
        message = f"{value!r}: {message}"
    return data_path, message


def format_errors(
    err: ValidationError | None,
    *,
    lines: dict[Loc, int],
    source: str,
    model: type[BaseModel],
    extra: Sequence[tuple[Loc, str]] = (),
    data: Any = None,
) -> list[str]:
    """One line per problem, in file order; union-branch noise merged into one message."""
    found: dict[Loc, list[tuple[str, str]]] = {}
    for raw in err.errors(include_url=False) if err else ():
        data_path, _absent = _clean_loc(tuple(raw["loc"]), data)
        path, message = _describe(raw, data_path, model)
        found.setdefault(path, []).append((raw["type"], message))
        exc = (raw.get("ctx") or {}).get("error")
        for more in each_problem(exc)[1:] if isinstance(exc, FieldProblem) else ():
            found.setdefault(data_path + (_parse_path(more.field) if more.field else ()), []).append(
                ("value_error", problem_text(more)))
    for path, message in extra:
        found.setdefault(tuple(path), []).append(("value_error", message))
    deeper = {p[:i] for p in found for i in range(len(p))}
    out: list[tuple[int, str]] = []
    for path, items in found.items():
        specific = path in deeper or any(t not in _MISMATCH for t, _ in items)
        kept = [m for t, m in items if not (t in _MISMATCH and specific)]
        if not kept:
            continue
        messages = list(dict.fromkeys(kept))
        message = messages[0] if len(messages) == 1 else " or ".join(messages)
        out.append((_line_for(path, lines), f"{source}:{_line_for(path, lines)}: {path_str(path)}: {message}"))
    out.sort(key=lambda item: item[0])
    return [line for _, line in out] or [f"{source}:1: invalid manifest"]


def _line_for(path: Loc, lines: dict[Loc, int]) -> int:
    for i in range(len(path), -1, -1):
        if path[:i] in lines:
            return lines[path[:i]]
    return 1
