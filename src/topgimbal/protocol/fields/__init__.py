"""Field codecs: how one field's value in user units becomes bytes of a frame's data, and back.

Each codec carries its metadata as data (width, unit, range, enum table, description of what is
allowed) so that the encoder, decoder, simulator, CLI, console and generated docs all read the same
facts. Codecs are immutable and pure; `encode` raises `FieldValueError` naming the field, the value
and what is allowed; `decode` raises `ValueError` on bytes that do not fit.

One module per codec family, all re-exported here (`from topgimbal.protocol.fields import HexInt`):

    base.py      Codec (the contract every codec keeps) and shared checks
    numbers.py   HexInt, DecInt, DecFloat, BinInt, Bitrate          kind "number"
    enums.py     Enum, EnumValue, enum(), OneOf                      kind "enum", "enum_or_number"
    text.py      Text, IPv4Text, RawData, Literal                    kind "text", "ipv4", "raw", "literal"
    geo.py       Geo (GeoDM / GeoDeg are its two spellings)          kind "coordinate"
    time.py      Timestamp                                           kind "datetime"
    field.py     Field (a named codec with meaning, axis and sign metadata)
"""

from __future__ import annotations

from .base import Codec, CodecDescription, EnumValueDescription, FieldValue, JsonScalar
from .enums import ON_OFF, Enum, EnumValue, OneOf, enum
from .field import AXES, SIGN_KINDS, Field, FieldDescription
from .geo import Geo, GeoDeg, GeoDM
from .numbers import BinInt, Bitrate, DecFloat, DecInt, HexInt
from .text import IPv4Text, Literal, RawData, Text
from .time import Timestamp

__all__ = [
    "AXES",
    "ON_OFF",
    "SIGN_KINDS",
    "BinInt",
    "Bitrate",
    "Codec",
    "CodecDescription",
    "DecFloat",
    "DecInt",
    "Enum",
    "EnumValue",
    "EnumValueDescription",
    "Field",
    "FieldDescription",
    "FieldValue",
    "Geo",
    "GeoDM",
    "GeoDeg",
    "HexInt",
    "IPv4Text",
    "JsonScalar",
    "Literal",
    "OneOf",
    "RawData",
    "Text",
    "Timestamp",
    "enum",
]
