"""amex's own protobuf messages: flat records of numbers, flags and texts, and their schemas.

``/tcp``, ``/goal``, ``/command`` and ``/method`` are protobuf messages of schemas made here
(issue #29: a float's shortest text costs ~0.4 us, its 8 bytes ~0.01 us; the numbers are written
exactly, NaN and infinity included). A schema is a flat message: each field a ``double``, a
``repeated double`` (packed), a ``bool`` or a ``string``, numbered from 1 in declaration order.
:func:`descriptor_set` writes it as the serialized ``FileDescriptorSet`` that an MCAP protobuf
channel carries (Foxglove reads it with protobufjs; :class:`amex.log.protobuf.ProtobufSchema`
reads it without the protobuf package). The package is ``amex``: schema names ``amex.Tcp``, ...

Every field a message has is written, zeros and empty texts included (proto3 would leave them
out; readers take them either way), so that a field absent from a message means null: the
reader (:mod:`amex.log.reader`) gives ``None`` for it, as the JSON messages of earlier logs did.
"""

from __future__ import annotations

import functools
import re
import struct
from collections.abc import Sequence
from typing import Any, NamedTuple

import foxglove

# FieldDescriptorProto.Type and .Label values (google/protobuf/descriptor.proto)
_TYPES = {"double": 1, "doubles": 1, "bool": 8, "string": 9}
_OPTIONAL, _REPEATED = 1, 3
_WIRE = {"double": 1, "doubles": 2, "bool": 0, "string": 2}
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

DOUBLE = struct.Struct("<d")


def varint(value: int) -> bytes:
    """``value`` >= 0 as a protobuf varint."""
    out = bytearray()
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def tag(number: int, kind: str) -> bytes:
    """The key of field ``number`` of ``kind`` (``double``, ``doubles``, ``bool``, ``string``)."""
    return varint(number << 3 | _WIRE[kind])


def _field(number: int, body: bytes) -> bytes:
    return varint(number << 3 | 2) + varint(len(body)) + body


def _text(number: int, text: str) -> bytes:
    return _field(number, text.encode())


def _int(number: int, value: int) -> bytes:
    return varint(number << 3) + varint(value)


class FlatSchema(NamedTuple):
    """A flat message: its full name (``amex.Tcp``) and its fields (name, kind), numbered from 1."""

    name: str
    fields: tuple[tuple[str, str], ...]

    def descriptor_set(self) -> bytes:
        """The serialized ``FileDescriptorSet`` of this one message (:func:`descriptor_set`).

        Kept per schema: every log makes the channels of ``/tcp``, ``/goal`` and ``/command``.
        """
        return _descriptor_set(self.name, self.fields)

    def schema(self) -> foxglove.Schema:
        """The MCAP schema record's content (name, ``protobuf``, the descriptor set)."""
        return foxglove.Schema(name=self.name, encoding="protobuf", data=self.descriptor_set())

    def channel(self, topic: str, context: foxglove.Context) -> foxglove.Channel:
        """A channel of pre-encoded messages of this schema."""
        return foxglove.Channel(
            topic, schema=self.schema(), message_encoding="protobuf", context=context
        )


@functools.lru_cache(maxsize=256)
def _descriptor_set(full_name: str, fields: tuple[tuple[str, str], ...]) -> bytes:
    return descriptor_set(full_name, fields)


def descriptor_set(full_name: str, fields: Sequence[tuple[str, str]]) -> bytes:
    """``FileDescriptorSet`` {file: ``amex/<Name>.proto``, package, one message, proto3}.

    Args:
        full_name: ``amex.<Name>``.
        fields: (name, kind) per field, numbered 1, 2, ...; names must be identifiers.
    """
    package, _, name = full_name.rpartition(".")
    message = _text(1, name)  # DescriptorProto.name
    for number, (field_name, kind) in enumerate(fields, start=1):
        if not _NAME.match(field_name):
            raise ValueError(f"invalid protobuf field name {field_name!r}: valid: identifiers")
        label = _REPEATED if kind == "doubles" else _OPTIONAL
        field = (  # FieldDescriptorProto: name, number, label, type, json_name
            _text(1, field_name) + _int(3, number) + _int(4, label) + _int(5, _TYPES[kind])
            + _text(10, field_name)
        )  # fmt: skip
        message += _field(2, field)  # DescriptorProto.field
    file = (  # FileDescriptorProto: name, package, message_type, syntax
        _text(1, f"{package.replace('.', '/')}/{name}.proto") + _text(2, package)
        + _field(4, message) + _text(12, "proto3")
    )  # fmt: skip
    return _field(1, file)  # FileDescriptorSet.file


