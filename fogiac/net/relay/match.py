"""How a reply names its request, read off a ROS 1 serialized message without deserializing it. Pure.

``header.stamp`` (the default, ROS practice: a reply carries its request's ``std_msgs/Header`` stamp)
is bytes 4..12 of a message whose first field is its Header (uint32 seq, time stamp, string frame_id).
Any other dotted path (``id``, ``request.uuid``, ``header.frame_id``...) is found by walking the raw
bytes with the topic's message definition, which a publisher sends in its TCPROS header: every field
before it is skipped (strings and arrays by their length prefixes), so the key is the field's own
bytes, whatever its type. A path that names no field is an error; a message too short for it has no key.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Payload

DEFAULT_MATCH = "header.stamp"
Key = bytes
KeyOf = Callable[[Payload], "Key | None"]

_SIZES = {"bool": 1, "int8": 1, "uint8": 1, "byte": 1, "char": 1, "int16": 2, "uint16": 2,
          "int32": 4, "uint32": 4, "float32": 4, "int64": 8, "uint64": 8, "float64": 8,
          "time": 8, "duration": 8}
_U32 = struct.Struct("<I")


@dataclass(frozen=True)
class Field:
    name: str
    base: str  # a primitive, "string", or a message type's full name
    array: int | None  # None: scalar; -1: variable length; n: fixed length n


def parse_definition(text: str, type_name: str) -> dict[str, tuple[Field, ...]]:
    """Message type -> its fields, from a TCPROS ``message_definition`` (the main type first, then each
    ``MSG: pkg/Type`` section)."""
    sections: list[tuple[str, list[str]]] = [(type_name, [])]
    for line in text.splitlines():
        if line.startswith("MSG: "):
            sections.append((line[5:].strip(), []))
        elif not line.startswith("====="):
            sections[-1][1].append(line)
    names = [name for name, _ in sections]
    out: dict[str, tuple[Field, ...]] = {}
    for name, lines in sections:
        package = name.split("/")[0] if "/" in name else ""
        fields = []
        for raw in lines:
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            if len(parts) < 2 or "=" in line:  # a constant, not a field
                continue
            kind, field_name = parts[0], parts[1]
            array: int | None = None
            if kind.endswith("]"):
                kind, size = kind[:-1].split("[", 1)
                array = int(size) if size else -1
            fields.append(Field(field_name, _resolve(kind, package, names), array))
        out[name] = tuple(fields)
    return out


def _resolve(kind: str, package: str, known: list[str]) -> str:
    if kind in _SIZES or kind == "string":
        return kind
    if kind == "Header":
        return "std_msgs/Header"
    if "/" in kind:
        return kind
    same = f"{package}/{kind}"
    return same if same in known else next((k for k in known if k.endswith("/" + kind)), same)


class _Walker:
    def __init__(self, types: dict[str, tuple[Field, ...]]) -> None:
        self.types = types

    def skip(self, base: str, data: Payload, off: int) -> int:
        if base in _SIZES:
            return off + _SIZES[base]
        if base == "string":
            return off + 4 + _U32.unpack_from(data, off)[0]
        for f in self._fields(base):
            off = self.skip_field(f, data, off)
        return off

    def skip_field(self, f: Field, data: Payload, off: int) -> int:
        if f.array is None:
            return self.skip(f.base, data, off)
        count = f.array
        if count < 0:
            count = _U32.unpack_from(data, off)[0]
            off += 4
        if f.base in _SIZES:
            return off + count * _SIZES[f.base]
        for _ in range(count):
            off = self.skip(f.base, data, off)
        return off

    def _fields(self, base: str) -> tuple[Field, ...]:
        if base == "std_msgs/Header" and base not in self.types:
            return (Field("seq", "uint32", None), Field("stamp", "time", None), Field("frame_id", "string", None))
        try:
            return self.types[base]
        except KeyError:
            raise RelayError(f"the message definition lacks {base}") from None

    def locate(self, base: str, path: list[str]) -> list[Field]:
        """The fields leading to ``path`` (checked once, before any message is read)."""
        chain = []
        for i, name in enumerate(path):
            found = next((f for f in self._fields(base) if f.name == name), None)
            if found is None:
                raise RelayError(f"{base} has no field {name!r}")
            if found.array is not None and i < len(path) - 1:
                raise RelayError(f"{base}.{name} is an array: a match key cannot look inside it")
            chain.append(found)
            base = found.base
        return chain

    def key(self, base: str, chain: list[Field], data: Payload) -> Key | None:
        off = 0
        try:
            for depth, target in enumerate(chain):
                for f in self._fields(base):
                    if f.name == target.name:
                        break
                    off = self.skip_field(f, data, off)
                if depth == len(chain) - 1:
                    end = self.skip_field(target, data, off)
                    return bytes(data[off:end]) if end <= len(data) else None
                base = target.base
        except struct.error:
            return None
        return None


def key_reader(match: str, type_name: str = "*", definition: str = "") -> KeyOf:
    """A function from a serialized message to its key (None: the message is too short to have one)."""
    if match == DEFAULT_MATCH:
        return lambda data: bytes(data[4:12]) if len(data) >= 12 else None
    path = [p for p in match.split(".") if p]
    if not path:
        raise RelayError(f"match {match!r} names no field")
    if not definition:
        raise RelayError(f"match {match!r}: the publisher of {type_name} sent no message definition")
    walker = _Walker(parse_definition(definition, type_name))
    chain = walker.locate(type_name, path)
    return lambda data: walker.key(type_name, chain, data)
