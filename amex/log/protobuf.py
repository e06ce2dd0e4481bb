"""Decoding the logs' protobuf messages (Foxglove schemas) without the protobuf package.

An MCAP protobuf channel carries its schema as a serialized ``FileDescriptorSet``; that is itself
protobuf, with field numbers fixed by ``google/protobuf/descriptor.proto``. :class:`ProtobufSchema`
reads the message definitions from it and decodes messages into dicts (field name -> value;
repeated fields -> lists; absent fields are absent, as proto3 writes no defaults). Enough of the
wire format for the Foxglove schemas: varints (incl. zigzag), fixed 32/64-bit, length-delimited
strings, bytes, nested and packed repeated fields. Pure Python, ~0.1 ms per JointStates message.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import Any, NamedTuple

# FieldDescriptorProto.Type values (descriptor.proto)
_FIXED = {1: "<d", 2: "<f", 6: "<Q", 7: "<I", 15: "<i", 16: "<q"}  # fixed-width scalars
_SIGNED = {3: 64, 5: 32}  # int64, int32: two's complement varints
_ZIGZAG = {17, 18}  # sint32, sint64
_BOOL, _STRING, _MESSAGE, _BYTES = 8, 9, 11, 12
_REPEATED = 3  # FieldDescriptorProto.Label


class Field(NamedTuple):
    """One field of a message definition."""

    name: str
    type: int
    type_name: str  # full name of a message type, without the leading dot
    repeated: bool


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        if b < 0x80:
            return value, i
        shift += 7


def wire_fields(buf: bytes) -> Iterator[tuple[int, int, Any]]:
    """(field number, wire type, value) of every field in ``buf``: int, or bytes for the rest."""
    i, n = 0, len(buf)
    while i < n:
        key, i = _varint(buf, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(buf, i)
            yield number, wire, value
        elif wire == 1:
            yield number, wire, buf[i : i + 8]
            i += 8
        elif wire == 5:
            yield number, wire, buf[i : i + 4]
            i += 4
        elif wire == 2:
            length, i = _varint(buf, i)
            yield number, wire, buf[i : i + length]
            i += length
        else:
            raise ValueError(f"unsupported protobuf wire type {wire}")


class ProtobufSchema:
    """The message definitions of a ``FileDescriptorSet``, and a decoder for them.

    Args:
        descriptor_set: the serialized ``FileDescriptorSet`` (an MCAP schema's data).
    """

    def __init__(self, descriptor_set: bytes) -> None:
        self.messages: dict[str, dict[int, Field]] = {}
        for number, _, file in wire_fields(descriptor_set):
            if number != 1:  # FileDescriptorSet.file
                continue
            parts = list(wire_fields(file))
            package = next((v.decode() for n, _, v in parts if n == 2), "")
            for n, _, message in parts:
                if n == 4:  # FileDescriptorProto.message_type
                    self._add(message, package)

    def _add(self, buf: bytes, scope: str) -> None:
        parts = list(wire_fields(buf))
        name = next((v.decode() for n, _, v in parts if n == 1), "")
        full = f"{scope}.{name}" if scope else name
        fields: dict[int, Field] = {}
        for n, _, value in parts:
            if n == 2:  # DescriptorProto.field
                f = {k: v for k, _, v in wire_fields(value)}
                fields[int(f.get(3, 0))] = Field(
                    name=bytes(f.get(1, b"")).decode(),
                    type=int(f.get(5, 0)),
                    type_name=bytes(f.get(6, b"")).decode().lstrip("."),
                    repeated=f.get(4) == _REPEATED,
                )
            elif n == 3:  # DescriptorProto.nested_type
                self._add(value, full)
        self.messages[full] = fields

    def decode(self, type_name: str, buf: bytes) -> dict[str, Any]:
        """The message ``buf`` of type ``type_name`` (e.g. ``foxglove.JointStates``) as a dict."""
        fields = self.messages.get(type_name)
        if fields is None:
            raise ValueError(f"message type {type_name!r} is not in the schema")
        out: dict[str, Any] = {}
        for number, wire, value in wire_fields(buf):
            field = fields.get(number)
            if field is None:
                continue  # unknown field: skipped, as protobuf does
            if field.repeated and wire == 2 and field.type not in (_STRING, _BYTES, _MESSAGE):
                out.setdefault(field.name, []).extend(self._packed(field.type, value))
                continue
            item = self._value(field, wire, value)
            if field.repeated:
                out.setdefault(field.name, []).append(item)
            else:
                out[field.name] = item
        return out

    def _value(self, field: Field, wire: int, value: Any) -> Any:
        t = field.type
        if t == _MESSAGE:
            return self.decode(field.type_name, value)
        if t == _STRING:
            return bytes(value).decode("utf-8", errors="replace")
        if t == _BYTES:
            return bytes(value)
        if t in _FIXED:
            return struct.unpack(_FIXED[t], value)[0]
        if t in _SIGNED and value >= 1 << (_SIGNED[t] - 1):
            return value - (1 << 64 if value >= 1 << 63 else 1 << _SIGNED[t])
        if t in _ZIGZAG:
            return (value >> 1) ^ -(value & 1)
        if t == _BOOL:
            return bool(value)
        return value  # uint32, uint64, enum

    def _packed(self, t: int, buf: bytes) -> list[Any]:
        if t in _FIXED:
            fmt = _FIXED[t]
            size = struct.calcsize(fmt)
            return list(struct.unpack(f"<{len(buf) // size}{fmt[1]}", buf))
        values, i = [], 0
        field = Field("", t, "", False)
        while i < len(buf):
            v, i = _varint(buf, i)
            values.append(self._value(field, 0, v))
        return values