def field_names(keys: Sequence[str], reserved: Sequence[str] = ()) -> list[str]:
    """Protobuf field names for ``keys``, unique, none of ``reserved`` (e.g. ``t``).

    Each key itself if it is an identifier, else the key with every other character replaced by
    ``_`` (and ``_`` before a leading digit); a name taken already gets a suffix ``_2``, ...
    """
    taken = set(reserved)
    names = []
    for key in keys:
        name = key if _NAME.match(key) else re.sub(r"\W", "_", key, flags=re.ASCII) or "_"
        if name[0].isdigit():
            name = "_" + name
        base, n = name, 1
        while name in taken:
            n += 1
            name = f"{base}_{n}"
        taken.add(name)
        names.append(name)
    return names


#: The per-step topics of fixed fields (``m`` task-space and ``n`` joint coordinates aside).
TCP = FlatSchema(
    "amex.Tcp",
    (("t", "double"), ("position", "doubles"), ("axis", "doubles"), ("velocity", "doubles"),
     ("distance_to_goal", "double")),
)  # fmt: skip
GOAL = FlatSchema("amex.Goal", (("t", "double"), ("position", "doubles"), ("distance", "double")))
COMMAND = FlatSchema(
    "amex.Command",
    (("t", "double"), ("y_star", "doubles"), ("yd_star", "doubles"), ("q_star", "doubles"),
     ("qd_star", "doubles")),
)  # fmt: skip


class FlatDecoder:
    """Reads the messages of a flat schema back into dicts: every field, None where absent.

    Strict: a message with a field the schema lacks, a field of another wire type or a cut
    field is not one of these messages (:meth:`decode` raises ValueError), so damaged bytes are
    not taken for numbers.

    Args:
        descriptor_set: the channel's schema data (a serialized ``FileDescriptorSet``).
        name: the message's full name (the MCAP schema's name).
    """

    def __init__(self, descriptor_set: bytes, name: str) -> None:
        from amex.log.protobuf import ProtobufSchema

        fields = ProtobufSchema(descriptor_set).messages.get(name)
        if fields is None:
            raise ValueError(f"message type {name!r} is not in the schema")
        self._fields = {}
        for number, field in sorted(fields.items()):
            kind = _KIND_OF_TYPE.get((field.type, field.repeated))
            if kind is None:
                raise ValueError(f"{name}.{field.name}: not a flat field")
            self._fields[number] = (field.name, kind)
        self._empty = dict.fromkeys(name for name, _ in self._fields.values())

    def decode(self, data: bytes) -> dict[str, Any]:
        """One message as ``{field: value or None}``, in field-number order."""
        from amex.log.protobuf import wire_fields

        out = dict(self._empty)
        for number, wire, value in wire_fields(bytes(data)):
            name, kind = self._fields.get(number, ("", ""))
            if _WIRE.get(kind) != wire:
                raise ValueError(f"field {number} of wire type {wire}: not in the schema")
            if kind == "double":
                if len(value) != 8:
                    raise ValueError(f"field {number} is cut")
                out[name] = DOUBLE.unpack(value)[0]
            elif kind == "doubles":
                if len(value) % 8:
                    raise ValueError(f"field {number} is cut")
                out[name] = list(struct.unpack(f"<{len(value) // 8}d", value))
            elif kind == "bool":
                out[name] = bool(value)
            else:
                out[name] = bytes(value).decode("utf-8", errors="replace")
        return out


_KIND_OF_TYPE = {  # (FieldDescriptorProto.Type, repeated) -> kind
    (1, False): "double",
    (1, True): "doubles",
    (8, False): "bool",
    (9, False): "string",
}
