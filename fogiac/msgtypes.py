"""The ROS message facts a replicated node's reply match needs, one store per ROS generation. Pure.

Why one module: validation (is ``reply_match`` a field of the stated reply type?), the relay (where in a
ROS 1 message are the key's bytes?) and Zenoh (where in a CDR message?) ask the same question of the
same facts, a field's offset and type for a message type and a dotted path. Each generation serializes
differently, so each has its own :class:`TypeStore` (as rosbags keeps one typestore per ROS generation):

- :data:`ROS1`: ROS 1 serialization, little-endian with no padding; a string or a variable-length array
  is a uint32 count, then its items; ``time`` is two uint32s.
- :data:`CDR`: ROS 2's CDR (what rmw_zenoh carries), a 4-byte encapsulation header, then fields aligned
  to their own size (8 at most) counted from after that header; a string is a uint32 length (its NUL
  included) and its bytes; a ``builtin_interfaces/Time`` is int32 sec, uint32 nanosec.

Both start knowing ``std_msgs/Header`` (and CDR its ``builtin_interfaces/Time``) and which common types
begin with a Header (ROS 1 and ROS 2 spell them alike, ROS 2 with ``/msg/`` in the middle); a ROS 1
publisher's ``message_definition`` adds the rest (:meth:`TypeStore.with_definition`). A bare
``std_msgs/Header`` answers ``header.*`` with its own fields: it is laid out as a message that begins
with one. Nothing here imports the rest of fogiac, so the manifest and both middlewares may import it.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass

DEFAULT_MATCH = "header.stamp"  # ROS practice: a reply copies its request's std_msgs/Header
HEADER = "std_msgs/Header"

Key = bytes
Payload = bytes | bytearray | memoryview  # a serialized message, as a transport hands it over
KeyOf = Callable[[Payload], "Key | None"]

_U32 = struct.Struct("<I")

# Common types whose first field is a std_msgs/Header, and common ones without one: enough to check the
# usual robot services at validate.
_HEADERED = frozenset({
    "geometry_msgs/PointStamped", "geometry_msgs/PoseArray", "geometry_msgs/PoseStamped",
    "geometry_msgs/PoseWithCovarianceStamped", "geometry_msgs/PolygonStamped", "geometry_msgs/QuaternionStamped",
    "geometry_msgs/TransformStamped", "geometry_msgs/TwistStamped", "geometry_msgs/TwistWithCovarianceStamped",
    "geometry_msgs/Vector3Stamped", "geometry_msgs/WrenchStamped", "geometry_msgs/AccelStamped",
    "geometry_msgs/InertiaStamped",
    "nav_msgs/GridCells", "nav_msgs/OccupancyGrid", "nav_msgs/Odometry", "nav_msgs/Path",
    "sensor_msgs/BatteryState", "sensor_msgs/CameraInfo", "sensor_msgs/CompressedImage", "sensor_msgs/FluidPressure",
    "sensor_msgs/Illuminance", "sensor_msgs/Image", "sensor_msgs/Imu", "sensor_msgs/JointState", "sensor_msgs/Joy",
    "sensor_msgs/LaserScan", "sensor_msgs/MagneticField", "sensor_msgs/MultiDOFJointState",
    "sensor_msgs/MultiEchoLaserScan", "sensor_msgs/NavSatFix", "sensor_msgs/PointCloud", "sensor_msgs/PointCloud2",
    "sensor_msgs/Range", "sensor_msgs/RelativeHumidity", "sensor_msgs/Temperature", "sensor_msgs/TimeReference",
    "stereo_msgs/DisparityImage", "trajectory_msgs/JointTrajectory", "trajectory_msgs/MultiDOFJointTrajectory",
    "visualization_msgs/Marker", "visualization_msgs/ImageMarker", "vision_msgs/Detection2DArray",
    "vision_msgs/Detection3DArray", "vision_msgs/Classification", "moveit_msgs/DisplayTrajectory",
})
_HEADERLESS_PACKAGES = ("std_msgs/",)  # std_msgs/Float64, String, ... (std_msgs/Header itself is a header)
_HEADERLESS = frozenset({
    "geometry_msgs/Point", "geometry_msgs/Point32", "geometry_msgs/Pose", "geometry_msgs/Pose2D",
    "geometry_msgs/PoseWithCovariance", "geometry_msgs/Quaternion", "geometry_msgs/Transform", "geometry_msgs/Twist",
    "geometry_msgs/TwistWithCovariance", "geometry_msgs/Vector3", "geometry_msgs/Wrench", "geometry_msgs/Accel",
    "geometry_msgs/Polygon", "geometry_msgs/Inertia", "nav_msgs/MapMetaData", "sensor_msgs/RegionOfInterest",
    "sensor_msgs/ChannelFloat32", "sensor_msgs/PointField", "trajectory_msgs/JointTrajectoryPoint",
})


class MatchError(ValueError):
    """A match path a message type cannot answer, in one line; each caller words it as its own error."""


class UnknownType(MatchError):
    """The store does not know enough of the type to say: the path may be right (validation lets it pass)."""


class DefinitionError(MatchError):
    """A ROS 1 ``message_definition`` fogiac will not read keys with: malformed, self-referential, nested too
    deep or too big. It comes from a publisher (a replica's, over its link): refuse it, never trust it."""


MAX_DEFINITION = 1 << 20  # characters of a message_definition (the largest common ones are ~100 KB)
MAX_DEPTH = 32  # message types nested in one another (a walker's recursion follows this)
MAX_ARRAY = 1 << 32  # a fixed array's length, as a uint32 count could say


@dataclass(frozen=True)
class Field:
    name: str
    base: str  # a primitive, "string", or a message type's full name
    array: int | None  # None: scalar; -1: variable length; n: fixed length n


@dataclass(frozen=True)
class FieldAt:
    """Where a match path's field is in a serialized message, and what it is."""

    type_name: str
    path: str
    base: str  # the field's type: a primitive, "string" or a message type
    array: int | None
    offset: int | None  # its first byte, counted from the payload's start; None: it depends on the data before it
    size: int | None  # its length in bytes; None: it depends on the data


def canonical_type(name: str) -> str:
    """``sensor_msgs/msg/Image`` (ROS 2) and ``sensor_msgs/Image`` (ROS 1) name the same type."""
    return name.replace("/msg/", "/")


def has_header(type_name: str) -> bool | None:
    """Whether the type begins with a std_msgs/Header: True, False, or None when the store does not know it."""
    name = canonical_type(type_name)
    if name in _HEADERED or name == HEADER:
        return True
    if name in _HEADERLESS or name.startswith(_HEADERLESS_PACKAGES):
        return False
    return name.endswith("Stamped") or None  # the ROS convention for "X with a header"


class TypeStore:
    """One ROS generation's message types and how it lays them out in bytes."""

    def __init__(self, name: str, *, sizes: Mapping[str, int], start: int, aligned: bool,
                 types: Mapping[str, tuple[Field, ...]]) -> None:
        self.name = name
        self.sizes = dict(sizes)
        self.start = start  # bytes before the message's first field (CDR's encapsulation header)
        self.aligned = aligned  # fields padded to their own size, counted from ``start``
        self.types = dict(types)
        # per base type, computed once: a nested type's figures would otherwise be walked once per path to it
        # (2^depth times for types that hold two of the next)
        self._least: dict[str, int] = {}
        self._fixed: dict[str, int | None] = {}
        self._aligns: dict[str, int] = {}

    def with_definition(self, text: str, type_name: str) -> TypeStore:
        """This store plus the types a ROS 1 ``message_definition`` declares (the main type first, then each
        ``MSG: pkg/Type`` section, as a publisher sends it in its TCPROS header). :class:`DefinitionError`
        when the definition is malformed, a type contains itself, or types nest deeper than ``MAX_DEPTH``:
        every walk over the result then ends (no recursion without bound, no loop a count in the data sets)."""
        store = TypeStore(self.name, sizes=self.sizes, start=self.start, aligned=self.aligned,
                          types={**self.types, **parse_definition(text, type_name)})
        store._check_nesting()
        return store

    def _check_nesting(self) -> None:
        """No type contains itself, through any chain of fields; none nests deeper than ``MAX_DEPTH``."""
        depth: dict[str, int] = {}

        def visit(base: str, path: tuple[str, ...]) -> int:
            if base in path:
                raise DefinitionError(f"message type {base} contains itself ({' -> '.join(path + (base,))})")
            if len(path) > MAX_DEPTH:
                raise DefinitionError(f"message types nest deeper than {MAX_DEPTH} ({path[0]} ...)")
            if base not in depth:
                depth[base] = 1 + max((visit(f.base, path + (base,)) for f in self.types.get(base, ())
                                       if f.base in self.types), default=0)
            return depth[base]

        for name in self.types:
            visit(name, ())

    def min_size(self, base: str) -> int:
        """The fewest bytes a value of ``base`` takes in this store's serialization (an unknown type: 0)."""
        if base in self.sizes:
            return self.sizes[base]
        if base == "string":
            return 4
        if base not in self._least:
            self._least[base] = sum(4 if f.array == -1 else self.min_size(f.base) * (1 if f.array is None else f.array)
                                    for f in self.types.get(base, ()))
        return self._least[base]

    def fields(self, type_name: str) -> tuple[tuple[Field, ...], bool]:
        """The type's fields as far as known, and whether that is all of them: a type known only to begin
        with a Header answers that field alone (incomplete), one known to have none answers nothing."""
        name = canonical_type(type_name)
        if name in self.types:
            return self.types[name], True
        return ((Field("header", HEADER, None),) if has_header(name) else ()), False

    def _field(self, base: str, name: str) -> Field:
        fields, complete = self.fields(base)
        found = next((f for f in fields if f.name == name), None)
        if found is not None:
            return found
        if name == "header" and has_header(base) is False:
            raise MatchError(f"{base} has no std_msgs/Header")
        if not complete:
            raise UnknownType(f"the definition of {base} is not known here")
        raise MatchError(f"{base} has no field {name!r}")

    def _chain(self, type_name: str, path: str) -> list[Field]:
        names = [p for p in path.split(".") if p]
        if not names:
            raise MatchError(f"match {path!r} names no field")
        if canonical_type(type_name) == HEADER and names[0] == "header" and len(names) > 1:
            names = names[1:]  # a bare Header is laid out as a message that begins with one
        base, chain = canonical_type(type_name), []
        for i, name in enumerate(names):
            if base in self.sizes or base == "string":
                raise MatchError(f"{'.'.join(names[:i])} is a {base}: it has no field {name!r}")
            found = self._field(base, name)
            if found.array is not None and i < len(names) - 1:
                raise MatchError(f"{base}.{name} is an array: a match key cannot look inside it")
            chain.append(found)
            base = found.base
        return chain

    def locate(self, type_name: str, path: str) -> FieldAt:
        """Where ``path`` is in a serialized ``type_name``; :class:`MatchError` when it names no field."""
        chain = self._chain(type_name, path)
        offset: int | None = self.start
        base = canonical_type(type_name)
        for target in chain:
            for f in self.fields(base)[0]:
                if f.name == target.name:
                    break
                offset = self._after(f, offset)
            if offset is not None:
                offset = self._align(offset, self._alignment(target))
            base = target.base
        last = chain[-1]
        return FieldAt(type_name=type_name, path=path, base=last.base, array=last.array, offset=offset,
                       size=self._size(last))

    def key_reader(self, type_name: str, path: str) -> KeyOf:
        """A function from a serialized message to the field's bytes (None: too short to have them)."""
        at = self.locate(type_name, path)
        if at.offset is not None and at.size is not None:
            start, end = at.offset, at.offset + at.size
            return lambda data: bytes(data[start:end]) if len(data) >= end else None
        if self.aligned:
            raise MatchError(f"{type_name}.{path}: its place in {self.name} depends on the data before it")
        walker = _Walker(self)
        chain = self._chain(type_name, path)
        return lambda data: walker.key(canonical_type(type_name), chain, data)

    # -- layout ---------------------------------------------------------------------------------------

    def _alignment(self, f: Field) -> int:
        if not self.aligned:
            return 1
        if f.array == -1 or f.base == "string":
            return 4
        if f.base in self.sizes:
            return min(self.sizes[f.base], 8)
        fields = self.types.get(f.base)
        if not fields:
            return 8
        if f.base not in self._aligns:
            self._aligns[f.base] = max((self._alignment(g) for g in fields), default=1)
        return self._aligns[f.base]

    def _align(self, offset: int, alignment: int) -> int:
        """``offset`` (from the payload's start) padded to ``alignment``, counted from the first field."""
        return offset + (-(offset - self.start) % alignment) if alignment > 1 else offset

    def _size(self, f: Field) -> int | None:
        """A field's fixed size (without leading padding); None when it depends on the data."""
        if f.array == -1 or f.base == "string":
            return None
        one: int | None
        if f.base in self.sizes:
            one = self.sizes[f.base]
        else:
            one = self._struct_size(f.base)
        if one is None:
            return None
        return one * (f.array if f.array is not None else 1)

    def _struct_size(self, base: str) -> int | None:
        if base not in self.types:
            return None  # not known (or known only to begin with a Header)
        if base not in self._fixed:
            offset: int | None = self.start
            for f in self.types[base]:
                offset = self._after(f, offset)
            self._fixed[base] = None if offset is None else offset - self.start
        return self._fixed[base]

    def _after(self, f: Field, offset: int | None) -> int | None:
        """The offset just past field ``f`` starting at ``offset`` (None: not fixed)."""
        if offset is None:
            return None
        size = self._size(f)
        if size is None:
            return None
        return self._align(offset, self._alignment(f)) + size


class _Walker:
    """Finds a field's bytes in one ROS 1 message by skipping each field before it (strings and arrays by
    their length prefixes): what a path after a variable-length field needs."""

    def __init__(self, store: TypeStore) -> None:
        self.store = store

    def skip(self, base: str, data: Payload, off: int) -> int:
        sizes = self.store.sizes
        if base in sizes:
            return off + sizes[base]
        if base == "string":
            return off + 4 + _U32.unpack_from(data, off)[0]
        fixed = self.store._struct_size(base) if not self.store.aligned else None
        if fixed is not None:  # no need to walk what has one size
            return off + fixed
        for f in self.store.fields(base)[0]:
            off = self.skip_field(f, data, off)
            if off > len(data):
                raise _TooShort
        return off

    def skip_field(self, f: Field, data: Payload, off: int) -> int:
        if f.array is None:
            return self.skip(f.base, data, off)
        count = f.array
        if count < 0:
            count = _U32.unpack_from(data, off)[0]
            off += 4
        if f.base in self.store.sizes:
            return off + count * self.store.sizes[f.base]
        least = self.store.min_size(f.base)
        if least == 0:  # a type of nothing (no fields, or only empty arrays) takes no bytes however many
            return off
        if off + count * least > len(data):  # a count no message this long could hold: no key, and no loop
            raise _TooShort
        for _ in range(count):
            off = self.skip(f.base, data, off)
            if off > len(data):
                raise _TooShort
        return off

    def key(self, base: str, chain: list[Field], data: Payload) -> Key | None:
        off = self.store.start
        try:
            for depth, target in enumerate(chain):
                for f in self.store.fields(base)[0]:
                    if f.name == target.name:
                        break
                    off = self.skip_field(f, data, off)
                if depth == len(chain) - 1:
                    end = self.skip_field(target, data, off)
                    return bytes(data[off:end]) if end <= len(data) else None
                base = target.base
        except (struct.error, _TooShort):
            return None
        return None


class _TooShort(Exception):
    """The message ends before the field (or its data says it holds more than it can)."""


_ROS1_SIZES = {"bool": 1, "int8": 1, "uint8": 1, "byte": 1, "char": 1, "int16": 2, "uint16": 2,
               "int32": 4, "uint32": 4, "float32": 4, "int64": 8, "uint64": 8, "float64": 8,
               "time": 8, "duration": 8}
_CDR_SIZES = {k: v for k, v in _ROS1_SIZES.items() if k not in ("time", "duration")} | {"float": 4, "double": 8,
                                                                                        "octet": 1}


def parse_definition(text: str, type_name: str) -> dict[str, tuple[Field, ...]]:
    """Message type -> its fields, from a ROS 1 ``message_definition`` (the main type first, then each
    ``MSG: pkg/Type`` section); constants and comments are not fields. :class:`DefinitionError` for text
    that is too big or a field that is not ``TYPE NAME`` with a valid array size."""
    if len(text) > MAX_DEFINITION:
        raise DefinitionError(f"the message definition of {type_name} is {len(text)} characters, over "
                              f"{MAX_DEFINITION}")
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
                kind, _, size = kind[:-1].partition("[")
                if size and not (size.isascii() and size.isdigit() and int(size) < MAX_ARRAY):
                    raise DefinitionError(f"{name}: field {field_name!r} has array size {size[:20]!r}, not a "
                                          f"count below {MAX_ARRAY}")
                array = int(size) if size else -1
            if not kind or "[" in kind or "]" in kind:
                raise DefinitionError(f"{name}: field {field_name!r} has no type fogiac can read ({kind[:40]!r})")
            fields.append(Field(field_name, _resolve(kind, package, names), array))
        out[name] = tuple(fields)
    return out


def _resolve(kind: str, package: str, known: list[str]) -> str:
    if kind in _ROS1_SIZES or kind == "string":
        return kind
    if kind == "Header":
        return HEADER
    if "/" in kind:
        return kind
    same = f"{package}/{kind}"
    return same if same in known else next((k for k in known if k.endswith("/" + kind)), same)


def _fields(text: str) -> tuple[Field, ...]:
    """``"float64 x, float64 y"`` -> its fields (a ``[]`` after a type: a variable-length array of it)."""
    out = []
    for part in text.split(","):
        kind, name = part.split()
        out.append(Field(name, kind.removesuffix("[]"), -1 if kind.endswith("[]") else None))
    return tuple(out)


# Common types known field by field in both generations, so that validate can say a stated type lacks the
# reply_match field (std_msgs/Float64 has no ``id``) rather than let it pass unchecked.
_COMMON = {
    **{f"std_msgs/{name}": _fields(f"{kind} data") for name, kind in (
        ("Bool", "bool"), ("Byte", "byte"), ("Char", "char"), ("Float32", "float32"), ("Float64", "float64"),
        ("Int8", "int8"), ("Int16", "int16"), ("Int32", "int32"), ("Int64", "int64"), ("UInt8", "uint8"),
        ("UInt16", "uint16"), ("UInt32", "uint32"), ("UInt64", "uint64"), ("String", "string"))},
    "std_msgs/Empty": (),
    "std_msgs/ColorRGBA": _fields("float32 r, float32 g, float32 b, float32 a"),
    "geometry_msgs/Point": _fields("float64 x, float64 y, float64 z"),
    "geometry_msgs/Point32": _fields("float32 x, float32 y, float32 z"),
    "geometry_msgs/Vector3": _fields("float64 x, float64 y, float64 z"),
    "geometry_msgs/Quaternion": _fields("float64 x, float64 y, float64 z, float64 w"),
    "geometry_msgs/Pose2D": _fields("float64 x, float64 y, float64 theta"),
    "geometry_msgs/Pose": _fields("geometry_msgs/Point position, geometry_msgs/Quaternion orientation"),
    "geometry_msgs/Twist": _fields("geometry_msgs/Vector3 linear, geometry_msgs/Vector3 angular"),
    "geometry_msgs/Accel": _fields("geometry_msgs/Vector3 linear, geometry_msgs/Vector3 angular"),
    "geometry_msgs/Wrench": _fields("geometry_msgs/Vector3 force, geometry_msgs/Vector3 torque"),
    "geometry_msgs/Transform": _fields("geometry_msgs/Vector3 translation, geometry_msgs/Quaternion rotation"),
    "geometry_msgs/PoseArray": _fields(f"{HEADER} header, geometry_msgs/Pose[] poses"),
    "geometry_msgs/PoseStamped": _fields(f"{HEADER} header, geometry_msgs/Pose pose"),
    "geometry_msgs/PointStamped": _fields(f"{HEADER} header, geometry_msgs/Point point"),
    "geometry_msgs/Vector3Stamped": _fields(f"{HEADER} header, geometry_msgs/Vector3 vector"),
    "geometry_msgs/TwistStamped": _fields(f"{HEADER} header, geometry_msgs/Twist twist"),
    "nav_msgs/Path": _fields(f"{HEADER} header, geometry_msgs/PoseStamped[] poses"),
}

ROS1 = TypeStore("ROS 1 serialization", sizes=_ROS1_SIZES, start=0, aligned=False, types={
    HEADER: (Field("seq", "uint32", None), Field("stamp", "time", None), Field("frame_id", "string", None)),
    **_COMMON,
})
CDR = TypeStore("CDR", sizes=_CDR_SIZES, start=4, aligned=True, types={
    HEADER: (Field("stamp", "builtin_interfaces/Time", None), Field("frame_id", "string", None)),
    "builtin_interfaces/Time": (Field("sec", "int32", None), Field("nanosec", "uint32", None)),
    **_COMMON,
})


def store_for(type_name: str) -> TypeStore:
    """The store a stated type's spelling points at: ``pkg/msg/Type`` is ROS 2's (CDR), ``pkg/Type`` ROS 1's."""
    return CDR if "/msg/" in type_name else ROS1
